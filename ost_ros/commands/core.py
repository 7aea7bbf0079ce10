"""Core verbs: ``ost generate``, ``ost sim``, ``ost schedule``."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from ost_ros import protocols
from ost_ros import validate as v
from ost_ros.bounds import lower_bound
from ost_ros.commands import realtime
from ost_ros.commands.animation import (
    add_animate_arguments,
    add_progress_argument,
    check_animation,
    frame_recorder,
    write_animation,
)
from ost_ros.commands.args import failure, fraction, leaf, load_scenario_arg, natural, period_list, positive
from ost_ros.coordination import ORGANISATIONS, CoordinationPolicy, coordinate
from ost_ros.engines import ENGINES, StepHook, check_failures, choose_engine, simulate
from ost_ros.errors import UsageError
from ost_ros.model import DEFAULT_HEIGHT, DEFAULT_NMAX, DEFAULT_WIDTH, Grid, ObjectSpec, Scenario
from ost_ros.planner import PLANNERS, improve
from ost_ros.scenario import ScenarioError, build_scenario, dump_scenario, generate_scenario
from ost_ros.validate import FieldError
from ost_ros.world import World

OBJECT_KEYS = ("id", "location", "destination", "required")


def register(sub) -> None:
    p = leaf(
        sub,
        "generate",
        cmd_generate,
        help="write a random scenario (paper §5.1)",
        description="Write the paper's random scenario: distinct uniform object locations, "
        "uniform destinations, n_i uniform in 1..nmax; ids = rank by (x, y). "
        "The objects depend on --seed only, not on --agents.",
    )
    p.add_argument("--agents", type=positive, required=True, help="number of agents N")
    p.add_argument("--objects", type=natural, required=True, help="number of objects M")
    p.add_argument("--seed", type=natural, required=True, help="random seed")
    p.add_argument("--width", type=positive, default=DEFAULT_WIDTH, help="grid width (500)")
    p.add_argument("--height", type=positive, default=DEFAULT_HEIGHT, help="grid height (200)")
    p.add_argument(
        "--nmax", type=positive, default=DEFAULT_NMAX, help="largest number of agents an object needs (10)"
    )
    p.add_argument(
        "--periods",
        type=period_list,
        default=None,
        help="heterogeneous team: comma-separated periods (agent k moves one cell every "
        "periods[k mod len] steps), e.g. 1,1,2,3 (default: all 1, the paper's)",
    )
    p.add_argument("-o", "--output", help="file to write (default: standard output)")

    add_sim_parser(sub)

    p = leaf(
        sub,
        "schedule",
        cmd_schedule,
        help="run only the Coordination algorithm",
        description="Run Algorithm Coordination on a state file "
        '{"agents":[{"id","cost","location"[,"base"]}],'
        '"objects":[{"id","location","destination","required"}]} '
        "and print the schedule in scheduling order.",
    )
    p.add_argument("state", help="state file (JSON; '-' for standard input)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument(
        "--planner",
        choices=PLANNERS,
        default="paper",
        help="paper: Algorithm Coordination; improved: its schedule improved by a bounded local "
        "search on the makespan with every agent home (at its base; default: where it stands)",
    )


# ----------------------------------------------------------------------------- generate


def cmd_generate(args: argparse.Namespace) -> int:
    try:
        scenario = generate_scenario(
            args.agents, args.objects, args.seed, Grid(args.width, args.height), args.nmax
        )
        if args.periods:
            # a heterogeneous team: agent k moves every periods[k mod len] steps
            agents = [
                dataclasses.replace(a, period=args.periods[k % len(args.periods)])
                for k, a in enumerate(scenario.agents)
            ]
            scenario = build_scenario(
                scenario.grid,
                scenario.objects,
                partition=scenario.partition,
                agents=agents,
                nmax=scenario.nmax,
            )
    except ScenarioError as exc:
        raise UsageError(str(exc)) from None
    text = dump_scenario(scenario)
    if args.output:
        try:
            Path(args.output).write_text(text)
        except OSError as exc:
            raise UsageError(f"{args.output}: cannot write ({exc.strerror})") from None
    else:
        sys.stdout.write(text)
    return 0


# ----------------------------------------------------------------------------- sim


def add_sim_parser(sub) -> None:
    p = leaf(
        sub,
        "sim",
        cmd_sim,
        help="simulate a scenario in-process",
        description="Run a scenario in-process and print the makespan, last delivery and "
        "per-agent cost / idle / carry time. Protocols: "
        + "; ".join(f"{s.name}: {s.title}" for s in protocols.REGISTRY.values())
        + ".",
    )
    p.add_argument("scenario", help="scenario file (YAML)")
    p.add_argument("--protocol", choices=protocols.names(), default="ccp", help="cooperation protocol")
    trig = p.add_mutually_exclusive_group()
    trig.add_argument(
        "--ci",
        type=positive,
        default=1,
        help="coordination interval: coordinate when this many found objects are "
        "unscheduled (default 1; >= M means after the whole search)",
    )
    trig.add_argument("--interval", type=positive, help="coordinate every T time steps instead")
    trig.add_argument(
        "--area-fraction",
        type=fraction,
        help="coordinate each time this fraction of the area is searched instead",
    )
    add_protocol_options(p)
    p.add_argument(
        "--agents",
        type=positive,
        help="replace the scenario's team by N agents (default partition and bases)",
    )
    p.add_argument("--max-steps", type=positive, help="stop after this many steps")
    p.add_argument(
        "--coordination",
        choices=ORGANISATIONS,
        default="distributed",
        help="who runs Algorithm Coordination: every agent (distributed, default) or "
        "the lowest-id agent, which broadcasts the schedule (coordinator; ccp)",
    )
    p.add_argument(
        "--partition",
        choices=("equal", "negotiated"),
        default="equal",
        help="search areas: the paper's equal m×n partition, or negotiated among the "
        "robots by speed and private forbidden zones (ost negotiate partition)",
    )
    p.add_argument("--partition-seed", type=natural, default=0, help="seed of that negotiation (0)")
    p.add_argument(
        "--fail",
        type=failure,
        action="append",
        default=[],
        metavar="AGENT:STEP",
        help="robot AGENT fails in step STEP (repeatable; protocols that recover: "
        + ", ".join(n for n, s in protocols.REGISTRY.items() if s.capabilities.recovers_failures)
        + "): survivors re-plan",
    )
    p.add_argument(
        "--engine",
        choices=("auto", *ENGINES),
        default="auto",
        help="step: the reference, every agent every step; event: jumps from decision "
        "to decision, same result (default auto: event for big runs, step when "
        "a progress bar or a plot needs every step)",
    )
    p.add_argument("--json", action="store_true", help="print the full result as JSON")
    p.add_argument("--plot", metavar="PNG", help="also draw the map and every agent's timeline")
    add_animate_arguments(p)
    add_progress_argument(p)
    realtime.add_arguments(p)  # --latency L[:J] and its options: the run without a barrier


def add_protocol_options(p: argparse.ArgumentParser) -> None:
    """Every protocol's own options (the registry's), as flags."""
    seen: set[str] = set()
    for spec in protocols.REGISTRY.values():
        for opt in spec.options:
            if opt.name in seen:  # an option two protocols share (same settings field): once
                continue
            seen.add(opt.name)
            default = protocols.option_default(spec, opt)
            p.add_argument(
                opt.flag,
                dest=opt.name,
                type=type(default),
                default=None,
                help=f"{spec.name.upper()}: {opt.help} (default {default})",
            )


def protocol_settings(args: argparse.Namespace) -> Any:
    """The chosen protocol's settings from its flags (one-line error for a bad value, or for a
    flag of another protocol)."""
    spec = protocols.get(args.protocol)
    own = {o.name for o in spec.options}
    for other in protocols.REGISTRY.values():
        for opt in other.options:
            if opt.name not in own and getattr(args, opt.name, None) is not None:
                raise UsageError(f"{opt.flag} is an option of {other.name}, not of {args.protocol}")
    try:
        return protocols.settings_from(args.protocol, vars(args))
    except protocols.ProtocolError as exc:
        raise UsageError(str(exc)) from None


def cmd_sim(args: argparse.Namespace) -> int:
    settings = protocol_settings(args)
    scenario = load_scenario_arg(args.scenario, args.agents)
    policy = CoordinationPolicy(
        ci=args.ci, interval=args.interval, area_fraction=args.area_fraction, organisation=args.coordination
    )
    failures = dict(args.fail)
    if len(failures) != len(args.fail):
        raise UsageError("--fail: an agent can fail only once")
    _check_protocol(args, policy=policy)
    if args.partition == "negotiated":
        scenario = _negotiated(args, scenario)
    _check_protocol(args, scenario=scenario, where=args.scenario)
    if failures:
        try:
            check_failures(scenario, args.protocol, failures, policy)
        except ValueError as exc:
            raise UsageError(f"--fail: {exc}") from None
    realtime.check(args)
    if args.latency is not None:  # the run without a barrier (ost_ros.realtime)
        return realtime.run(args, scenario, policy, settings, failures)
    if args.animate:
        check_animation(args)
    engine = _sim_engine(args, scenario, policy, failures)
    hooks, bar, timeline = _step_hooks(args, scenario, engine)
    recorder = frame_recorder(args, scenario)
    if recorder is not None:
        hooks.append(recorder)
    try:
        result = simulate(
            scenario,
            args.protocol,
            policy,
            max_steps=args.max_steps,
            on_step=_each(hooks) if hooks else None,
            engine=engine,
            settings=settings,
            failures=failures,
        )
    finally:
        if bar is not None:
            bar.close()
    result.lower_bound = lower_bound(scenario).value
    if timeline is not None:
        from ost_ros.plot import plot_run

        try:
            plot_run(scenario, result, timeline, args.plot)
        except OSError as exc:
            raise UsageError(f"{args.plot}: cannot write ({exc.strerror})") from None
    if recorder is not None:
        write_animation(args, scenario, result, recorder)
    print(json.dumps(result.to_dict(), indent=1) if args.json else result.summary())
    return 0 if result.completed else 1


def _check_protocol(args: argparse.Namespace, where: str = "", **what: Any) -> None:
    try:
        protocols.check(args.protocol, **what)
    except protocols.ProtocolError as exc:
        raise UsageError(f"{where}: {exc}" if where else str(exc)) from None


def _negotiated(args: argparse.Namespace, scenario: Scenario) -> Scenario:
    """The scenario with search areas negotiated among its robots."""
    if not protocols.get(args.protocol).capabilities.own_sweeps:
        able = ", ".join(n for n, s in protocols.REGISTRY.items() if s.capabilities.own_sweeps)
        raise UsageError(
            f"--partition negotiated: {args.protocol} cannot run robots with their own "
            f"sweeps; use --protocol {' or '.join(able.split(', '))}"
        )
    from ost_ros.negotiation.errors import NegotiationError
    from ost_ros.negotiation.partition import negotiated_scenario

    try:
        return negotiated_scenario(scenario, seed=args.partition_seed)[0]
    except (NegotiationError, ScenarioError) as exc:
        raise UsageError(f"--partition negotiated: {exc}") from None


def _sim_engine(
    args: argparse.Namespace, scenario: Scenario, policy: CoordinationPolicy, failures: dict[int, int]
) -> str:
    """The engine to run on: the one asked for; auto picks the event engine for big runs unless a
    plot or a progress bar needs every step; failures and the coordinator need the step engine."""
    for flag, needs_steps in (
        ("--fail: robot failures run", bool(failures)),
        ("--coordination coordinator runs", policy.centralised),
    ):
        if needs_steps and args.engine == "event":
            raise UsageError(f"{flag} on the step engine (--engine step)")
        if needs_steps:
            return "step"
    if args.engine == "auto":
        return "step" if (args.plot or args.animate or args.progress) else choose_engine(scenario)
    if args.engine == "event" and args.animate:
        raise UsageError("--animate: the animation needs every step (--engine step or auto)")
    return str(args.engine)


def _step_hooks(args: argparse.Namespace, scenario: Scenario, engine: str):
    """What watches every step (only the step engine has steps): the plot's timeline and the
    progress bar."""
    from ost_ros.plot import Timeline

    hooks: list[StepHook] = []
    timeline = Timeline() if args.plot else None
    if timeline is not None:
        hooks.append(timeline)
    show = sys.stderr.isatty() if args.progress is None else args.progress
    bar = None
    if show and engine == "step":
        from tqdm import tqdm

        bar = tqdm(total=len(scenario.objects), desc="delivered", unit="obj", file=sys.stderr, leave=False)

        def progress(world: World, _actions: list) -> None:
            done = sum(o.delivered is not None for o in world.objects.values())
            if done != bar.n:
                bar.update(done - bar.n)
            if world.t % 500 == 0:
                bar.set_postfix(step=world.t, refresh=False)

        hooks.append(progress)
    return hooks, bar, timeline


def _each(hooks: list[StepHook]) -> StepHook:
    def on_step(world: World, actions: list) -> None:
        for hook in hooks:
            hook(world, actions)

    return on_step


# ----------------------------------------------------------------------------- schedule


def parse_state(
    data: Any,
) -> tuple[list[int], list[int], list[tuple[int, int]], list[tuple[int, int]], list[ObjectSpec]]:
    """Validate a coordination state document; returns ids, costs, locations, bases (sorted by
    id; a missing base is the agent's location), objects."""
    data = v.mapping(data, "state", ("agents", "objects"), ("agents", "objects"))
    agents = []
    for k, a in enumerate(v.listing(data["agents"], "agents")):
        a = v.mapping(a, f"agents[{k}]", ("id", "cost", "location", "base"), ("id", "cost", "location"))
        at = v.cell(a["location"], f"agents[{k}].location")
        agents.append(
            (
                v.integer(a["id"], f"agents[{k}].id", 0),
                v.integer(a["cost"], f"agents[{k}].cost", 0),
                at,
                v.cell(a["base"], f"agents[{k}].base") if "base" in a else at,
            )
        )
    if not agents:
        raise FieldError("agents: the team needs at least one agent")
    agents.sort()
    for (x, *_), (y, *_) in zip(agents, agents[1:]):
        if x == y:
            raise FieldError(f"agents: duplicate id {x}")
    objects, seen = [], set()
    for k, o in enumerate(v.listing(data["objects"], "objects")):
        where = f"objects[{k}]"
        o = v.mapping(o, where, OBJECT_KEYS, OBJECT_KEYS)
        obj = ObjectSpec(
            v.integer(o["id"], where + ".id", 0),
            v.cell(o["location"], where + ".location"),
            v.cell(o["destination"], where + ".destination"),
            v.integer(o["required"], where + ".required", 1),
        )
        if obj.id in seen:
            raise FieldError(f"{where}.id: duplicate id {obj.id}")
        if obj.required > len(agents):
            raise FieldError(f"{where}.required: {obj.required} exceeds the team of {len(agents)} agents")
        seen.add(obj.id)
        objects.append(obj)
    return (
        [a[0] for a in agents],
        [a[1] for a in agents],
        [a[2] for a in agents],
        [a[3] for a in agents],
        objects,
    )


def cmd_schedule(args: argparse.Namespace) -> int:
    try:
        text = sys.stdin.read() if args.state == "-" else Path(args.state).read_text()
    except FileNotFoundError:
        raise UsageError(f"{args.state}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"{args.state}: cannot read ({exc.__class__.__name__})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UsageError(f"{args.state}: invalid JSON at line {exc.lineno}: {exc.msg}") from None
    try:
        ids, cost, loc, bases, objects = parse_state(data)
    except FieldError as exc:
        raise UsageError(str(exc)) from None
    if args.planner == "improved":
        result = improve(ids, cost, loc, objects, bases)
    else:
        result = coordinate(ids, cost, loc, objects)
    out = {
        "schedule": [
            {"object": a.object, "agents": list(a.agents), "start": a.start, "finish": a.finish}
            for a in result.schedule
        ],
        "agents": [
            {"id": i, "cost": int(c), "location": [int(v) for v in xy]}
            for i, c, xy in zip(ids, result.cost, result.loc)
        ],
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"{'object':>6} {'start':>7} {'finish':>7}  agents")
        for s in out["schedule"]:
            print(f"{s['object']:>6} {s['start']:>7} {s['finish']:>7}  {s['agents']}")
        print()
        print(f"{'agent':>6} {'cost':>7}  location")
        for a in out["agents"]:
            print(f"{a['id']:>6} {a['cost']:>7}  {a['location']}")
    return 0
