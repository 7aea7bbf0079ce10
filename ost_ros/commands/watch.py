"""``ost record info`` and ``ost replay``: recordings of DDS runs (``ost_up.sh --record``).

A recording is a rosbag2-style MCAP file (:mod:`ost_msgs_py.bag`). ``ost replay`` rebuilds the
run from it with the world's own bookkeeping fed the recorded messages (:mod:`ost_msgs_py.replay`,
:mod:`ost_ros.lockstep.follow`) — the per-robot table, the timeline (``--plot``) and the
animation (``--animate``) — and checks the rebuilt result against the one the world published. No agent
runs and nothing is simulated.
"""

from __future__ import annotations

import argparse
import json
import sys

from ost_ros.commands.animation import (
    add_animate_arguments,
    add_progress_argument,
    check_animation,
    frame_recorder,
    write_animation,
)
from ost_ros.commands.args import OneLineParser, leaf
from ost_ros.errors import UsageError


def register(sub) -> None:
    rec = sub.add_parser(
        "record",
        help="recordings of DDS runs (ost_up.sh --record FILE.mcap)",
        description="Look into a recording: rosbag2-style MCAP, every topic of a run.",
    )
    verbs = rec.add_subparsers(dest="record_verb", metavar="VERB", parser_class=OneLineParser)
    p = leaf(verbs, "info", cmd_info, help="topics, types, counts, duration (as ros2 bag info)")
    p.add_argument("bag", help="the recording (.mcap)")
    p.add_argument("--json", action="store_true", help="print JSON")

    p = leaf(
        sub,
        "replay",
        cmd_replay,
        help="rebuild a recorded run: result, timeline, animation",
        description="Rebuild a run from its recording (ost_up.sh --record) with the world's own "
        "bookkeeping fed the recorded messages — no simulation — print its result and check it "
        "against the one the world published.",
    )
    p.add_argument("bag", help="the recording (.mcap)")
    p.add_argument("--json", action="store_true", help="print the rebuilt result as JSON")
    p.add_argument("--plot", metavar="PNG", help="also draw the map and every robot's timeline")
    add_animate_arguments(p)
    add_progress_argument(p)


def cmd_info(args: argparse.Namespace) -> int:
    from ost_msgs_py.bag import BagError, info

    try:
        summary = info(args.bag)
    except BagError as exc:
        raise UsageError(str(exc)) from None
    if args.json:
        out = {
            "path": str(summary.path),
            "size": summary.size,
            "profile": summary.profile,
            "duration_s": summary.duration_s,
            "start_ns": summary.start_ns,
            "end_ns": summary.end_ns,
            "messages": summary.messages,
            "topics": [{"topic": t.topic, "type": t.type_name, "count": t.count} for t in summary.topics],
        }
        print(json.dumps(out, indent=1))
    else:
        print(summary.text())
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from ost_msgs_py.bag import BagError
    from ost_msgs_py.replay import replay
    from ost_ros.lockstep.follow import FollowError
    from ost_ros.plot import Timeline

    if args.animate:
        check_animation(args)
    hooks: list = []
    timeline = Timeline() if args.plot else None
    if timeline is not None:
        hooks.append(timeline)
    # The frames need the scenario, which the recording's first message (run_info) brings.
    state: dict = {}

    def on_step(world, actions) -> None:
        if args.animate and "frames" not in state:
            state["frames"] = frame_recorder(args, world.scenario)
        for hook in (*hooks, state.get("frames")):
            if hook is not None:
                hook(world, actions)

    try:
        done = replay(args.bag, on_step=on_step)
    except (BagError, FollowError) as exc:
        raise UsageError(f"{args.bag}: {exc}" if not str(exc).startswith(args.bag) else str(exc)) from None
    result = done.result
    if timeline is not None:
        from ost_ros.plot import plot_run

        try:
            plot_run(done.scenario, result, timeline, args.plot)
        except OSError as exc:
            raise UsageError(f"{args.plot}: cannot write ({exc.strerror})") from None
    if "frames" in state:
        write_animation(args, done.scenario, result, state["frames"])
    print(json.dumps(result.to_dict(), indent=1) if args.json else result.summary())
    rt = done.follower.rt
    assert rt is not None
    line = (
        f"replayed {done.messages} messages of run {rt.run} ({done.namespace or '/'}): "
        f"{result.steps} steps, {rt.round_trips} round trips, {rt.skipped} steps from the agents' plans"
    )
    print(line, file=sys.stderr)
    if done.matches is None:
        print("replay: the recording has no result of its own to check against", file=sys.stderr)
    elif not done.matches:
        print(
            "replay: error: the rebuilt result DIFFERS from the result the world published", file=sys.stderr
        )
        return 1
    else:
        print("replay: identical to the result the world published", file=sys.stderr)
    return 0 if result.completed else 1
