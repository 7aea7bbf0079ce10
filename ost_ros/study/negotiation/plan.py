"""``ost negotiate reproduce`` as a study: what runs (the plan), one spec per negotiation, and the
result each gives (a pure function of its spec)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ost_ros.negotiation.scenarios import (
    MISSION_DELTAS,
    fig4,
    mission_run,
    nfz_run,
    offer_ratios,
    table2_run,
    target_run,
)
from ost_ros.negotiation.tasks import AreaTask
from ost_ros.study.runner import Study

T2_METRICS = ("overlap_pct", "G", "covered_pct", "out_pct", "rounds")
T2_NAMES = ("overlap %", "G", "covered %", "out %", "rounds")
STOPPING_LABELS = {
    "paper": "paper: Eq. 3 test, exit option",
    "overlap": "overlap: ours before (2 % overlap exit, clipped claims)",
}
RULE_LABELS = {
    "furthest": "furthest (§4.2, the paper's)",
    "path": "path (§5.1)",
    "reward": "reward (ours before)",
}
TGT_R = TGT_N = tuple(range(2, 8))
AREA_R = (2, 3, 4, 5)
TGT_KEYS = ("excess_total_pct", "excess_max_pct", "excess_minmax_pct", "rounds", "messages")


@dataclass(frozen=True)
class Plan:
    """How many runs of what: runs per Table 2 row and per Table 3/4 cell, no-fly-zone seeds,
    §5.1 layouts, the stopping rules (areas) and drop rules (targets) to compare."""

    area_runs: int
    target_runs: int
    nfz_runs: int
    layouts: int
    stoppings: tuple[str, ...]
    rules: tuple[str, ...]

    @classmethod
    def make(cls, quick: bool, runs: int | None) -> Plan:
        return cls(
            area_runs=runs if runs is not None else (2 if quick else 10),
            target_runs=runs if runs is not None else (3 if quick else 10),
            nfz_runs=3 if quick else 10,
            layouts=4 if quick else 20,
            stoppings=("paper",) if quick else ("paper", "overlap"),
            rules=("furthest",) if quick else ("furthest", "path", "reward"),
        )


Job = tuple[str, tuple]  # (kind, its arguments): "t2", "tgt", "nfz", "mission" or "fig4"


def run(job: Job) -> Any:
    """One negotiation's result (plain values: lists, numbers, strings)."""
    kind, args = job
    if kind == "t2":
        robots, stopping, seed = args
        return table2_run(robots, seed, stopping=stopping)
    if kind == "tgt":
        n, robots, k, strategy, rule, seed = args
        return target_run(n, robots, k, strategy=strategy, rule=rule, seed=seed)
    if kind == "nfz":
        return nfz_run(args[0])
    if kind == "mission":
        layout, variant, seed = args
        return mission_run(layout, MISSION_DELTAS[variant], seed)
    if kind == "fig4":
        res = fig4(args[0])
        task = res.task
        assert isinstance(task, AreaTask)
        return {
            "trace": res.trace,
            "shares": [list(res.task.encode(s)) for s in res.shares],
            "metrics": res.metrics(),
            "rounds": res.rounds,
            "status": res.status,
            "ratios": offer_ratios(task, res),
        }
    raise ValueError(kind)


def combos(cfg: Plan) -> list[tuple[str, str]]:
    """The (strategy, drop rule) pairs of the target runs."""
    return [("rounds", rule) for rule in cfg.rules] + [("all-against-all", "furthest")]


def jobs(cfg: Plan, seed: int) -> list[Job]:
    """Every negotiation of the plan, longest first (so the workers stay busy to the end)."""
    out: list[Job] = []
    for r in sorted(AREA_R, reverse=True):
        for stop in cfg.stoppings:
            out += [("t2", (r, stop, seed + k)) for k in range(cfg.area_runs)]
    out.append(("fig4", (seed,)))
    out += [("nfz", (seed + k,)) for k in range(cfg.nfz_runs)]
    for strategy, rule in combos(cfg):
        out += [
            ("tgt", (n, r, k, strategy, rule, seed))
            for r in TGT_R
            for n in TGT_N
            for k in range(cfg.target_runs)
        ]
    out += [("mission", (lay, v, seed)) for lay in range(cfg.layouts) for v in range(2)]
    return out


def weight(job: Job) -> float:
    """Rough seconds of one negotiation (docs/negotiation.md): an area split among R robots takes
    about R − 1 s, Fig. 4 and a no-fly-zone run a second or two, a target split a few ms."""
    kind, args = job
    return {"t2": max(1, args[0] - 1), "fig4": 2.0, "nfz": 1.0}.get(kind, 0.02)


def study(cfg: Plan, seed: int) -> Study[Job, Any]:
    return Study("negotiate-reproduce", jobs(cfg, seed), run, weight)
