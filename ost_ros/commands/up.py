"""``ost up``: a run over DDS — one world node and one agent node per robot, each its own
process — from one run configuration (:mod:`ost_ros.runconfig`); ``bringup_scripts/ost_up.sh``
takes the same options.

    ost up --agents 10 --objects 20 --seed 1 [options]   # prepare, start, supervise, print the result
    ost up --scenario s.yaml --background --run-dir DIR  # return once started; ost_down.sh DIR ends it

Waits for discovery by the world's ``ready`` file (it counts matched endpoints), for the result by
``result.json``; prints it as ``ost sim`` does (``--json``: byte-for-byte ``ost sim --json``) and
tears every process down, also on Ctrl-C or when one dies (naming it). Internal modes for
``ost_up.sh``: ``--prepare`` (make the run directory, print its path), ``--supervise DIR`` (become
the supervisor of the processes the script started), ``--wait-started DIR SUPERVISOR_PID``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from ost_ros.commands.args import OneLineParser, leaf
from ost_ros.errors import UsageError
from ost_ros.runconfig import BY_NAME, ConfigError, RunConfig, Setting, options

GROUPS = ("scenario", "protocol", "realtime", "ROS", "watch", "run", "faults")


def add_options(p: argparse.ArgumentParser) -> None:
    """Every run option (the configuration's), in --help sections; unset ones stay absent."""
    sections = {g: p.add_argument_group(g) for g in GROUPS}
    for s in options():
        g = sections[s.group]
        kw: dict[str, Any] = {"dest": s.name, "default": argparse.SUPPRESS, "help": _help(s)}
        if s.type is bool:
            g.add_argument(s.cli, action="store_const", const=not s.default, **kw)
        elif s.type is list:
            g.add_argument(s.cli, action="append", metavar=s.metavar or None, **kw)
        elif s.name == "foxglove":  # a bare --foxglove: the usual port
            g.add_argument(s.cli, nargs="?", const="8765", metavar=s.metavar, **kw)
        else:
            g.add_argument(s.cli, metavar=s.metavar or "|".join(s.choices) or s.name.upper(), **kw)


def _help(s: Setting) -> str:
    extra = []
    if s.type is not bool and s.default not in ("", [], None) and s.name != "foxglove":
        extra.append(f"default {s.default}")
    text = s.help + (f" ({'; '.join(extra)})" if extra else "")
    return text.replace("%", "%%")  # argparse formats help with %


def config_of(args: argparse.Namespace) -> RunConfig:
    """The run configuration of parsed options; an error names the flag."""
    given = {s.name: getattr(args, s.name) for s in options() if hasattr(args, s.name)}
    try:
        return RunConfig.of(given)
    except ConfigError as exc:
        raise UsageError(flagged(exc)) from None


def flagged(exc: ConfigError) -> str:
    s = BY_NAME.get(exc.setting)
    flag = s.cli if s is not None and s.option else exc.setting
    return f"{flag}: {exc}" if flag else str(exc)


def register(sub) -> None:
    p = leaf(
        sub,
        "up",
        cmd_up,
        help="start a run over DDS: a world node and one agent node per robot",
        description="Start a run over DDS: a world node and one agent node per robot, each its own "
        "process, from one run configuration. Waits for discovery, prints the result as ost sim "
        "does and tears every process down (also on Ctrl-C, or when one dies).",
        epilog="bringup_scripts/ost_up.sh takes the same options; docs/ros.md explains the run.",
    )
    add_options(p)
    internal = p.add_argument_group("internal (bringup_scripts/ost_up.sh)")
    internal.add_argument("--prepare", action="store_true", help="prepare the run directory, print its path")
    internal.add_argument("--supervise", metavar="DIR", help="supervise the processes started for DIR")
    internal.add_argument("--wait-started", nargs=2, metavar=("DIR", "PID"), help="until DIR's run started")
    internal.add_argument("--down", metavar="DIR", help="stop the background run in DIR (ost_down.sh)")


def cmd_up(args: argparse.Namespace) -> int:
    from ost_ros.commands import bringup, supervise

    if args.supervise:
        run = bringup.Run.load(args.supervise)
        # (a robot that joins later has no PID yet: the supervisor starts it, supervise.Joins)
        pids = {p.name: supervise._pid(run.file(f"{p.name}.pid")) for p in run.processes if run.listed(p)}
        # (it starts the robots it forks, --spawn fork)
        return supervise.Supervisor(run, pids, start=supervise.at_start(run, listed=False)).supervise()
    if args.down:
        d = Path(args.down)
        if not d.is_dir():
            raise UsageError(f"{d}: no such run directory")
        left = supervise.stop(d)
        extra = f" ({left} processes stopped directly)" if left else ""
        print(f"ost_down: stopped the run in {d}{extra}", file=sys.stderr)
        return 0
    if args.wait_started:
        return supervise.wait_started(Path(args.wait_started[0]), int(args.wait_started[1]))
    cfg = config_of(args)
    try:
        run = bringup.prepare(cfg, say)
    except ConfigError as exc:
        raise UsageError(flagged(exc)) from None
    run.write()
    if args.prepare:
        print(run.dir)
        return 0
    if cfg["background"]:
        return _background(run)
    return supervise.Supervisor(run, {}, start=supervise.at_start(run)).supervise()


def run_up(given: dict[str, Any]) -> tuple[int, str, str]:
    """A whole run from Python (``ost faults``, scripts): settings by name -> exit code, what it
    printed (the result) and what it said on stderr."""
    import io

    from ost_ros.commands import bringup, supervise

    out, err = io.StringIO(), io.StringIO()
    try:
        run = bringup.prepare(RunConfig.of(given), lambda text: print(f"ost up: {text}", file=err))
    except ConfigError as exc:
        return 2, "", f"ost up: error: {flagged(exc)}\n"
    except UsageError as exc:
        return 2, "", f"ost up: error: {exc}\n"
    run.write()
    code = supervise.Supervisor(run, {}, err=err, out=out, start=supervise.at_start(run)).supervise()
    return code, out.getvalue(), err.getvalue()


def say(text: str) -> None:
    print(f"ost up: {text}", file=sys.stderr, flush=True)


def _background(run) -> int:
    """Fork the supervisor (it starts the processes and stays their parent), detached from
    this terminal; return once the run has started."""
    from ost_ros.commands import supervise

    pid = os.fork()
    if pid == 0:  # the supervisor
        os.setsid()
        code = 1
        try:
            with open(run.file("ost_up.out"), "w") as out, open(run.file("ost_up.log"), "w") as err:
                os.dup2(err.fileno(), 2)
                sup = supervise.Supervisor(run, {}, err=err, out=out, start=supervise.at_start(run))
                code = sup.supervise()
        finally:
            os._exit(code)  # never back into the caller's code
    run.file("ost_up.pid").write_text(f"{pid}\n")
    code = supervise.wait_started(run.dir, pid)
    print(run.dir)
    return code


__all__ = ["OneLineParser", "add_options", "cmd_up", "config_of", "register"]
