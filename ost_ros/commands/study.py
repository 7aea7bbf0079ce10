"""Study verbs: ``ost optimal`` (Algorithm Optimal-OST, CCP's gap), ``ost reproduce`` (the
paper's whole simulation study) and ``ost compare`` (every protocol and planner side by side)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ost_ros import protocols
from ost_ros.bounds import lower_bound
from ost_ros.commands.args import add_workers, at_least, executor, leaf, load_scenario_arg, resumed
from ost_ros.commands.realtime import latency
from ost_ros.errors import UsageError
from ost_ros.optimal import optimal_schedule, post_search_problem, search_space_order

MAX_OPTIMAL_OBJECTS = 10  # beyond this even the pruned search is hopeless in Python


def register(sub) -> None:
    p = leaf(
        sub,
        "optimal",
        cmd_optimal,
        help="exact optimum of the post-search schedule",
        description="Algorithm Optimal-OST (all object orders × agent groups, pruned) on the "
        "scheduling problem left after the whole search, against CCP's "
        "Coordination on the same problem (CCP's gap). Small M and N only.",
    )
    p.add_argument("scenario", help="scenario file (YAML)")
    p.add_argument("--agents", type=at_least(1), help="replace the scenario's team by N agents")
    p.add_argument(
        "--max-nodes",
        type=at_least(1),
        default=2_000_000,
        help="search budget; if exhausted the best schedule found is reported as "
        "not proven (default 2000000)",
    )
    p.add_argument("--json", action="store_true", help="print JSON")

    p = leaf(
        sub,
        "reproduce",
        cmd_reproduce,
        help="rerun the paper's simulation study",
        description="The paper's §5 study (Table 1, Figs 7–11, Table 3) from this code: "
        "CSVs, PNG plots and report.md with ours vs the paper's numbers.",
    )
    p.add_argument("--out", required=True, help="output directory (created if needed)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="a subset: N in 10,20,50, M in 1,10,50,100, 2 object sets (< 20 s)",
    )
    p.add_argument("--seed", type=at_least(0), default=1, help="seed of the object sets (1)")
    p.add_argument("--sets", type=at_least(1), help="object sets per M (default 10; quick 2)")
    p.add_argument(
        "--seeds",
        type=seed_range,
        help="seeds A-B for Table 3's spread: CCP CI=1 and CI=M also run on their object sets "
        "(default: --seed and the 4 after it; quick: --seed alone)",
    )
    add_workers(p)

    p = leaf(
        sub,
        "compare",
        cmd_compare,
        help="every protocol and planner side by side",
        description="Every protocol of the registry (those with coordination triggers at CI=1 and "
        f"CI=M: {', '.join(protocols.names())}) and CCP's improved planner on the same scenarios "
        "of the study's grid: mean "
        "makespan with 95 % intervals, ratio to the lower bound, messages per object, CPU per "
        "run; report.md, runs.csv, summary.csv and one figure per N.",
    )
    p.add_argument("--out", required=True, help="output directory (created if needed)")
    p.add_argument(
        "--quick", action="store_true", help="N in 10, 50 and M in 10, 50, 3 object sets (about 20 s)"
    )
    p.add_argument("--sets", type=at_least(2), help="object sets per (N, M) (default 10; quick 3)")
    p.add_argument(
        "--latency",
        type=latency,
        metavar="L[:J]",
        help="also run every protocol and planner that runs without a barrier so, at latency L + "
        "U[0, J] steps (ost sim --latency): the realtime rows beside the lockstep ones",
    )
    add_workers(p)


def out_dir(text: str) -> Path:
    """``--out``: a directory, created if needed (one-line usage errors otherwise)."""
    out = Path(text)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {text}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--out {text}: cannot create ({exc.strerror})") from None
    return out


def cmd_compare(args: argparse.Namespace) -> int:
    from ost_ros.study.compare import grid, run_all, write_all

    out = out_dir(args.out)
    tasks = grid(args.quick, args.sets)
    with executor(args) as ex:
        rows, outcome = run_all(tasks, ex, out, args.progress, args.latency)
    files = write_all(rows, outcome.timing, out)
    outcome.finish()
    print(
        f"{len(rows)} runs in {outcome.timing.wall:.1f} s{resumed(outcome.timing)}; wrote {', '.join(files)} to {out}",
        file=sys.stderr,
    )
    print((out / "report.md").read_text())
    return 0


def seed_range(text: str) -> tuple[int, ...]:
    """``A-B`` (inclusive) or ``A``: non-negative seeds, at most 20."""
    lo, sep, hi = text.partition("-")
    try:
        a, b = int(lo), int(hi) if sep else int(lo)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not A-B or A (seeds)") from None
    if a < 0 or b < a or b - a >= 20:
        raise argparse.ArgumentTypeError(f"{text!r}: need 0 <= A <= B, at most 20 seeds")
    return tuple(range(a, b + 1))


def cmd_optimal(args: argparse.Namespace) -> int:
    scenario = load_scenario_arg(args.scenario, args.agents)
    m, n = scenario.n_objects, scenario.n_agents
    if scenario.heterogeneous:
        raise UsageError(
            f"{args.scenario}: the exact search is for unit-speed teams (some agent "
            "has a period other than 1)"
        )
    if m > MAX_OPTIMAL_OBJECTS:
        raise UsageError(
            f"{args.scenario}: {m} objects is too many for the exact search (at most "
            f"{MAX_OPTIMAL_OBJECTS}; its space is ~10^{search_space_order(m, n):.0f})"
        )
    ids, cost, loc, bases, objects = post_search_problem(scenario)
    r = optimal_schedule(ids, cost, loc, bases, objects, max_nodes=args.max_nodes)
    bound = lower_bound(scenario).value
    out = {
        "objects": m,
        "agents": n,
        "search_space_order": round(search_space_order(m, n), 2),
        "free_at": cost[0] if cost else 0,
        "optimal": r.cost,
        "proven": r.proven,
        "nodes": r.nodes,
        "ccp": r.ccp_cost,
        "ccp_gap": round(r.gap, 4),
        "improved": r.improved_cost,
        "improved_gap": round(r.improved_gap, 4),
        "lower_bound": bound,
        "plan": [
            {"object": s.object, "agents": list(s.agents), "start": s.start, "finish": s.finish}
            for s in r.plan
        ],
    }
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print(
        f"post-search problem: M={m} objects, N={n} agents, all free at step {out['free_at']} "
        f"(search space ~10^{out['search_space_order']:.0f})"
    )
    print(f"optimal makespan  {r.cost}{'' if r.proven else '  (NOT proven: node budget spent)'}")
    print(f"CCP makespan      {r.ccp_cost}   gap {100 * r.gap:.2f}%  (planner paper)")
    print(f"improved planner  {r.improved_cost}   gap {100 * r.improved_gap:.2f}%")
    print(f"lower bound       {bound}   nodes searched {r.nodes}")
    print()
    print(f"{'object':>6} {'start':>7} {'finish':>7}  agents")
    for s in r.plan:
        print(f"{s.object:>6} {s.start:>7} {s.finish:>7}  {list(s.agents)}")
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    from ost_ros.study.design import Design
    from ost_ros.study.report import write_all
    from ost_ros.study.reproduce import run_design

    out = out_dir(args.out)
    design = Design.quick(args.seed) if args.quick else Design(seed=args.seed)
    from dataclasses import replace

    if args.sets is not None:
        design = replace(design, sets=args.sets)
    seeds = args.seeds or ((args.seed,) if args.quick else tuple(range(args.seed, args.seed + 5)))
    design = replace(design, table3_seeds=seeds)
    start = time.perf_counter()
    with executor(args) as ex:
        rows, outcome = run_design(design, ex, out, args.progress)
    timing = outcome.timing
    report = write_all(out, design, rows, timing, args.quick)
    outcome.finish()
    total = time.perf_counter() - start
    print(
        f"{len(rows)} runs in {timing.wall:.1f} s{resumed(timing)} ({timing.cpu:.1f} CPU s, {total:.1f} s with "
        f"tables and plots, load {timing.load:.1f})",
        file=sys.stderr,
    )
    print(report)
    return 0
