"""``ost reproduce`` as a study: one run spec per (object set, team size, variant) of the design,
and the row each gives."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ost_ros import protocols
from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Scenario
from ost_ros.result import RunResult
from ost_ros.study.design import Design, Task, Variant, scenario_of
from ost_ros.study.executors import Executor
from ost_ros.study.runner import Outcome, Study, run_study


@dataclass(frozen=True)
class Row:
    agents: int
    objects: int
    set: int
    seed: int
    variant: str
    protocol: str
    ci: str
    makespan: int
    last_delivery: int
    lower_bound: int
    messages: int
    coordinations: int
    study_seed: int = 1
    search_end: int = 0  # the last agent's end of search (its search steps)
    first_carry: int = 0  # the first step any object was carried


@dataclass(frozen=True)
class Run:
    """One variant on one object set with one team size."""

    agents: int
    objects: int
    set: int
    seed: int  # of the object set
    variant: Variant
    study_seed: int = 1  # the design's seed the object set comes from


@lru_cache(maxsize=4)
def _scenario(agents: int, objects: int, seed: int) -> tuple[Scenario, int]:
    # A task's variants run one after another in a chunk: the scenario and its bound once.
    scenario = scenario_of(Task(agents, objects, 0, seed, ()))
    return scenario, lower_bound(scenario).value


@lru_cache(maxsize=16)
def _simulate(agents: int, objects: int, seed: int, protocol: str, ci: int | None) -> RunResult:
    # Every CI > M is one run (coordination only once everyone has searched), and CI=M is CI=M:
    # a chunk's variants that are the same run share it.
    scenario = _scenario(agents, objects, seed)[0]
    if ci is None:  # a protocol without coordination triggers
        return simulate(scenario, protocol, engine="event")
    return simulate(scenario, protocol, CoordinationPolicy(ci=ci), engine="event")


def run(spec: Run) -> Row:
    """The row of one run (a pure function of the spec)."""
    v = spec.variant
    ci = None
    if v.ci is not None:
        ci = min(max(spec.objects if v.ci == "M" else int(v.ci), 1), spec.objects + 1)
    r = _simulate(spec.agents, spec.objects, spec.seed, v.protocol, ci)
    if not r.completed or r.rejections or r.warnings:
        raise RuntimeError(
            f"{v.label} on N={spec.agents} M={spec.objects} set {spec.set}: "
            f"{r.error or (r.rejections + r.warnings)[:1]}"
        )
    return Row(
        spec.agents,
        spec.objects,
        spec.set,
        spec.seed,
        v.label,
        v.protocol,
        "" if v.ci is None else str(v.ci),
        int(r.makespan or 0),
        r.last_delivery,
        _scenario(spec.agents, spec.objects, spec.seed)[1],
        r.messages,
        r.coordinations,
        spec.study_seed,
        max((a.search for a in r.agents), default=0),
        min((o.start for o in r.objects if o.start is not None), default=0),
    )


def weight(spec: Run) -> float:
    """Rough relative cost: protocols stepped agent by agent (no team model) grow with N·M."""
    stepped = protocols.get(spec.variant.protocol).team_comm is None
    return (1 + spec.objects) * (spec.agents if stepped else 2)


def study(design: Design) -> Study[Run, Row]:
    """Every run of the design: the tasks heaviest first, each task's variants together (they
    share its scenario)."""
    specs = [
        Run(t.agents, t.objects, t.set, t.seed, v, t.study_seed) for t in design.tasks() for v in t.variants
    ]
    return Study("reproduce", specs, run, weight, Row)


def run_design(
    design: Design, executor: Executor, out: Path | None = None, progress: bool | None = None
) -> tuple[list[Row], Outcome[Row]]:
    """All runs of the design, sorted as runs.csv lists them, and the runner's outcome (rows in
    spec order, CPU per run, timing)."""
    outcome = run_study(study(design), executor, out, progress)
    return sorted(outcome.rows, key=lambda r: (r.study_seed, r.agents, r.objects, r.variant, r.set)), outcome
