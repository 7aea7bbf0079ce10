"""``ost negotiate …``: run one negotiation, or reproduce the paper's figures and tables.

ost negotiate run --task area --robots 3 [--delta 0.98] [--json]
ost negotiate run --file task.yaml [--json]
ost negotiate reproduce --out DIR [--quick] [--seed S] [--runs K] [--jobs J | --cluster ADDRESS]
ost negotiate partition [--file team.yaml] [--robots N --periods 1,2,1 --width W --height H] [--json] [--plot F.png]
ost negotiate partition --scenario s.yaml [-o negotiated.yaml]
ost negotiate slots --scenario s.yaml [--delta D] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from ost_ros.commands.args import OneLineParser, add_workers, at_least, executor, resumed
from ost_ros.errors import UsageError
from ost_ros.negotiation.errors import NegotiationError
from ost_ros.yamlload import safe_load

TASK_TYPES = ("area", "targets")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``negotiate`` and its subcommands to the ``ost`` parser."""
    p = subparsers.add_parser(
        "negotiate",
        help="negotiation-based task subdivision and allocation (Rossi et al.)",
        description="Negotiate how to split an area or a set of target points among robots.",
    )
    sub = p.add_subparsers(dest="negotiate_cmd", metavar="CMD", parser_class=OneLineParser)

    run = sub.add_parser("run", help="run one negotiation from flags or a YAML/JSON task file")
    run.add_argument("--file", type=Path, help="YAML or JSON task file (flags given too override it)")
    run.add_argument("--task", help="task type: area or targets (default area)")
    run.add_argument("--robots", type=int, help="number of robots (default 2)")
    run.add_argument(
        "--delta", help="discount factor(s), one or comma-separated per robot (default 0.98 / 0.9)"
    )
    run.add_argument("--polygon", help='area task polygon "x,y;x,y;..." (default: the 0.673 hexagon)')
    run.add_argument("--targets", type=int, help="targets task: number of random points (default 5)")
    run.add_argument("--strategy", help="rounds or all-against-all (default rounds)")
    run.add_argument(
        "--drop-rule", help="targets: furthest (§4.2, default), path (§5.1) or reward (the earlier rule)"
    )
    run.add_argument(
        "--stopping", help="areas: paper (Eq. 3 test, default) or overlap (the earlier 2 %% overlap exit)"
    )
    run.add_argument("--seed", type=at_least(0), help="random seed, 0 or more (default 0)")
    run.add_argument("--max-rounds", type=int, help="time-out in rounds (default 400)")
    run.add_argument("--json", action="store_true", help="print the result as JSON")
    run.set_defaults(func=cmd_run, prog=run.prog)

    rep = sub.add_parser("reproduce", help="reproduce Fig. 4, Tables 2-4 and the NFZ example into a report")
    rep.add_argument("--out", type=Path, required=True, help="output directory (CSVs, PNGs, report.md)")
    rep.add_argument("--quick", action="store_true", help="few runs per cell (well under a minute)")
    rep.add_argument("--seed", type=at_least(0), default=0, help="base seed, 0 or more (default 0)")
    rep.add_argument("--runs", type=int, help="runs per table cell (default 10, quick 2-3)")
    add_workers(rep, jobs="up to 2 cores")
    rep.set_defaults(func=cmd_reproduce, prog=rep.prog)

    part = sub.add_parser(
        "partition",
        help="negotiate search subareas for robots of different speeds; compare "
        "with the paper's equal partition",
    )
    part.add_argument(
        "--file",
        type=Path,
        help="YAML/JSON team file: grid: {width, height}, robots: [{id, period, "
        "forbidden: [[x0, y0, x1, y1], ...]}], delta (flags override it)",
    )
    part.add_argument(
        "--robots", type=int, help="number of robots (default 4, or as many as --periods / the file give)"
    )
    part.add_argument(
        "--periods", help="steps per cell moved, comma-separated, one per robot (default 1 each)"
    )
    part.add_argument("--width", type=int, help="grid width in cells (default 100)")
    part.add_argument("--height", type=int, help="grid height in cells (default 40)")
    part.add_argument("--delta", type=float, help="the fastest robot's discount factor (default 0.95)")
    part.add_argument("--rule", help="where the speed preference lives: patience (default) or reward")
    part.add_argument("--seed", type=int, help="random seed (default 0)")
    part.add_argument("--max-rounds", type=int, help="time-out in rounds (default 200)")
    part.add_argument(
        "--scenario",
        type=Path,
        help="an OST scenario: its grid and robots (periods, forbidden zones) form the team",
    )
    part.add_argument(
        "-o",
        "--output",
        type=Path,
        help="with --scenario: write the scenario with every robot sweeping its negotiated region",
    )
    part.add_argument("--json", action="store_true", help="print the result as JSON")
    part.add_argument("--plot", type=Path, help="write the ownership maps (negotiated, equal) to this PNG")
    part.set_defaults(func=cmd_partition, prog=part.prog)

    slots = sub.add_parser(
        "slots", help="the slot negotiation NCP runs: a scenario's objects allocated after the whole search"
    )
    slots.add_argument("--scenario", type=Path, required=True, help="an OST scenario (YAML)")
    slots.add_argument("--delta", type=float, help="claim discount per round, in (0, 1) (default 0.8)")
    slots.add_argument(
        "--timeout", type=int, help="rounds without an answer before a negotiator is left out (default 3)"
    )
    slots.add_argument("--json", action="store_true", help="print the result as JSON")
    slots.set_defaults(func=cmd_slots, prog=slots.prog)

    p.set_defaults(func=lambda args: (p.print_help(), 2)[1], prog=p.prog)


# ------------------------------------------------------------------ task files ------------------
def load_task_file(path: Path) -> dict[str, Any]:
    """Read a YAML/JSON task description into a dict (one-line errors)."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise UsageError(f"cannot read task file {path}: {exc.strerror or exc}") from None
    try:
        if path.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            data = safe_load(text)
    except Exception as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise UsageError(
            f"task file {path} is not valid {'JSON' if path.suffix.lower() == '.json' else 'YAML'}: {first}"
        ) from None
    if not isinstance(data, dict):
        raise UsageError(f"task file {path} must hold a mapping (task:, robots:, ...)")
    return data


def build_from_spec(spec: dict[str, Any]) -> tuple[Any, list[Any], dict[str, Any]]:
    """(task, agents, options) from a plain dict: the file format and the flags share it."""
    known = {
        "task",
        "polygon",
        "area",
        "points",
        "weights",
        "targets",
        "robots",
        "delta",
        "strategy",
        "seed",
        "max_rounds",
        "drop_rule",
        "stopping",
        "start",
    }
    extra = sorted(set(spec) - known)
    if extra:
        raise NegotiationError(f"unknown key(s) in task description: {', '.join(extra)}")
    kind = str(spec.get("task", "area"))
    if kind not in TASK_TYPES:
        raise NegotiationError(f"unknown task type {kind!r} (expected area or targets)")
    seed = _int(spec.get("seed", 0), "seed")
    if seed < 0:
        raise NegotiationError(f"seed must be 0 or more, got {seed}")
    entries = _robot_entries(spec.get("robots", 2))
    deltas = _deltas(spec.get("delta", 0.98 if kind == "area" else 0.9), len(entries))
    task = _task(kind, spec, seed)
    agents = [_agent(i, e, d, kind, task, spec) for i, (e, d) in enumerate(zip(entries, deltas))]
    opts = {
        "strategy": str(spec.get("strategy", "rounds")),
        "seed": seed,
        "max_rounds": _int(spec.get("max_rounds", 400), "max_rounds"),
        "drop_rule": str(spec.get("drop_rule", "furthest")),
        "stopping": str(spec.get("stopping", "paper")),
    }
    return task, agents, opts


def _robot_entries(robots: Any) -> list[Any]:
    if isinstance(robots, list):
        entries = robots
    else:
        n = _int(robots, "robots")
        if n < 1:
            raise NegotiationError(f"need at least one robot, got {n}")
        entries = [{} for _ in range(n)]
    if not entries:
        raise NegotiationError("need at least one robot, got 0")
    return entries


def _deltas(deltas: Any, robots: int) -> list[Any]:
    """One discount factor per robot: a list, a comma-separated string, or one for all."""
    if isinstance(deltas, str):
        deltas = [d for d in deltas.split(",") if d.strip()]
    if not isinstance(deltas, list):
        deltas = [deltas] * robots
    if len(deltas) == 1:
        deltas = deltas * robots
    if len(deltas) != robots:
        raise NegotiationError(f"got {len(deltas)} discount factors for {robots} robots")
    return deltas


def _task(kind: str, spec: dict[str, Any], seed: int) -> Any:
    import numpy as np

    from ost_ros.negotiation.tasks import AreaTask, TargetTask, make_task_polygon, polygon_from_vertices

    if kind == "area":
        if "polygon" in spec:
            return AreaTask(polygon_from_vertices(spec["polygon"], "task polygon"))
        return AreaTask(make_task_polygon(float(spec.get("area", 0.673))))
    if "points" in spec:
        return TargetTask.from_points(spec["points"], spec.get("weights"))
    n = _int(spec.get("targets", 5), "targets")
    if n < 1:
        raise NegotiationError(f"need at least one target, got {n}")
    return TargetTask.from_points(np.random.default_rng(seed).random((n, 2)))


def _agent(i: int, e: Any, d: Any, kind: str, task: Any, spec: dict[str, Any]) -> Any:
    """Robot i of the description: its discount factor and private reward."""
    from ost_ros.negotiation.agents import AgentSpec
    from ost_ros.negotiation.rewards import AreaReward, TargetReward
    from ost_ros.negotiation.scenarios import ROBOT_START
    from ost_ros.negotiation.tasks import polygon_from_vertices

    if not isinstance(e, dict):
        raise NegotiationError(f"robot {i + 1}: expected a mapping (delta:, start:, forbidden:)")
    d = e.get("delta", d)
    try:
        d = float(d)
    except (TypeError, ValueError):
        raise NegotiationError(f"robot {i + 1}: discount factor must be a number, got {d!r}") from None
    x, y = (float(v) for v in e.get("start", spec.get("start", ROBOT_START)))
    start = (x, y)
    reward: AreaReward | TargetReward
    if kind == "area":
        zone = e.get("forbidden")
        reward = AreaReward(
            forbidden=polygon_from_vertices(zone, f"robot {i + 1} forbidden zone") if zone else None
        )
    else:
        forb = frozenset(int(j) for j in e.get("forbidden", []))
        if any(not 0 <= j < task.n for j in forb):
            raise NegotiationError(f"robot {i + 1}: forbidden target index out of range 0..{task.n - 1}")
        reward = TargetReward(start=start, forbidden=forb)
    return AgentSpec(d, reward, name=f"robot {i + 1}")


def _int(v: Any, name: str) -> int:
    try:
        if isinstance(v, bool) or float(v) != int(float(v)):
            raise ValueError
        return int(float(v))
    except (TypeError, ValueError):
        raise NegotiationError(f"{name} must be an integer, got {v!r}") from None


# ------------------------------------------------------------------ commands --------------------
def cmd_run(args: argparse.Namespace) -> int:
    from ost_ros.negotiation.multiparty import negotiate
    from ost_ros.negotiation.optimal import evaluate_allocation
    from ost_ros.negotiation.tasks import TargetTask

    spec: dict[str, Any] = load_task_file(args.file) if args.file else {}
    flags = {
        "task": args.task,
        "robots": args.robots,
        "delta": args.delta,
        "targets": args.targets,
        "strategy": args.strategy,
        "seed": args.seed,
        "max_rounds": args.max_rounds,
        "drop_rule": args.drop_rule,
        "stopping": args.stopping,
    }
    spec.update({k: v for k, v in flags.items() if v is not None})
    if args.polygon:
        try:
            spec["polygon"] = [
                [float(x) for x in pt.split(",")] for pt in args.polygon.split(";") if pt.strip()
            ]
        except ValueError:
            raise UsageError(f'--polygon must look like "x,y;x,y;x,y", got {args.polygon!r}') from None
    try:
        task, agents, opts = build_from_spec(spec)
        t = time.perf_counter()
        res = negotiate(
            task,
            agents,
            strategy=opts["strategy"],
            seed=opts["seed"],
            max_rounds=opts["max_rounds"],
            drop_rule=opts["drop_rule"],
            stopping=opts["stopping"],
            trace=False,
        )
    except NegotiationError as exc:
        raise UsageError(str(exc)) from None
    elapsed = time.perf_counter() - t
    out = res.to_dict()
    out["elapsed_s"] = round(elapsed, 3)
    out["robots"] = [
        {"delta": a.delta, "share": task.dim(task.inside(s)) / task.size} for a, s in zip(agents, res.shares)
    ]
    if isinstance(task, TargetTask):
        import numpy as np

        from ost_ros.negotiation.optimal import route_is_exact

        starts = np.array([a.reward.start for a in agents])
        alloc = evaluate_allocation(starts, task.points, res.shares)
        for r, s, length in zip(out["robots"], res.shares, alloc.lengths):
            r["targets"] = sorted(s)
            r["route_length"] = length
            r["route_exact"] = route_is_exact(len(s))
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    m = out["metrics"]
    print(
        f"{task.kind} task, {len(agents)} robots, {opts['strategy']}: {res.status} after {res.rounds} rounds, "
        f"{res.messages} messages, {elapsed:.2f} s"
    )
    print(
        f"overlap {100 * m['overlap']:.2f} %  G {m['G']:.4f}  covered {100 * m['covered']:.1f} %  out {100 * m['out']:.2f} %"
    )
    for i, r in enumerate(out["robots"]):
        extra = ""
        if "targets" in r:
            how = "" if r["route_exact"] else " (nearest neighbour + 2-opt: over 12 targets)"
            extra = f"  targets {r['targets']}  route {r['route_length']:.3f}{how}"
        print(f"robot {i + 1} (δ={r['delta']:g}): share {100 * r['share']:.1f} %{extra}")
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    import os

    from ost_ros.study.negotiation import reproduce

    if args.runs is not None and args.runs < 1:
        raise UsageError(f"--runs must be at least 1, got {args.runs}")
    if args.out.exists() and not args.out.is_dir():
        raise UsageError(f"--out {args.out} exists and is not a directory")
    try:
        with executor(args, jobs=min(2, os.cpu_count() or 1)) as ex:
            summary = reproduce(
                args.out, ex, quick=args.quick, seed=args.seed, runs=args.runs, progress=args.progress
            )
    except NegotiationError as exc:
        raise UsageError(str(exc)) from None
    except OSError as exc:
        raise UsageError(f"cannot write into {args.out}: {exc.strerror or exc}") from None
    print(
        f"report written to {args.out / 'report.md'} ({summary['elapsed_s']:.1f} s{resumed(summary['timing'])})"
    )
    return 0


def cmd_partition(args: argparse.Namespace) -> int:
    from ost_ros.negotiation.partition import SearchTeam, apply_flags, negotiate_partition

    for flag, path in (("--plot", args.plot), ("--output", args.output)):
        if path is not None and not path.resolve().parent.is_dir():
            raise UsageError(f"{flag} {path}: directory {path.parent} does not exist")
    if args.output is not None and args.scenario is None:
        raise UsageError("--output: needs --scenario (the scenario to write with negotiated sweeps)")
    if args.scenario is not None:
        given = [
            f
            for f, v in (
                ("--file", args.file),
                ("--robots", args.robots),
                ("--periods", args.periods),
                ("--width", args.width),
                ("--height", args.height),
            )
            if v is not None
        ]
        if given:
            raise UsageError(f"--scenario: the team comes from the scenario, not {given[0]}")
        from ost_ros.negotiation.partition import negotiated_scenario
        from ost_ros.scenario import ScenarioError, dump_scenario, load_scenario

        try:
            base = load_scenario(args.scenario)
            scenario, result = negotiated_scenario(
                base,
                delta=0.95 if args.delta is None else args.delta,
                seed=args.seed or 0,
                max_rounds=args.max_rounds or 200,
                rule=args.rule or "patience",
            )
        except (ScenarioError, NegotiationError) as exc:
            raise UsageError(str(exc)) from None
        if args.output is not None:
            try:
                args.output.write_text(dump_scenario(scenario))
            except OSError as exc:
                raise UsageError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    else:
        spec: dict[str, Any] = load_task_file(args.file) if args.file else {}
        try:
            spec = apply_flags(
                spec,
                width=args.width,
                height=args.height,
                robots=args.robots,
                periods=args.periods,
                delta=args.delta,
                seed=args.seed,
                max_rounds=args.max_rounds,
                rule=args.rule,
            )
            team = SearchTeam.from_spec(spec)
            result = negotiate_partition(team)
        except NegotiationError as exc:
            raise UsageError(str(exc)) from None
    if args.plot is not None:
        try:
            result.plot(args.plot)
        except (OSError, ValueError) as exc:  # unwritable path, unknown image format
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise UsageError(f"cannot write plot {args.plot}: {first}") from None
    print(json.dumps(result.to_dict(), indent=2) if args.json else result.table())
    return 0


def cmd_slots(args: argparse.Namespace) -> int:
    """Every object of the scenario negotiated at once, as NCP does when it coordinates only after
    the whole search (CI > M): robots at the ends of their sweeps, free one step after the last
    search ends. The same :mod:`ost_ros.negotiation.slots` code NCP's comm modules run."""
    from ost_ros.negotiation.slots import NegotiationSettings, after_search, negotiate_slots
    from ost_ros.scenario import ScenarioError, load_scenario

    try:
        scenario = load_scenario(args.scenario)
        settings = NegotiationSettings(
            **{k: v for k, v in (("delta", args.delta), ("timeout_rounds", args.timeout)) if v is not None}
        )
    except (ScenarioError, NegotiationError) as exc:
        raise UsageError(str(exc)) from None
    objects, reach, ids = after_search(scenario)
    if not objects:
        raise UsageError(f"{args.scenario}: no objects to negotiate")
    neg, moves = negotiate_slots(objects, reach, ids, settings)
    groups = neg.groups(ids)
    if args.json:
        print(
            json.dumps(
                {
                    "rounds": neg.round,
                    "moves": moves,
                    "forced": neg.forced,
                    "groups": {str(o): list(g) for o, g in groups.items()},
                },
                indent=1,
            )
        )
        return 0
    how = "closed by the protection rule" if neg.forced else "everyone left with an uncontested claim"
    print(f"{len(objects)} objects, {len(ids)} robots: {neg.round} rounds, {moves} moves ({how})")
    for o in objects:
        print(f"object {o.id:>4} (needs {o.required}): robots {list(groups[o.id])}")
    return 0
