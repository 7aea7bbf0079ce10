"""``ost sim SCENARIO --latency L[:J]``: the run without a barrier, in process — the realtime
runtimes on a discrete-event network whose copies of each message take L + U{0..J} steps
(seeded), with speed noise and stalls as options. Output as ``ost sim``; JSON adds ``mode``,
``latency``, ``disagreements`` and each agent's largest lag (docs/realtime.md). ``--plot`` and
``--animate`` draw it with who was in the team when."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.errors import UsageError
from ost_ros.model import Scenario
from ost_ros.protocols import ProtocolError
from ost_ros.realtime.net import parse_split


def latency(text: str) -> tuple[float, float]:
    """argparse type: L or L:J, steps ≥ 0 (integers or decimals)."""
    base, sep, jitter = text.partition(":")
    try:
        lat, jit = float(base), float(jitter) if sep else 0.0
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected L or L:J (steps), got {text!r}") from None
    if lat < 0 or jit < 0 or lat != lat or jit != jit or lat == float("inf") or jit == float("inf"):
        raise argparse.ArgumentTypeError(f"latency and jitter must be finite and ≥ 0, got {text!r}")
    return lat, jit


def stall(text: str) -> tuple[int, int, int]:
    """argparse type: AGENT:STEP:S (robot AGENT stands still for S steps from step STEP)."""
    parts = text.split(":")
    try:
        a, t, s = (int(x) for x in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected AGENT:STEP:STEPS, got {text!r}") from None
    if a < 0 or t < 0 or s < 1:
        raise argparse.ArgumentTypeError(f"expected AGENT:STEP:STEPS (≥ 0, ≥ 0, ≥ 1), got {text!r}")
    return a, t, s


def join(text: str) -> tuple[int, int]:
    """argparse type: AGENT:STEP (robot AGENT joins at step STEP > 0)."""
    parts = text.split(":")
    try:
        a, t = (int(x) for x in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected AGENT:STEP, got {text!r}") from None
    if a < 0 or t < 1:
        raise argparse.ArgumentTypeError(f"expected AGENT:STEP (≥ 0, ≥ 1), got {text!r}") from None
    return a, t


def split(text: str) -> tuple[tuple[frozenset[int], ...], int, int]:
    """argparse type: GROUPS:STEP:S, GROUPS robots by commas, groups by slashes (0,1,2/3,4)."""
    try:
        return parse_split(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).replace("GROUPS:T:S", "GROUPS:STEP:S")) from None


def positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid number {text!r}") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return value


def jitter(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid number {text!r}") from None
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be ≥ 0, got {text!r}")
    return value


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("without a barrier (realtime runtimes, in process)")
    g.add_argument(
        "--latency",
        type=latency,
        metavar="L[:J]",
        help="run without a barrier: every message takes L steps plus up to J more (seeded, per "
        "receiver); 0 gives ost sim's result (every protocol: ccp with either planner, ncp, auction, "
        "greedy, hcp)",
    )
    g.add_argument(
        "--base-delay",
        type=latency,
        default=None,
        metavar="L[:J]",
        help="every robot's base is across a network, as an agent node's: its goals and its base's "
        "events take L steps plus up to J more (seeded, in order), and it decides on its own picture "
        "of its base (needs --latency)",
    )
    g.add_argument("--latency-seed", type=int, default=None, metavar="S", help="seed of the delays (0)")
    g.add_argument(
        "--speed-jitter",
        type=jitter,
        default=None,
        metavar="X",
        help="each goal's time per cell is multiplied by a seeded draw in [1, 1+X] (needs --latency)",
    )
    g.add_argument(
        "--stall",
        type=stall,
        action="append",
        default=[],
        metavar="AGENT:STEP:S",
        help="robot AGENT stands still for S steps from step STEP (repeatable; needs --latency)",
    )
    g.add_argument(
        "--silence",
        type=stall,
        action="append",
        default=[],
        metavar="AGENT:STEP:S",
        help="robot AGENT's process stops for S steps from step STEP (its base goes on): past "
        "--failure-timeout it is declared out, and comes back when it runs again (repeatable)",
    )
    g.add_argument(
        "--join",
        type=join,
        action="append",
        default=[],
        metavar="AGENT:STEP",
        help="robot AGENT is not there at the start and joins at step STEP (repeatable)",
    )
    g.add_argument(
        "--split",
        type=split,
        action="append",
        default=[],
        metavar="GROUPS:STEP:S",
        help="a partition: from step STEP for S steps nothing passes between the groups (robots "
        "by commas, groups by slashes: 0,1,2/3,4); held, delivered when it heals (repeatable)",
    )
    g.add_argument(
        "--split-mode",
        choices=("held", "lost"),
        default=None,
        help="what a partition does with what crosses it: holds it until the heal (held, the "
        "default), or loses it — the robots say it again when it heals (lost)",
    )
    g.add_argument(
        "--failure-timeout",
        type=positive,
        default=None,
        metavar="T",
        help="steps of silence after which a robot is declared out (10; with --silence/--join)",
    )


def check(args: argparse.Namespace) -> None:
    """The realtime options make sense together (one line otherwise)."""
    if args.latency is None:
        for flag, given in (
            ("--latency-seed", args.latency_seed is not None),
            ("--speed-jitter", args.speed_jitter is not None),
            ("--base-delay", args.base_delay is not None),
            ("--stall", bool(args.stall)),
            ("--silence", bool(args.silence)),
            ("--join", bool(args.join)),
            ("--split", bool(args.split)),
            ("--split-mode", args.split_mode is not None),
            ("--failure-timeout", args.failure_timeout is not None),
        ):
            if given:
                raise UsageError(f"{flag} needs --latency (the run without a barrier)")
        return
    if args.split_mode is not None and not args.split:
        raise UsageError("--split-mode needs --split")
    if args.engine != "auto":
        raise UsageError("--engine is for the lockstep engines, not with --latency")


def _faults(args: argparse.Namespace, scenario: Scenario, failures: dict[int, int]) -> dict[int, int]:
    """The robots the fault options name are in the team, and make sense together (one line
    otherwise); the joins, agent -> step."""
    ids = {a.id for a in scenario.agents}
    for flag, given in (("--stall", args.stall), ("--silence", args.silence), ("--join", args.join)):
        for a, *_ in given:
            if a not in ids:
                raise UsageError(f"{flag}: no agent {a} (team {sorted(ids)})")
    for groups, _, _ in args.split:
        unknown = sorted(a for g in groups for a in g if a not in ids)
        if unknown:
            raise UsageError(f"--split: no agents {unknown} (team {sorted(ids)})")
    joins = dict(args.join)
    if joins:
        from ost_ros.realtime.run import refused

        why = refused(args.protocol, "join")
        if why:
            raise UsageError(f"--join: {why}")
    if len(joins) != len(args.join):
        raise UsageError("--join: an agent can join only once")
    for a in joins:
        if a in failures:
            raise UsageError(f"--join: agent {a} also fails (--fail)")
    if joins and len(joins) == len(ids):
        raise UsageError("--join: somebody must be there at the start")
    return joins


def _plot(path: str, scenario: Scenario, result: Any, report: Any) -> None:
    """The run drawn: the map, every robot's timeline from its base's goals (who was out when),
    the partitions shaded."""
    from ost_ros.plot import Timeline, plot_run

    timeline = Timeline.of_labels(report.labels, float(result.steps))
    timeline.splits = [(s[0], float(s[1]), float(s[2])) for s in report.to_dict()["membership"]["splits"]]
    try:
        plot_run(scenario, result, timeline, path)
    except OSError as exc:
        raise UsageError(f"{path}: cannot write ({exc.strerror})") from None


def run(
    args: argparse.Namespace,
    scenario: Scenario,
    policy: CoordinationPolicy,
    settings: Any,
    failures: dict[int, int],
) -> int:
    """The realtime run of ``ost sim``: print the result (text or JSON), exit 0 if completed."""
    from ost_ros.realtime.net import Latency, Split
    from ost_ros.realtime.run import check_realtime, run_realtime

    try:
        check_realtime(args.protocol, policy)
    except ProtocolError as exc:
        raise UsageError(f"--latency: {exc}") from None
    joins = _faults(args, scenario, failures)
    lat, jit = args.latency
    recorder = None
    if args.animate:
        from ost_ros.commands.animation import check_animation
        from ost_ros.watch.frames import RealtimeRecorder

        check_animation(args)
        recorder = RealtimeRecorder(scenario, every=args.every)
    result, report = run_realtime(
        scenario,
        args.protocol,
        policy,
        settings,
        latency=Latency(lat, jit),
        seed=args.latency_seed or 0,
        speed_jitter=args.speed_jitter or 0.0,
        stalls=[(a, float(t), float(s)) for a, t, s in args.stall],
        failures=failures,
        max_steps=args.max_steps,
        silences=[(a, float(t), float(s)) for a, t, s in args.silence],
        joins={a: float(t) for a, t in joins.items()},
        failure_timeout=args.failure_timeout or 10.0,
        splits=[Split(g, float(t), float(s), lost=args.split_mode == "lost") for g, t, s in args.split],
        observe=recorder,
        base_delay=Latency(*args.base_delay) if args.base_delay is not None else None,
    )
    result.lower_bound = lower_bound(scenario).value
    if args.plot:
        _plot(args.plot, scenario, result, report)
    if recorder is not None:
        from ost_ros.commands.animation import write_animation

        heading = f"latency {report.to_dict()['latency'][0]}+0..{report.to_dict()['latency'][1]}"
        write_animation(args, scenario, result, recorder, heading=heading)
    if args.json:
        print(json.dumps(result.to_dict() | report.to_dict(), indent=1))
    else:
        print(result.summary())
        lags = report.lag.values()
        print(
            f"\nrealtime        latency {report.to_dict()['latency'][0]}"
            f"+0..{report.to_dict()['latency'][1]} steps (seed {report.seed}), "
            f"disagreements {report.disagreements} in {report.coordinations} coordinations, "
            f"largest lag {max(lags, default=0):g} steps"
        )
        if report.base_delay is not None:
            d = report.to_dict()["base_delay"]
            print(f"bases           across a network: goals and base events {d[0]}+0..{d[1]} steps late")
        if args.silence or joins:
            m = report.to_dict()["membership"]
            print(
                f"membership      {m['declared']} declared out (timeout {m['failure_timeout']} steps), "
                f"{m['rejoins']} back, out at the end: {m['out_at_end'] or 'none'}"
            )
        if args.split:
            what = (
                f"{report.lost} copies lost, said again when they healed"
                if args.split_mode == "lost"
                else f"{report.held} copies held until they healed"
            )
            print(f"partitions      {len(args.split)}; {what}")
    return 0 if result.completed and report.disagreements == 0 else 1
