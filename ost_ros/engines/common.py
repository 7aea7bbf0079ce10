"""What every engine shares: the step bound of a run and the result built from the world's
record plus what the agents know."""

from __future__ import annotations

from collections.abc import Sequence

from ost_ros.model import Scenario, group_period
from ost_ros.protocols.base import ProtocolAgent
from ost_ros.result import RunResult
from ost_ros.team import TeamInfo
from ost_ros.world import World

ENGINES = ("step", "event")


def step_limit(scenario: Scenario, failures: int = 0) -> int:
    """A bound no correct run exceeds: the longest search, then every object handled one after
    another (reach + carry ≤ 2·(W+H) each), then the way home. Beyond it, the run is deadlocked.
    With ``failures`` robots failing, survivors may sweep every subarea one after another and
    redo the objects after each failure."""
    team = TeamInfo.from_scenario(scenario)
    span = scenario.grid.width + scenario.grid.height
    slowest = group_period(scenario.periods)  # a group of every period moves this rarely
    lengths = team.sweep_lengths()
    search = int(lengths.max()) if not failures else int(lengths.sum()) + scenario.n_agents * span * slowest
    return search + 2 + (failures + 1) * (2 * len(scenario.objects) + 1) * span * slowest


def choose_engine(scenario: Scenario, engine: str = "auto") -> str:
    """``auto``: the event engine once a run is big enough for it to matter, else the reference."""
    if engine not in (*ENGINES, "auto"):
        raise ValueError(f"unknown engine {engine!r} (choose from auto, {', '.join(ENGINES)})")
    if engine != "auto":
        return engine
    return "event" if scenario.n_agents * max(scenario.n_objects, 1) >= 50 else "step"


def finish_result(world: World, agents: Sequence[ProtocolAgent], messages: int) -> RunResult:
    """The world's record plus what the agents know (prediction, agreement, warnings).
    Failed agents told nothing at the end: only survivors count (as over DDS, where they report);
    nor do robots out when the run ended (realtime: silent, their view stale)."""
    out = getattr(world, "outs", {})
    survivors = [ag for ag in agents if ag.id not in world.failed and ag.id not in out] or list(agents)
    known = [ag.summary() for ag in survivors]
    first = known[0]
    found: dict[int, int] = {}
    for k in known:  # CCP: everyone knows every find; HCP: each owner knows its own
        for oid, t in k.found.items():
            found[oid] = min(t, found.get(oid, t))
    result = world.result(
        protocol=survivors[0].protocol,
        trigger=first.trigger,
        predicted_makespan=first.predicted_makespan,
        coordinations=first.coordinations,
        messages=messages,
        agreement=all(k.view == first.view for k in known),
        warnings=[f"agent {ag.id}: {w}" for ag, k in zip(survivors, known) for w in k.warnings],
        found=dict(sorted(found.items())),
        schedule=list(first.schedule),
    )
    if not result.completed and result.error is None:
        result.error = f"not finished after {world.t} steps (deadlock or step limit)"
    return result
