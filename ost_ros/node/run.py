"""A node process's life, the same for the world, agent and watch nodes: rclpy up, the node
built, one executor spun until the node is done, bad parameters as one line and exit code 2,
and a teardown that never hangs."""

from __future__ import annotations

import faulthandler
import os
import sys
from collections.abc import Callable
from pathlib import Path

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from ost_ros.node.params import ParameterError

# rcl now and then spins forever inside destroy_node (busy, holding the GIL; seen twice in about
# 600 node processes here, once at exit and once destroying a node right after creating it), so
# a node process could hang after its work is done.
DESTROY_TIMEOUT_S = 5.0


# How a node waits for its samples. ``events``: rclpy's EventsExecutor (C++; about 10 µs a
# sample); ``single``: a SingleThreadedExecutor, which rebuilds its wait set on every wait
# (about 130 µs a sample) — the lockstep round trip is mostly that (benchmarks/bench_floor.py).
EXECUTORS = ("events", "single")


def executor(node: Node, name: str) -> Executor:
    """The executor ``name`` (one of EXECUTORS) with ``node`` added; the caller loops on
    ``spin_once(timeout_sec=...)`` until its node is done."""
    if name not in EXECUTORS:
        raise ParameterError(f"executor: {name!r} is not one of {', '.join(EXECUTORS)}")
    ex: Executor
    if name == "single":
        ex = SingleThreadedExecutor()
    else:
        from rclpy.experimental import EventsExecutor

        ex = EventsExecutor()
    ex.add_node(node)
    return ex


def guard_exit(seconds: float = DESTROY_TIMEOUT_S) -> None:
    """Arm a C-level watchdog (faulthandler's own thread needs no GIL): if the process is still
    alive ``seconds`` from now it prints where it hangs and exits with code 1."""
    faulthandler.dump_traceback_later(seconds, exit=True)


def executor_parameter(node: Node) -> str:
    """The node's ``executor`` parameter (world and agents: one of EXECUTORS)."""
    return str(node.get_parameter("executor").value)


def run_node[N: Node](
    prog: str,
    make: Callable[[], N],
    args: list[str] | None = None,
    *,
    done: Callable[[N], bool],
    code: Callable[[N], int] = lambda _node: 0,
    executor_name: Callable[[N], str] = executor_parameter,
    interrupted: int = 0,
    errors: tuple[type[Exception], ...] = (),
    close: Callable[[N], None] | None = None,
) -> int:
    """Run one node process; its exit code.

    ``make()`` builds the node (after ``rclpy.init``); one executor (``executor_name(node)``, see
    EXECUTORS) spins it until ``done(node)``, then the exit code is ``code(node)``. A bad
    parameter — the node's own :class:`ParameterError`, rclpy's ``ParameterException`` s (a
    ``--ros-args -p`` value of the wrong type or out of its declared range), or one of
    ``errors`` — is one line ``<prog>: error: ...`` and code 2; Ctrl-C or an external shutdown
    gives ``interrupted``. ``close(node)`` runs before the teardown, which is guarded
    (:func:`guard_exit`)."""
    bad_input: tuple[type[Exception], ...] = (ParameterError, ParameterException, *errors)
    rclpy.init(args=args)
    node: N | None = None
    status = 0
    try:
        node = make()
        # One executor for the node's life (rclpy.spin_once(node) adds and removes the node on
        # every call).
        ex = executor(node, executor_name(node))
        while rclpy.ok() and not done(node):
            try:
                ex.spin_once(timeout_sec=0.5)
            except Exception:
                if rclpy.ok():
                    raise
                # a signal shut the context down between the check and the wait (the wait set
                # then fails to build): an external shutdown, not a fault
                raise ExternalShutdownException() from None
        status = code(node)
    except bad_input as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        status = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        status = interrupted
    finally:
        if node is not None and close is not None:
            close(node)
        guard_exit()  # never hang in teardown
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return status


def process_age() -> float | None:
    """Seconds since this process started (Linux /proc; None elsewhere): the world starts with
    the agents, so at the run's start this is the bring-up (processes up, discovery done)."""
    try:
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        start = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        return uptime - start / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def write_file(path: str, text: str) -> None:
    """A file the run's supervisor polls (ready, progress, result), replaced at once (tmp +
    rename): a reader never sees half of it. OSError is the caller's to report."""
    tmp = f"{path}.tmp"
    Path(tmp).write_text(text)
    os.replace(tmp, path)
