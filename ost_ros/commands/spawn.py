"""Robots started by fork (``--spawn fork``, the default of ``ost up`` and ``ost_up.sh``).

A robot's process spends 0.5–0.7 CPU-s importing before it does anything (rclpy, numpy, the
protocols, the wire's codecs): 50 robots, 17 s of two cores. The supervisor imports the robot
node's code once and forks a process per robot: each is its own process (its PID, its DDS
participant, its log), as if started from its executable, and shares the imported code
copy-on-write.

Only what does not start a thread is imported before the fork: rclpy loads LTTng's tracing
library, which starts two threads, so each robot imports rclpy itself (0.1 s) — a fork copies
only the calling thread, and a lock another thread held would stay held in the child. The
supervisor forks only while it has one thread; otherwise (a caller with threads) the robot is
started from its executable, as ``--spawn exec`` does. A robot on a simulated host (``--hosts``)
is always started from its executable (``ip netns exec``).
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import importlib
import os
import signal
import sys
from pathlib import Path

# The ROS-free modules a robot node imports (import order: numpy first, its BLAS on one thread).
PRELOAD = (
    "numpy",
    "yaml",
    "cryptography.hazmat.primitives.asymmetric.x25519",
    "cryptography.hazmat.primitives.serialization",
    "ost_ros.protocols",
    "ost_ros.coordination",
    "ost_ros.lockstep.agent",
    "ost_ros.realtime.agent",
    "ost_ros.realtime.run",
    "ost_ros.realtime.world",
    "ost_msgs_py.wire",
    "ost_msgs_py.auth",
)
_PR_SET_NAME = 15
_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
# What each signal did in this process before a supervisor took it over (imported first): a
# robot gets that back — an ignored SIGHUP (nohup, ost_up.sh --background) stays ignored.
_INHERITED = {sig: signal.getsignal(sig) for sig in _SIGNALS}


def threads() -> int:
    """This process's threads (the kernel's count: C threads too, not only Python's)."""
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return 0  # no /proc: we cannot tell, so we do not fork


_loaded = False


def preload() -> bool:
    """Import what every robot imports (the first time); whether this process may fork robots
    now (one thread: asked at every fork, a caller may have started one since). numpy's OpenBLAS
    is held to one thread by ``ost_ros/commands/__init__.py``, which runs before this module."""
    global _loaded
    if threads() != 1:
        return False
    if not _loaded:
        for name in PRELOAD:
            importlib.import_module(name)
        # what is imported stays shared: the robots' collections do not walk (and so copy) it
        gc.freeze()
        _loaded = True
    return threads() == 1


def fork_robot(argv: list[str], env: dict[str, str], log: Path) -> int:
    """A robot node's process, forked: ``argv`` as its executable's (``agent_node --ros-args
    ...``), ``env`` on top of this process's, output appended to ``log``; its PID."""
    # (blocked across the fork: a signal between it and the child's own handlers would run the
    # supervisor's in the child)
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    pid = os.fork()
    if pid:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        return pid
    code = 70  # EX_SOFTWARE: the node never returned its own code
    try:
        _become_robot(env, log)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        sys.argv = list(argv)
        from agent_node.agent_node import main

        code = main(sys.argv)
    except BaseException as exc:  # a child never goes back into its parent's code
        code = exc.code if isinstance(exc, SystemExit) and isinstance(exc.code, int) else 70
        if not isinstance(exc, SystemExit | KeyboardInterrupt):
            import traceback

            traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):  # (its log may be gone: exit all the same)
                stream.flush()
        os._exit(code)


def _become_robot(env: dict[str, str], log: Path) -> None:
    """The child's start: the signals, files and name a process started from its executable
    would have."""
    for sig, handler in _INHERITED.items():  # (the supervisor's handlers raise in its own code)
        signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
    os.environ.update(env)
    out = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    null = os.open(os.devnull, os.O_RDWR)
    # Every descriptor the supervisor holds — the pipes its caller reads to the end, a lock —
    # becomes /dev/null: the robot keeps none of them, and the numbers stay taken, so a Python
    # object of the parent that still names one can never close a descriptor the robot opens.
    for fd in _open_fds():
        if fd > 2 and fd not in (out, null):
            with contextlib.suppress(OSError):
                os.dup2(null, fd)
    os.dup2(null, 0)
    os.dup2(out, 1)
    os.dup2(out, 2)
    os.close(out)
    os.close(null)
    sys.stdout = open(1, "w", buffering=1, closefd=False)  # noqa: SIM115 (the process's own)
    sys.stderr = open(2, "w", buffering=1, closefd=False)  # noqa: SIM115
    _set_name(b"agent_node")


def _open_fds() -> list[int]:
    try:
        return [int(fd) for fd in os.listdir("/proc/self/fd")]
    except OSError:
        return []


def _set_name(name: bytes) -> None:
    """The process's short name, as ``ps -o comm``, ``top`` and ``pgrep agent_node`` show it (its
    command line stays the supervisor's: ``pgrep -f`` and ``ps -ef`` show that)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).prctl(_PR_SET_NAME, ctypes.c_char_p(name[:15]), 0, 0, 0)
