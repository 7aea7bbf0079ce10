"""Fault study (``ost faults report``): robot failures run in-process (every protocol, and CCP's
coordinator organisation) against the fault-free run of the same scenario — objects delivered,
makespan, overhead.

A fault is a set of robots failing at a share of the fault-free makespan (the robots are picked
by a seeded draw). The DDS rows (``--dds``: a real SIGKILL, a lossy network) are added by the
command, which owns the processes; this module stays ROS-free.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from functools import lru_cache

from ost_ros import protocols
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid, Scenario
from ost_ros.result import RunResult
from ost_ros.scenario import generate_scenario
from ost_ros.study.executors import Executor
from ost_ros.study.runner import Study, run_study


@dataclass(frozen=True)
class FaultCase:
    """``count`` robots fail at ``share`` of the fault-free makespan."""

    count: int
    share: float

    def label(self) -> str:
        return f"{self.count} robot{'s fail' if self.count > 1 else ' fails'} at {self.share:.0%} of the run"

    def failures(self, scenario: Scenario, makespan: int, seed: int) -> dict[int, int]:
        ids = [a.id for a in scenario.agents]
        dead = random.Random(seed * 7919 + self.count).sample(ids, min(self.count, len(ids) - 1))
        return {a: int(self.share * makespan) for a in sorted(dead)}


@dataclass
class FaultRow:
    scenario: str
    fault: str
    delivered: int
    total: int
    makespan: int | None
    baseline: int | None
    note: str = ""

    @property
    def overhead(self) -> float | None:
        if self.makespan is None or not self.baseline:
            return None
        return self.makespan / self.baseline - 1.0

    def cells(self) -> list[str]:
        over = "—" if self.overhead is None else f"{self.overhead:+.1%}"
        return [
            self.scenario,
            self.fault,
            f"{self.delivered}/{self.total}",
            "—" if self.makespan is None else str(self.makespan),
            over,
            self.note,
        ]


HEADER = ["scenario", "fault", "delivered / total", "makespan", "overhead vs fault-free", "note"]


def study_scenarios(quick: bool = False) -> list[tuple[str, Scenario]]:
    """The paper's area and object law; teams of 10 and 20 (seeded)."""
    grid = Grid(100, 40) if quick else Grid(500, 200)
    sizes = [(10, 20, 5)] if quick else [(10, 20, 5), (20, 50, 10)]
    return [
        (f"N={n} M={m} {grid.width}×{grid.height} nmax={k}", generate_scenario(n, m, 1, grid, k))
        for n, m, k in sizes
    ]


def cases_for(scenario: Scenario) -> list[FaultCase]:
    n, nmax = scenario.n_agents, scenario.nmax
    return [
        FaultCase(1, 0.25),
        FaultCase(1, 0.5),
        FaultCase(1, 0.75),
        FaultCase(max(2, (n - nmax) // 2), 0.5),
        FaultCase(n - nmax, 0.5),
        FaultCase(n - nmax + 1, 0.5),
    ]


def row_of(name: str, fault: str, result: RunResult, baseline: int | None, note: str = "") -> FaultRow:
    delivered = sum(o.delivered is not None for o in result.objects)
    if not note and not result.completed and result.error:
        note = result.error
    return FaultRow(name, fault, delivered, len(result.objects), result.makespan, baseline, note)


def recovering() -> tuple[str, ...]:
    """The protocols of the registry that recover from robot failures."""
    return tuple(n for n, s in protocols.REGISTRY.items() if s.capabilities.recovers_failures)


def variants(names: tuple[str, ...] | None = None) -> list[tuple[str, CoordinationPolicy]]:
    """Every recovering protocol (CI = 1), then the other organisations those can run."""
    chosen = names or recovering()
    out = [(name, CoordinationPolicy(ci=1)) for name in chosen]
    for name in chosen:
        for organisation in protocols.get(name).capabilities.organisations:
            if organisation != "distributed":
                out.append((name, CoordinationPolicy(ci=1, organisation=organisation)))
    return out


@dataclass(frozen=True)
class FaultRun:
    """One run of the fault study: scenario ``scenario`` of ``study_scenarios(quick)``, a protocol
    and its organisation, and ``case`` (an index of ``cases_for``; -1: the fault-free run)."""

    quick: bool
    scenario: int
    protocol: str
    policy: CoordinationPolicy
    case: int
    seed: int


@lru_cache(maxsize=2)
def _scenario(quick: bool, index: int) -> tuple[str, Scenario]:
    return study_scenarios(quick)[index]


@lru_cache(maxsize=8)
def _baseline(quick: bool, index: int, protocol: str, policy: CoordinationPolicy) -> RunResult:
    # Every fault case needs the fault-free makespan: once per worker, not once per case.
    return simulate(_scenario(quick, index)[1], protocol, policy, engine="auto")


def run(spec: FaultRun) -> FaultRow:
    """The row of one run (a pure function of the spec)."""
    label, scenario = _scenario(spec.quick, spec.scenario)
    name = f"{spec.protocol.upper()}{'' if not spec.policy.centralised else ' (coordinator)'}: {label}"
    base = _baseline(spec.quick, spec.scenario, spec.protocol, spec.policy)
    if spec.case < 0:
        return row_of(name, "none", base, base.makespan)
    assert base.makespan is not None, base.error
    case = cases_for(scenario)[spec.case]
    failures = case.failures(scenario, base.makespan, spec.seed)
    r = simulate(scenario, spec.protocol, spec.policy, failures=failures)
    note = f"agents {sorted(failures)} at step {next(iter(failures.values()))}"
    if not r.completed and r.error:
        note += f"; {r.error.split(': ', 1)[0]} (too few survivors)"
    return row_of(name, case.label(), r, base.makespan, note)


def study(
    quick: bool = False, seed: int = 1, names: tuple[str, ...] | None = None
) -> Study[FaultRun, FaultRow]:
    """Per scenario and protocol setting: the fault-free run, then every fault case."""
    specs = [
        FaultRun(quick, k, protocol, policy, case, seed)
        for k, (_, scenario) in enumerate(study_scenarios(quick))
        for protocol, policy in variants(names)
        for case in range(-1, len(cases_for(scenario)))
    ]
    return Study("faults", specs, run, row_type=FaultRow)


def in_process_rows(
    executor: Executor,
    quick: bool = False,
    seed: int = 1,
    progress: bool | None = None,
    names: tuple[str, ...] | None = None,
) -> list[FaultRow]:
    return run_study(study(quick, seed, names), executor, progress=progress).rows


def markdown(rows: list[FaultRow]) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(r.cells()) + " |" for r in rows]
    return "\n".join(lines)
