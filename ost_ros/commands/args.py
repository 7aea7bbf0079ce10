"""argparse helpers shared by the verbs: typed values with one-line errors, and leaf parsers."""

from __future__ import annotations

import argparse
from typing import NoReturn


class OneLineParser(argparse.ArgumentParser):
    """argparse with one-line errors (argparse prints usage + error; we print only the error)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def at_least(minimum: int):
    """argparse type: an integer >= minimum."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid integer {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value

    return parse


positive, natural = at_least(1), at_least(0)


def period_list(text: str) -> list[int]:
    """argparse type: comma-separated integers >= 1 (agent periods)."""
    try:
        values = [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"every period must be at least 1, got {text!r}")
    return values


def failure(text: str) -> tuple[int, int]:
    """argparse type: AGENT:STEP (a robot failing in that step)."""
    agent, sep, step = text.partition(":")
    try:
        a, t = int(agent), int(step)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected AGENT:STEP, got {text!r}") from None
    if not sep or a < 0 or t < 0:
        raise argparse.ArgumentTypeError(f"expected AGENT:STEP with non-negative integers, got {text!r}")
    return a, t


def fraction(text: str) -> float:
    """argparse type: a number in (0, 1]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid number {text!r}") from None
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1], got {value}")
    return value


def leaf(sub, name: str, func, **kwargs) -> argparse.ArgumentParser:
    """A verb's parser; ``func(args) -> exit code`` runs it, ``prog`` names it in errors."""
    parser = sub.add_parser(name, **kwargs)
    parser.set_defaults(func=func, prog=parser.prog)
    return parser


def load_scenario_arg(path: str, agents: int | None):
    """The scenario file a verb was given, with ``--agents`` replacing its team; bad files are
    one-line usage errors."""
    from ost_ros.errors import UsageError
    from ost_ros.scenario import ScenarioError, load_scenario, with_team

    try:
        scenario = load_scenario(path)
        return scenario if agents is None else with_team(scenario, agents)
    except ScenarioError as exc:
        raise UsageError(str(exc)) from None


# ----------------------------------------------------------------------------- study verbs


def add_workers(p: argparse.ArgumentParser, jobs: str = "every core") -> None:
    """``--jobs``, ``--cluster`` and ``--progress``, as every study verb takes them."""
    p.add_argument("--jobs", type=at_least(1), help=f"worker processes on this machine (default: {jobs})")
    p.add_argument(
        "--cluster",
        type=cluster_spec,
        metavar="ADDRESS|FILE.json|local:K",
        help="run on a Dask distributed cluster instead: its scheduler's address (tcp://HOST:PORT), "
        "its scheduler file, or local:K (K worker processes started here); docs/reproduce.md",
    )
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="progress bar on stderr (default: when stderr is a terminal)",
    )


def cluster_spec(text: str):
    """argparse type of ``--cluster`` (checked before Dask is imported)."""
    from ost_ros.study.executors import ClusterSpec

    try:
        return ClusterSpec.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def executor(args: argparse.Namespace, jobs: int | None = None):
    """The executor of a study verb's flags (``jobs``: the verb's default for ``--jobs``)."""
    from ost_ros.errors import UsageError
    from ost_ros.study.executors import open_executor

    if args.cluster is not None and args.jobs is not None:
        raise UsageError("--jobs and --cluster: one or the other (a cluster has its own workers)")
    return open_executor(args.jobs or jobs, args.cluster)


def resumed(timing) -> str:
    """What an interrupted start had done already, for the closing line."""
    return f" ({timing.resumed} more taken from the interrupted start)" if timing.resumed else ""
