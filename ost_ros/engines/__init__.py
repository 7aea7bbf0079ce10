"""Engines: three ways to run a scenario that give the same result.

- ``step`` (:mod:`.step`): the reference — every agent every step, as over DDS;
- ``event`` for protocols whose agents hold the same public state (capability
  ``team_knowledge``: CCP, NCP, the auction): the run computed from its events by one comm
  module (:mod:`.analytic`);
- ``event`` for every other protocol: jumps from decision to decision on the agents' own plans
  (:mod:`.event`).

:func:`simulate` picks one and checks what the protocol can run (the registry).
"""

from __future__ import annotations

from typing import Any

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines.analytic import run_analytic
from ost_ros.engines.common import ENGINES, choose_engine, finish_result, step_limit
from ost_ros.engines.event import run_events
from ost_ros.engines.step import StepHook, run_steps
from ost_ros.model import Scenario
from ost_ros.protocols import check, make_agents
from ost_ros.result import RunResult

__all__ = [
    "ENGINES",
    "StepHook",
    "check_failures",
    "choose_engine",
    "finish_result",
    "simulate",
    "simulate_events",
    "step_limit",
]


def check_failures(
    scenario: Scenario,
    protocol: str,
    failures: dict[int, int] | None,
    policy: CoordinationPolicy | None = None,
) -> dict[int, int]:
    """The failures as {agent: step}, checked: team members, steps ≥ 0, a recovering protocol."""
    failures = dict(failures or {})
    if not failures:
        return failures
    ids = {a.id for a in scenario.agents}
    for a, t in failures.items():
        if a not in ids:
            raise ValueError(f"failure of agent {a}: no such agent (team {sorted(ids)})")
        if not isinstance(t, int) or t < 0:
            raise ValueError(f"failure of agent {a}: step {t!r} must be a non-negative integer")
    check(protocol, policy=policy, failures=True)
    return failures


def simulate(
    scenario: Scenario,
    protocol: str = "ccp",
    policy: CoordinationPolicy | None = None,
    max_steps: int | None = None,
    on_step: StepHook | None = None,
    engine: str = "step",
    settings: Any = None,
    failures: dict[int, int] | None = None,
) -> RunResult:
    """Run a scenario to completion (or to the step limit) and return the result.

    ``on_step(world, actions)`` is called after each step (progress display, tracing, tests);
    the event engines have no steps to report and ignore it. ``settings``: the protocol's own
    (e.g. NCP's negotiation settings; None: its defaults). ``failures``: agent id -> the step it
    fails in (protocols that recover; the step engine runs them). The coordinator organisation
    runs on the step engine too.
    """
    policy = policy or CoordinationPolicy()
    spec = check(protocol, scenario=scenario, policy=policy)
    failures = check_failures(scenario, protocol, failures, policy)
    for why, needs_steps in (
        ("robot failures run", bool(failures)),
        ("the coordinator organisation runs", policy.centralised),
    ):
        if needs_steps and engine == "event":
            raise ValueError(f"{why} on the step engine, not 'event'")
        if needs_steps:
            engine = "step"
    if choose_engine(scenario, engine) == "event":
        if spec.capabilities.team_knowledge:
            result = run_analytic(scenario, spec, policy, settings)
            if max_steps is None or result.steps <= max_steps:
                return result
            # the reference reports where it stopped
            return simulate(scenario, protocol, policy, max_steps=max_steps, settings=settings)
        return run_events(scenario, make_agents(scenario, protocol, policy, settings), max_steps)
    return run_steps(
        scenario, make_agents(scenario, protocol, policy, settings), max_steps, on_step, failures
    )


def simulate_events(
    scenario: Scenario,
    protocol: str = "ccp",
    policy: CoordinationPolicy | None = None,
    max_steps: int | None = None,
    settings: Any = None,
) -> RunResult:
    """The event engine's run: :func:`simulate` with ``engine="event"``."""
    return simulate(scenario, protocol, policy, max_steps=max_steps, engine="event", settings=settings)
