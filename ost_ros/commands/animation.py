"""The animation's options and steps, shared by ``ost sim`` (lockstep and ``--latency``) and
``ost replay``: ``--animate FILE [--fps F] [--every K]``, ``--progress``, the target checked
before a run, the frames drawn after it."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ost_ros.commands.args import positive
from ost_ros.errors import UsageError
from ost_ros.model import Scenario


def add_animate_arguments(p: argparse.ArgumentParser) -> None:
    """``--animate FILE [--fps F] [--every K]`` (``ost sim``, ``ost replay``)."""
    p.add_argument(
        "--animate",
        metavar="GIF|MP4",
        help="also write an animation of the run (robots by state, objects, groups, deliveries; "
        "without a barrier, who is in the team when)",
    )
    p.add_argument("--fps", type=positive, default=20, help="animation frames per second (20)")
    p.add_argument(
        "--every",
        type=positive,
        help="one frame every K steps, plus every lift and delivery (default: about 400 frames)",
    )


def add_progress_argument(p: argparse.ArgumentParser) -> None:
    """``--progress/--no-progress``: a bar on stderr (default: when stderr is a terminal)."""
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="progress bar on stderr (default: when stderr is a terminal)",
    )


def check_animation(args: argparse.Namespace) -> None:
    """A bad --animate target ends before the run, in one line."""
    from ost_ros.watch.animate import AnimationError, check_target

    try:
        check_target(args.animate)
    except AnimationError as exc:
        raise UsageError(f"--animate: {exc}") from None


def frame_recorder(args: argparse.Namespace, scenario: Scenario):
    """The step hook that keeps the animation's frames (None without --animate)."""
    if not getattr(args, "animate", None):
        return None
    from ost_ros.watch.frames import FrameRecorder

    return FrameRecorder(scenario, every=args.every)


def write_animation(
    args: argparse.Namespace, scenario: Scenario, result: Any, recorder: Any, heading: str = ""
) -> None:
    """Draw the recorded frames into ``args.animate`` (a progress bar on a terminal; ``heading``
    ends each frame's title)."""
    from ost_ros.watch.animate import AnimationError, animate

    frames = recorder.finish()
    bar = None
    if sys.stderr.isatty() if args.progress is None else args.progress:
        from tqdm import tqdm

        bar = tqdm(total=len(frames), desc="animation", unit="frame", file=sys.stderr, leave=False)
    try:
        written = animate(
            scenario,
            result,
            frames,
            args.animate,
            fps=args.fps,
            progress=(lambda i, n: bar.update(1)) if bar is not None else None,
            heading=heading,
        )
    except AnimationError as exc:
        raise UsageError(f"--animate: {exc}") from None
    finally:
        if bar is not None:
            bar.close()
    print(
        f"animation: {written.path} ({written.frames} frames, {written.bytes / 1e6:.1f} MB)",
        file=sys.stderr,
    )
