"""In-process reference simulator: the world and N agents stepped in lockstep, messages of a step
delivered to everyone within that step (the same semantics the ROS lockstep barrier provides).

Step t: every agent acts on its observation (search, motion) → all messages of the step are
exchanged → every agent's comm module runs → the world applies all actions at once → t+1.

Robot failures (``failures = {agent: step}``): from that step on the agent neither acts nor
sends; the world's :class:`AgentLost` notice joins the inbox of that step, after every agent's
messages — exactly where the ROS world node puts it (``Tick.failed``).
"""
from __future__ import annotations

from typing import Callable

from ost_msgs_py.messages import AgentLost
from ost_ros.agent import CcpAgent
from ost_ros.coordination import Assignment, CoordinationPolicy
from ost_ros.hcp import HcpAgent
from ost_ros.model import Scenario, group_period
from ost_ros.ncp import NcpAgent, NegotiationSettings
from ost_ros.result import RunResult
from ost_ros.team import TeamInfo
from ost_ros.world import World

PROTOCOLS = ("ccp", "hcp", "ncp")
RECOVERING = ("ccp", "hcp")   # protocols that re-plan after a robot failure
ENGINES = ("step", "event")


def step_limit(scenario: Scenario, failures: int = 0) -> int:
    """A bound no correct run exceeds: the longest search, then every object handled one after
    another (reach + carry ≤ 2·(W+H) each), then the way home. Beyond it, the run is deadlocked.
    With ``failures`` robots failing, survivors may sweep every subarea one after another and
    redo the objects after each failure."""
    team = TeamInfo.from_scenario(scenario)
    span = scenario.grid.width + scenario.grid.height
    slowest = group_period(scenario.periods)     # a group of every period moves this rarely
    lengths = team.sweep_lengths()
    search = int(lengths.max()) if not failures else int(lengths.sum()) + scenario.n_agents * span * slowest
    return search + 2 + (failures + 1) * (2 * len(scenario.objects) + 1) * span * slowest


def make_agents(scenario: Scenario, protocol: str, policy: CoordinationPolicy,
                ncp: NegotiationSettings | None = None) -> list:
    if protocol not in PROTOCOLS:
        raise ValueError(f"unknown protocol {protocol!r} (choose from {', '.join(PROTOCOLS)})")
    team = TeamInfo.from_scenario(scenario)
    if protocol == "hcp":
        if any(a.sweep for a in scenario.agents):
            raise ValueError("HCP owns objects by the equal partition's subareas; a scenario with "
                             "own sweeps (a negotiated partition) needs ccp or ncp")
        if scenario.heterogeneous:
            raise ValueError("HCP runs unit-speed teams only (agent periods other than 1 need "
                             "ccp or ncp)")
        return [HcpAgent(a.id, team) for a in scenario.agents]
    if protocol == "ncp":
        return [NcpAgent(a.id, team, policy, ncp) for a in scenario.agents]
    return [CcpAgent(a.id, team, policy) for a in scenario.agents]


def choose_engine(scenario: Scenario, engine: str = "auto") -> str:
    """``auto``: the event engine once a run is big enough for it to matter, else the reference."""
    if engine not in ENGINES + ("auto",):
        raise ValueError(f"unknown engine {engine!r} (choose from auto, {', '.join(ENGINES)})")
    if engine != "auto":
        return engine
    return "event" if scenario.n_agents * max(scenario.n_objects, 1) >= 50 else "step"


def simulate(scenario: Scenario, protocol: str = "ccp", policy: CoordinationPolicy | None = None,
             max_steps: int | None = None,
             on_step: Callable[[World, list], None] | None = None,
             engine: str = "step", ncp: NegotiationSettings | None = None,
             failures: dict[int, int] | None = None) -> RunResult:
    """Run a scenario to completion (or to the step limit) and return the result.

    ``on_step(world, actions)`` is called after each step (progress display, tracing, tests);
    the event engine (``engine="event"``, same result, :mod:`ost_ros.events`) has no steps to
    report and ignores it. ``ncp``: the negotiation settings of protocol ``ncp``.
    ``failures``: agent id → the step it fails in (CCP; the step engine runs them).
    """
    policy = policy or CoordinationPolicy()
    failures = check_failures(scenario, protocol, failures)
    if policy.centralised:
        if protocol == "ncp":
            raise ValueError("the coordinator organisation is for ccp (ncp negotiates)")
        if failures:
            raise ValueError("robot failures: the coordinator organisation does not recover from "
                             "them (the distributed one does)")
        engine = "step" if engine in ("auto", "step") else _not_for_coordinator(engine)
    if failures:
        engine = "step" if engine in ("auto", "step") else _no_event_engine(engine)
    if choose_engine(scenario, engine) == "event":
        if protocol not in PROTOCOLS:
            raise ValueError(f"unknown protocol {protocol!r} (choose from {', '.join(PROTOCOLS)})")
        from ost_ros.events import simulate_events   # events builds on this module
        return simulate_events(scenario, protocol, policy, max_steps, ncp)
    agents = make_agents(scenario, protocol, policy, ncp)
    world = World(scenario)
    limit = max_steps if max_steps is not None else step_limit(scenario, len(failures))
    messages = 0
    live = list(agents)
    while not world.done and world.t < limit:
        t = world.t
        lost = sorted(ag.id for ag in live if failures.get(ag.id) == t)
        live = [ag for ag in live if ag.id not in lost]
        actions = [ag.act(world.observe(ag.id)) for ag in live]
        inbox = [m for ag in live for m in ag.outbox()]
        messages += len(inbox)
        for a in lost:
            world.fail(a)
        inbox += [AgentLost(a, t, world.dropped_by(a)) for a in lost]
        for ag in live:
            ag.communicate(t, inbox)
        world.apply(actions)
        if on_step is not None:
            on_step(world, actions)
    return finish_result(world, agents, protocol, policy, messages)


def _not_for_coordinator(engine: str) -> str:
    raise ValueError(f"the coordinator organisation runs on the step engine, not {engine!r}")


def _no_event_engine(engine: str) -> str:
    raise ValueError(f"robot failures run on the step engine, not {engine!r}")


def check_failures(scenario: Scenario, protocol: str, failures: dict[int, int] | None) -> dict[int, int]:
    """The failures as {agent: step}, checked: team members, steps ≥ 0, CCP only."""
    failures = dict(failures or {})
    if not failures:
        return failures
    ids = {a.id for a in scenario.agents}
    for a, t in failures.items():
        if a not in ids:
            raise ValueError(f"failure of agent {a}: no such agent (team {sorted(ids)})")
        if not isinstance(t, int) or t < 0:
            raise ValueError(f"failure of agent {a}: step {t!r} must be a non-negative integer")
    if protocol not in RECOVERING:
        raise ValueError(f"robot failures: protocol {protocol} does not recover from them (ccp and "
                         "hcp do)")
    return failures


def finish_result(world: World, agents: list, protocol: str, policy: CoordinationPolicy,
                  messages: int) -> RunResult:
    """The world's record plus what the agents know (prediction, agreement, warnings).
    Failed agents told nothing at the end: only survivors count (as over DDS, where they report)."""
    agents = [ag for ag in agents if ag.id not in world.failed] or agents
    first = agents[0].comm
    # CCP/NCP agents agree on the global schedule; HCP agents on every staffing decision.
    view = (lambda c: c.groups) if protocol == "hcp" else (lambda c: c.schedule)
    agreement = all(view(ag.comm) == view(first) for ag in agents)
    warnings = [f"agent {ag.id}: {w}" for ag in agents for w in ag.warnings]
    found: dict[int, int] = {}
    for ag in agents:   # CCP: everyone knows every find; HCP: each owner knows its own
        for oid, t in ag.comm.found_at.items():
            found[oid] = min(t, found.get(oid, t))
    result = world.result(protocol=protocol, trigger=policy.name if protocol != "hcp" else "help",
                          predicted_makespan=first.predicted_makespan,
                          coordinations=first.coordinations, messages=messages,
                          agreement=agreement, warnings=warnings, found=dict(sorted(found.items())),
                          schedule=[a for a in first.schedule if isinstance(a, Assignment)])
    if not result.completed and result.error is None:
        result.error = f"not finished after {world.t} steps (deadlock or step limit)"
    return result
