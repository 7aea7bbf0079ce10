"""The ``ost`` command: one CLI, subcommands in the verb pattern of ros2cli.

Every subcommand module exposes ``register(subparsers)``, which adds its parser and sets
``func`` (a callable taking the parsed namespace and returning an exit code). Bad input anywhere
ends in one line on stderr, ``ost <verb>: error: <what>``, and exit code 2 — never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Callable, Sequence

# Before numpy is imported: its OpenBLAS threads cost ~0.15 CPU-s of every start, and no
# verb calls BLAS (docs/ros.md, "Lost datagrams, late announcements, idle threads").
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from ost_ros.commands.args import OneLineParser
from ost_ros.errors import UsageError

__all__ = ["OneLineParser", "UsageError", "build_parser", "main"]


# Modules that add subcommands, in the order they appear in ``ost --help``.
VERB_MODULES: tuple[str, ...] = (
    "ost_ros.commands.core",
    "ost_ros.commands.protocols",
    "ost_ros.commands.negotiate",
    "ost_ros.commands.up",
    "ost_ros.commands.ros",
    "ost_ros.commands.study",
    "ost_ros.commands.faults",
    "ost_ros.commands.watch",
    "ost_ros.commands.keys",
)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="ost",
        description="Object-Sorting Task: scenarios, simulation and the cooperation protocols.",
    )
    sub = parser.add_subparsers(dest="verb", metavar="VERB", parser_class=OneLineParser)
    for name in VERB_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            # Tolerate only the verb module (or its package) being absent — a partial checkout —
            # not a missing dependency inside it: that is a real error and must show.
            if not exc.name or not name.startswith(exc.name):
                raise
            continue
        module.register(sub)
    return parser


def run(func: Callable[[argparse.Namespace], int], args: argparse.Namespace, prog: str) -> int:
    """Run a verb, turning user errors into one line and exit code 2."""
    try:
        return int(func(args) or 0)
    except UsageError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `ost sim ... | head` must not print a traceback
        return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0 if args.verb is None else 2
    return run(args.func, args, getattr(args, "prog", "ost"))


if __name__ == "__main__":
    # Run through the package's own module so exception classes are the same objects.
    from ost_ros.cli import main as _main

    sys.exit(_main())
