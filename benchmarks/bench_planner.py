"""CCP's planners side by side: the paper's Algorithm Coordination and the improved planner.

    .venv/bin/python benchmarks/bench_planner.py [--sets 3] [--quick] [--seeds 1-12,101-112]
                                                 [--against REV]

In one run, on the same scenarios:

1. makespan of full runs (event engine) with ``--planner paper`` and ``improved`` over the study's
   workloads (500×200, N = 10…50, M = 10…200, CI = 1 and CI = M): the mean relative change, how
   many runs got worse, and the largest change either way; the same for the paper's sizes alone
   (M ≥ 40);
2. the gap to the exact optimum on small post-search problems,
   ``ost generate --agents 4 --objects 7 --seed S --width 60 --height 24 --nmax 3`` then
   ``ost optimal``, one set of 12 per seed range of ``--seeds`` (default: 1..12, the problems the
   tests use, and 101..112, which no test uses): mean and max, both planners;
3. the wall time of one coordination at M = 200, N = 50 (median of 5; the improved planner's
   local search is bounded by an operation count, so the schedule is the same on any machine).

``--against REV`` adds the improved planner as it was at git revision REV (its
``ost_ros/planner.py``, loaded beside this one) to every part: before and after in one run, every
ratio over the same paper runs.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import ost_ros.protocols.ccp.comm as ccp_comm
from ost_ros.coordination import CoordinationPolicy, coordinate
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.optimal import makespan_of, optimal_schedule, post_search_problem
from ost_ros.planner import improve
from ost_ros.protocols.ccp import CcpSettings
from ost_ros.scenario import generate_objects, generate_scenario
from ost_ros.study.design import Design, Task, scenario_of

IMPROVED = CcpSettings("improved")


def planner_at(rev: str) -> Callable:
    """The ``improve`` of ost_ros/planner.py at git revision ``rev``."""
    root = Path(__file__).resolve().parent.parent
    text = subprocess.run(
        ["git", "show", f"{rev}:ost_ros/planner.py"], cwd=root, capture_output=True, text=True, check=True
    ).stdout
    path = Path(tempfile.mkdtemp()) / "planner_then.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("planner_then", path)
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    sys.modules["planner_then"] = module
    spec.loader.exec_module(module)
    return module.improve


@contextmanager
def ccp_planning_with(fn: Callable):
    """CCP's improved planner is ``fn`` for the duration."""
    now = ccp_comm.improve
    ccp_comm.improve = fn
    try:
        yield
    finally:
        ccp_comm.improve = now


def workloads(sets: int, quick: bool) -> list[tuple[int, int, int, int]]:
    design = Design()
    ns = (10, 30, 50) if quick else design.agents
    ms = (10, 50, 200) if quick else tuple(m for m in design.objects if m >= 10)
    return [(n, m, ci, s) for n in ns for m in ms for ci in (1, m) for s in range(sets)]


def summary(name: str, change: list[float], paper_size: list[bool]) -> None:
    big = [c for c, p in zip(change, paper_size) if p]
    print(
        f"   {name}: mean {statistics.mean(change):+.2f} %, best {min(change):+.1f} %, "
        f"worst {max(change):+.1f} %, worse than paper in {sum(c > 0 for c in change)} runs"
        + (
            f"; paper sizes (M >= 40, {len(big)} runs): mean {statistics.mean(big):+.2f} %, "
            f"worst {max(big):+.1f} %, worse than paper in {sum(c > 0 for c in big)}"
            if big
            else ""
        )
    )


def runs(sets: int, quick: bool, then: Callable | None) -> None:
    design = Design()
    cases = workloads(sets, quick)
    change: dict[str, list[float]] = {"improved": [], "then": []}
    paper_size, seconds = [], {"paper": 0.0, "improved": 0.0, "then": 0.0}
    for k, (n, m, ci, s) in enumerate(cases, 1):
        scenario = scenario_of(Task(n, m, s, design.object_seed(m, s), ()))
        policy = CoordinationPolicy(ci=ci)
        t0 = time.perf_counter()
        a = simulate(scenario, "ccp", policy, engine="event")
        t1 = time.perf_counter()
        b = simulate(scenario, "ccp", policy, engine="event", settings=IMPROVED)
        t2 = time.perf_counter()
        seconds["paper"] += t1 - t0
        seconds["improved"] += t2 - t1
        assert a.makespan and b.makespan
        change["improved"].append(100 * (b.makespan / a.makespan - 1))
        if then is not None:
            with ccp_planning_with(then):
                c = simulate(scenario, "ccp", policy, engine="event", settings=IMPROVED)
            seconds["then"] += time.perf_counter() - t2
            assert c.makespan
            change["then"].append(100 * (c.makespan / a.makespan - 1))
        paper_size.append(m >= 40)
        print(
            f"\r  {k}/{len(cases)} runs (N={n} M={m} CI={ci} set {s})   ",
            end="",
            file=sys.stderr,
            flush=True,
        )
    print(file=sys.stderr)
    print(
        f"1. makespan against the paper's planner over {len(cases)} runs (N x M x CI x {sets} object "
        f"sets); planning+run time {seconds['paper']:.1f} s paper, {seconds['improved']:.1f} s improved"
        + (f", {seconds['then']:.1f} s improved then" if then is not None else "")
    )
    summary("improved", change["improved"], paper_size)
    if then is not None:
        summary("improved then", change["then"], paper_size)
        diff = [100 * ((1 + b / 100) / (1 + c / 100) - 1) for b, c in zip(change["improved"], change["then"])]
        print(
            f"   improved against improved then: mean {statistics.mean(diff):+.2f} %, "
            f"worse in {sum(d > 0 for d in diff)} runs, better in {sum(d < 0 for d in diff)}"
        )


def seed_ranges(text: str) -> list[range]:
    """'1-12,101-112' -> [range(1, 13), range(101, 113)]."""
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.append(range(int(lo), int(hi or lo) + 1))
    return out


def small_gaps(sets: list[range], then: Callable | None) -> None:
    for seeds in sets:
        gaps: dict[str, list[float]] = {"paper": [], "improved": [], "then": []}
        optimal = {"improved": 0, "then": 0}
        for seed in seeds:
            ids, ca, where, homes, objs = post_search_problem(
                generate_scenario(4, 7, seed, Grid(60, 24), nmax=3)
            )
            r = optimal_schedule(ids, ca, where, homes, objs)
            assert r.proven
            gaps["paper"].append(100 * r.gap)
            gaps["improved"].append(100 * r.improved_gap)
            optimal["improved"] += r.improved_cost == r.cost
            if then is not None:
                p = then(ids, ca, where, objs, homes)
                cost = makespan_of([int(c) for c in p.cost], [(int(x), int(y)) for x, y in p.loc], homes)
                gaps["then"].append(100 * (cost - r.cost) / r.cost)
                optimal["then"] += cost == r.cost
        print(
            f"2. gap to the optimum, {len(seeds)} small problems (seeds {seeds[0]}..{seeds[-1]}): "
            f"paper mean {statistics.mean(gaps['paper']):.2f} % (max {max(gaps['paper']):.1f} %), "
            f"improved mean {statistics.mean(gaps['improved']):.2f} % (max {max(gaps['improved']):.1f} %, "
            f"optimal in {optimal['improved']})"
            + (
                f", improved then mean {statistics.mean(gaps['then']):.2f} % "
                f"(max {max(gaps['then']):.1f} %, optimal in {optimal['then']})"
                if then is not None
                else ""
            )
        )


def one_coordination(then: Callable | None) -> None:
    grid = Grid()
    objects = generate_objects(200, seed=1, grid=grid)
    rng = np.random.default_rng(2)
    ids = list(range(50))
    cost = rng.integers(0, 3000, 50)
    loc = np.stack([rng.integers(0, grid.width, 50), rng.integers(0, grid.height, 50)], 1)
    bases = np.stack([rng.integers(0, grid.width, 50), np.zeros(50, dtype=np.int64)], 1)
    planners: dict[str, Callable] = {"paper": lambda: coordinate(ids, cost, loc, objects)}
    planners["improved"] = lambda: improve(ids, cost, loc, objects, bases)
    if then is not None:
        planners["improved then"] = lambda: then(ids, cost, loc, objects, bases)
    times: dict[str, list[float]] = {k: [] for k in planners}
    for _ in range(5):
        for name, fn in planners.items():
            t0 = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t0)
    print(
        "3. one coordination, M=200 N=50 (median of 5): "
        + ", ".join(f"{k} {1e3 * statistics.median(v):.0f} ms" for k, v in times.items())
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sets", type=int, default=3, help="object sets per (N, M, CI) (default 3)")
    p.add_argument("--quick", action="store_true", help="N in 10, 30, 50 and M in 10, 50, 200 only")
    p.add_argument(
        "--seeds",
        default="1-12,101-112",
        help="seed ranges of the small problem sets, comma-separated (default 1-12,101-112)",
    )
    p.add_argument("--against", metavar="REV", help="also the improved planner of git revision REV")
    p.add_argument("--skip-runs", action="store_true", help="parts 2 and 3 only")
    a = p.parse_args()
    then = planner_at(a.against) if a.against else None
    one_coordination(then)
    small_gaps(seed_ranges(a.seeds), then)
    if not a.skip_runs:
        runs(a.sets, a.quick, then)


if __name__ == "__main__":
    main()
