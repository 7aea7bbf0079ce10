"""CCP's planners side by side: the paper's Algorithm Coordination and the improved planner.

    .venv/bin/python benchmarks/bench_planner.py [--sets 3] [--quick]

In one run, on the same scenarios:

1. makespan of full runs (event engine) with ``--planner paper`` and ``improved`` over the study's
   workloads (500×200, N = 10…50, M = 10…200, CI = 1 and CI = M): the mean relative change, how
   many runs got worse, and the largest change either way;
2. the gap to the exact optimum on the 12 small post-search problems of
   ``ost generate --agents 4 --objects 7 --seed 1..12 --width 60 --height 24 --nmax 3``
   (``ost optimal``): mean and max, both planners;
3. the wall time of one coordination at M = 200, N = 50 (median of 5; the improved planner's
   local search is bounded by an operation count, so the schedule is the same on any machine).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from ost_ros.coordination import CoordinationPolicy, coordinate
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.optimal import optimal_schedule, post_search_problem
from ost_ros.planner import improve
from ost_ros.protocols.ccp import CcpSettings
from ost_ros.scenario import generate_objects, generate_scenario
from ost_ros.study.design import Design, Task, scenario_of


def workloads(sets: int, quick: bool) -> list[tuple[int, int, int, int]]:
    design = Design()
    ns = (10, 30, 50) if quick else design.agents
    ms = (10, 50, 200) if quick else tuple(m for m in design.objects if m >= 10)
    return [(n, m, ci, s) for n in ns for m in ms for ci in (1, m) for s in range(sets)]


def runs(sets: int, quick: bool) -> None:
    design = Design()
    ratios, worse = [], 0
    cases = workloads(sets, quick)
    t_paper = t_improved = 0.0
    for k, (n, m, ci, s) in enumerate(cases, 1):
        scenario = scenario_of(Task(n, m, s, design.object_seed(m, s), ()))
        policy = CoordinationPolicy(ci=ci)
        t0 = time.perf_counter()
        a = simulate(scenario, "ccp", policy, engine="event")
        t1 = time.perf_counter()
        b = simulate(scenario, "ccp", policy, engine="event", settings=CcpSettings("improved"))
        t2 = time.perf_counter()
        t_paper, t_improved = t_paper + t1 - t0, t_improved + t2 - t1
        assert a.makespan and b.makespan
        ratios.append(b.makespan / a.makespan)
        worse += b.makespan > a.makespan
        print(
            f"\r  {k}/{len(cases)} runs (N={n} M={m} CI={ci} set {s})   ",
            end="",
            file=sys.stderr,
            flush=True,
        )
    print(file=sys.stderr)
    change = [100 * (r - 1) for r in ratios]
    print(
        f"1. makespan, improved vs paper over {len(ratios)} runs "
        f"(N x M x CI x {sets} object sets): mean {statistics.mean(change):+.1f} %, "
        f"best {min(change):+.1f} %, worst {max(change):+.1f} %, worse than paper in {worse} runs; "
        f"planning+run time {t_paper:.1f} s paper, {t_improved:.1f} s improved"
    )


def small_gaps() -> None:
    paper, better = [], []
    for seed in range(1, 13):
        scenario = generate_scenario(4, 7, seed, Grid(60, 24), nmax=3)
        r = optimal_schedule(*post_search_problem(scenario))
        assert r.proven
        paper.append(100 * r.gap)
        better.append(100 * r.improved_gap)
    print(
        f"2. gap to the optimum on the 12 small problems: paper mean {statistics.mean(paper):.1f} % "
        f"(max {max(paper):.1f} %), improved mean {statistics.mean(better):.1f} % "
        f"(max {max(better):.1f} %)"
    )


def one_coordination() -> None:
    grid = Grid()
    objects = generate_objects(200, seed=1, grid=grid)
    rng = np.random.default_rng(2)
    ids = list(range(50))
    cost = rng.integers(0, 3000, 50)
    loc = np.stack([rng.integers(0, grid.width, 50), rng.integers(0, grid.height, 50)], 1)
    bases = np.stack([rng.integers(0, grid.width, 50), np.zeros(50, dtype=np.int64)], 1)
    times = {"paper": [], "improved": []}
    for _ in range(5):
        t0 = time.perf_counter()
        coordinate(ids, cost, loc, objects)
        t1 = time.perf_counter()
        improve(ids, cost, loc, objects, bases)
        t2 = time.perf_counter()
        times["paper"].append(t1 - t0)
        times["improved"].append(t2 - t1)
    print(
        "3. one coordination, M=200 N=50 (median of 5): "
        + ", ".join(f"{k} {1e3 * statistics.median(v):.0f} ms" for k, v in times.items())
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sets", type=int, default=3, help="object sets per (N, M, CI) (default 3)")
    p.add_argument("--quick", action="store_true", help="N in 10, 30, 50 and M in 10, 50, 200 only")
    a = p.parse_args()
    one_coordination()
    small_gaps()
    runs(a.sets, a.quick)


if __name__ == "__main__":
    main()
