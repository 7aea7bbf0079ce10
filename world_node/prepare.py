"""What ``ost_up.sh`` does before it starts any node, in one Python process.

Starting Python with this package's imports costs ~0.4 s here, and the script used to start it
four times before the first node (``ost protocols check``, ``ost generate``, reading the team's
ids, ``ost keys make``): ~1.6 s of a 10-robot run's ~10 s. The steps and their errors are the
same; each error is one line on stderr and exit code 2.

    python -m world_node.prepare --protocol NAME [--coordination C] [--silence] [--own-sweeps]
        [--scenario FILE [--team N] | --generate FILE --agents N --objects M --seed S
        [--width W] [--height H] [--nmax X]] [--keys DIR]

With a scenario it prints the ids of the run's agents on one line (``--team N``: a team of N
replaces the file's); ``--keys DIR``: fresh keys for them (``ost keys make``). With
``--protocol`` alone it only checks the protocol.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys

from ost_ros.errors import UsageError

ME = "ost_up"


def parse(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m world_node.prepare", add_help=False)
    p.add_argument("--protocol", required=True)
    p.add_argument("--coordination", default="distributed")
    p.add_argument("--silence", action="store_true")
    p.add_argument("--own-sweeps", action="store_true")
    p.add_argument("--scenario")
    p.add_argument("--team", type=int, default=0)
    p.add_argument("--generate", metavar="FILE")
    for name in ("agents", "objects", "seed", "width", "height", "nmax"):
        p.add_argument(f"--{name}")
    p.add_argument("--keys", metavar="DIR")
    return p.parse_args(argv)


def check_protocol(args: argparse.Namespace) -> None:
    """``ost protocols check``, its reason prefixed with the flag it is about."""
    from ost_ros.commands.protocols import cmd_check

    check = argparse.Namespace(
        name=args.protocol,
        coordination=args.coordination,
        failures=False,
        silence=args.silence,
        own_sweeps=args.own_sweeps,
    )
    try:
        cmd_check(check)
    except UsageError as exc:
        raise UsageError(f"--protocol {args.protocol}: {exc}") from None


def generate(args: argparse.Namespace) -> int:
    """``ost generate ... -o FILE``, through the CLI (its defaults, checks and error line)."""
    from ost_ros.cli import main as ost

    argv = ["generate", "-o", args.generate]
    for name in ("agents", "objects", "seed", "width", "height", "nmax"):
        if getattr(args, name) is not None:
            argv += [f"--{name}", getattr(args, name)]
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            return ost(argv)
    except SystemExit as exc:  # a bad flag: argparse said so in one line
        return exc.code if isinstance(exc.code, int) else 2


def main(argv: list[str] | None = None) -> int:
    args = parse(sys.argv[1:] if argv is None else argv)
    try:
        check_protocol(args)
        if args.generate:
            code = generate(args)
            if code:
                return code
            args.scenario = args.generate
        if not args.scenario:
            return 0
        from ost_ros.commands.args import load_scenario_arg

        ids = [a.id for a in load_scenario_arg(args.scenario, args.team or None).agents]
        if args.keys:
            from ost_msgs_py.auth import make_keys

            try:
                make_keys(args.keys, ids)
            except OSError as exc:
                raise UsageError(f"{args.keys}: cannot write keys ({exc.strerror})") from None
    except UsageError as exc:
        print(f"{ME}: error: {exc}", file=sys.stderr)
        return 2
    print(" ".join(map(str, ids)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
