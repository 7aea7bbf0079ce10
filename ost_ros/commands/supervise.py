"""Starting and supervising the processes of a prepared run (:mod:`ost_ros.commands.bringup`).

The supervisor is the parent of every process of the run — ``ost up`` starts them itself;
``bringup_scripts/ost_up.sh`` starts them from its shell and then becomes the supervisor
(``exec ost up --supervise DIR``: the processes stay children of the same PID). It waits for the
files the nodes write (``ready``, ``progress``, ``result.json``), never for log lines; shows a
progress line on a terminal; names a process that dies; restarts a dead world from its
checkpoint (``--respawn-world``); ends everything on the result, a signal, a time-out or a
death (TERM, 3 s, then KILL), removes the Fast DDS files the run left in /dev/shm and what
preparing took (domain lock, simulated hosts); and prints the result as ``ost sim`` does.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from ost_ros.commands import spawn
from ost_ros.commands.bringup import PROGRESS, READY, RESULT, Process, Run, release
from ost_ros.errors import UsageError

SHM = Path("/dev/shm")
SHM_PREFIXES = ("fastrtps_", "sem.fastrtps_", "fast_datasharing")
POLL_S = 0.1
STARTED = "started"  # the supervisor has seen the run start (and said so)
# The processes this one started: kept, so that subprocess never reaps one behind our back (a
# forgotten Popen is waited for by the next Popen); the supervisor reaps them by PID.
_STARTED: list[subprocess.Popen] = []


class Interrupted(Exception):
    """SIGINT/SIGTERM reached the supervisor."""


def start(run: Run, p: Process, extra: list[str] | None = None) -> int:
    """Start one process of the run (on its simulated host, if any), output to its log; its PID.
    A robot ``run.forked`` is forked from this process when it may (:mod:`.spawn`)."""
    argv = p.argv(run) + (extra or [])
    if run.forked(p) and spawn.preload():
        pid = spawn.fork_robot(argv, run.env, run.file(f"{p.name}.log"))
        run.file(f"{p.name}.pid").write_text(f"{pid}\n")
        return pid
    host = run.host_of(p)
    if host:
        argv = ["ip", "netns", "exec", host, *argv]
    with open(run.file(f"{p.name}.log"), "ab") as log:
        child = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                 env={**os.environ, **run.env})  # fmt: skip
    _STARTED.append(child)
    run.file(f"{p.name}.pid").write_text(f"{child.pid}\n")
    return child.pid


def at_start(run: Run, listed: bool = True) -> list[Process]:
    """Every process of the run that starts with it, in its order (one that joins later:
    :class:`Joins`). ``listed=False``: only those a shell does not start from ``processes``
    (``ost_up.sh``: the robots forked here)."""
    return [p for p in run.processes if p.at < 0 and (listed or not run.listed(p))]


def _reap(pid: int) -> int | None:
    """The exit code of a child that has ended (a signal: 128 + its number), else None."""
    try:
        done, status = os.waitpid(pid, os.WNOHANG)
    except ChildProcessError:
        return -1  # not ours any more (already reaped)
    if done == 0:
        return None
    return os.waitstatus_to_exitcode(status) if os.WIFEXITED(status) else 128 + os.WTERMSIG(status)


def _sim_time(run: Run) -> float | None:
    """The run's sim time (its progress file), or None before the start."""
    try:
        return float(_text(run.file(PROGRESS)).split()[0])
    except (IndexError, ValueError):
        return None


def _amend_result(run: Run, key: str, value: object) -> None:
    """``membership[key] = value`` in the run's result (the world's JSON)."""
    path = run.file(RESULT)
    data = json.loads(path.read_text())
    data.setdefault("membership", {})[key] = value
    path.write_text(json.dumps(data, indent=1) + "\n")


@dataclass
class Cut:
    """One ``--split`` over simulated hosts: what it cuts, when, and what happened (epoch s)."""

    groups: tuple[frozenset[int], ...]
    at: int  # the sim time it begins at
    seconds: int  # how long it lasts (wall)
    hosts: list[list[int]]  # each group's hosts
    cut: tuple[float, float] | None = None  # (wall, sim time) it began
    healed: tuple[float, float] | None = None  # (wall, sim time) it ended


class Partitions:
    """``--split GROUPS:T:S`` over the simulated hosts: each cut (a bridge rule between the groups'
    hosts) once the run's sim time reaches T, healed S wall seconds later; what happened goes into
    the result (``membership.splits``), with how long after the heal the last robot took the last
    batch stamped before it (its digest: ``agree_after_s``)."""

    def __init__(self, run: Run, say):
        self.run, self.say = run, say
        host = {int(p.name.split("_")[1]): p.host for p in run.agents}
        self.cuts = [
            Cut(groups, t, s, [sorted({host[a] for a in g}) for g in groups])
            for groups, t, s in run.config.splits()
        ]

    def tick(self) -> None:
        if not any(c.healed is None for c in self.cuts):
            return
        sim = _sim_time(self.run)
        if sim is None:
            return  # not started
        from ost_ros.commands import hosts

        for k, c in enumerate(self.cuts):
            if c.cut is None and sim >= c.at:
                hosts.cut(self.run.netns, c.hosts, k)
                c.cut = (time.time(), sim)
                names = " | ".join(",".join(map(str, sorted(g))) for g in c.groups)
                self.say(f"split {names}: no traffic between them from sim time {sim:g} for {c.seconds} s")
            elif c.cut is not None and c.healed is None and time.time() - c.cut[0] >= c.seconds:
                hosts.heal(self.run.netns, k)
                c.healed = (time.time(), sim)
                self.say(f"split healed at sim time {sim:g}")

    def record(self) -> None:
        """The splits into the run's result (the world's JSON, with the digests' arrival times)."""
        if not self.cuts:
            return
        data = json.loads(self.run.file(RESULT).read_text())
        arrived = {int(s): t for s, t in data.get("digests_at", {}).items()}
        out = []
        for c in self.cuts:
            item: dict = {"groups": [sorted(g) for g in c.groups], "seconds": c.seconds,
                          "from": None, "healed": None, "agree_after_s": None}  # fmt: skip
            if c.cut is not None:
                item["from"] = round(c.cut[1], 3)
            if c.healed is not None:
                wall, sim = c.healed
                item["healed"] = round(sim, 3)
                late = [t for s, t in arrived.items() if s <= sim]
                item["agree_after_s"] = round(max(max(late, default=wall) - wall, 0.0), 3)
            out.append(item)
        _amend_result(self.run, "splits", out)


class Joins:
    """``--join AGENT:T``: the robot's process starts once the run's sim time reaches T (the
    world and the monitor have counted it out from the start; it asks to come in as a robot
    declared out does, and its peers say everything again to its new readers)."""

    def __init__(self, run: Run, pids: dict[str, int], say):
        self.run, self.pids, self.say = run, pids, say
        self.late = sorted((p for p in run.processes if p.at >= 0), key=lambda p: p.at)
        self.started: dict[int, float] = {}  # agent -> the sim time its process started at

    def tick(self) -> None:
        sim = _sim_time(self.run) if self.late else None
        if sim is None:
            return  # nobody left to start, or not started
        while self.late and sim >= self.late[0].at:
            p = self.late.pop(0)
            self.pids[p.name] = start(self.run, p)
            self.started[int(p.name.split("_")[1])] = sim
            self.say(f"{p.name} joins: its process started at sim time {sim:g}")

    def record(self) -> None:
        """The joins into the run's result (``membership.joins``: agent, asked, started)."""
        joins = self.run.config.joins()
        if not joins:
            return
        _amend_result(
            self.run,
            "joins",
            [{"agent": a, "at": t, "started": self.started.get(a)} for a, t in sorted(joins.items())],
        )


class Supervisor:
    """One run's processes until its result (see the module docstring)."""

    def __init__(
        self,
        run: Run,
        pids: dict[str, int],
        err: TextIO = sys.stderr,
        out: TextIO = sys.stdout,
        start: list[Process] | None = None,
    ):
        """``pids``: the processes already started (by a shell); ``start``: those it starts
        itself, under its signal handlers (Ctrl-C while they start tears down what started)."""
        # (a PID <= 0 is no process: waitpid and kill would take it for the whole group)
        self.run, self.err, self.out = run, err, out
        self.pids = {name: pid for name, pid in pids.items() if pid > 0}
        self.pending = list(start or [])
        self.cfg = run.config
        self.stay = bool(self.cfg["background"])
        self.respawns = self.cfg["respawn_world"]
        self.partitions = Partitions(run, self.say)
        self.joins = Joins(run, self.pids, self.say)
        self.started = False
        self.shown = ""
        self.t0 = time.monotonic()
        self.shm_before = set(os.listdir(SHM)) if SHM.is_dir() else set()
        if run.domain_lock:  # the lock names the process that holds the run
            Path(run.domain_lock, "pid").write_text(f"{os.getpid()}\n")
        where = f"ROS_DOMAIN_ID={run.env.get('ROS_DOMAIN_ID', '?')}, namespace /{self.cfg['namespace'].strip('/')}"
        if run.netns:
            c = self.cfg
            hosts = f" on {c['hosts']} simulated hosts (loss {c['loss']} %, discovery {c['discovery']})"
        else:
            hosts = ""
        if self.cfg["record"]:
            self.say(f"recording every topic of /{self.cfg['namespace'].strip('/')} to {self.cfg['record']}")
        if self.cfg["foxglove"]:
            self.say(f"live view: open ws://127.0.0.1:{self.cfg['foxglove']} in the Foxglove app "
                     "(Open connection, Foxglove WebSocket)")  # fmt: skip
        monitor = " + membership node" if any(p.name == "membership" for p in run.processes) else ""
        later = sum(p.at >= 0 for p in run.agents)
        joining = f" ({later} to join later)" if later else ""
        self.say(
            f"started world{monitor} + {len(run.agents) - later} agents{joining}{hosts} ({where}, run dir {run.dir})"
        )

    def say(self, text: str) -> None:
        self.end_progress()
        print(f"ost up: {text}", file=self.err, flush=True)

    # ------------------------------------------------------------------ the run

    def supervise(self) -> int:
        """Until the result (or a failure); the exit code ost up / ost_up.sh returns."""
        previous = {s: signal.signal(s, self._interrupt) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            while self.pending:
                p = self.pending.pop(0)
                self.pids[p.name] = start(self.run, p)
            code = self._watch()
            if code is not None:
                self.teardown()
                return code
            return self._finish()
        except Interrupted:
            self.say(f"interrupted: stopping {len(self.alive())} processes")
            self.teardown()
            return 130
        finally:
            for s, h in previous.items():
                signal.signal(s, h)

    def _interrupt(self, signum, frame) -> None:
        raise Interrupted

    def _watch(self) -> int | None:
        """Poll until the result is in (None) or the run failed (its exit code)."""
        run, result = self.run, self.run.file(RESULT)
        n = sum(p.at < 0 for p in run.agents)  # (those that join later are not awaited)
        timeout = self.cfg["timeout"]
        while True:
            if not self.started and run.file(READY).exists():
                self.started = True
                self.say(f"discovery complete: {n} agents matched after {self.ms()} ms")
                run.file(STARTED).touch()  # for --background's caller (wait_started)
            self.progress()
            if result.exists() and (self.stay or "world" not in self.alive()):
                self.partitions.record()
                self.joins.record()
                return None
            self.partitions.tick()
            self.joins.tick()
            for name, pid in list(self.pids.items()):
                code = _reap(pid)
                if code is None:
                    continue
                failed = self._ended(name, pid, code, result.exists())
                if failed is not None:
                    return failed
            if timeout and time.monotonic() - self.t0 > timeout:
                self.say(f"timeout: no result after {timeout} s; stopping")
                return 1
            time.sleep(POLL_S)

    def _ended(self, name: str, pid: int, code: int, over: bool) -> int | None:
        """A process ended with ``code``: carry on (None) or the run has failed (exit code)."""
        del self.pids[name]
        if name == "world" and not over and self.respawns > 0:
            self.respawns -= 1
            self.say(f"world (pid {pid}) died with exit code {code}; restarting it from its checkpoint "
                     f"({self.respawns} restarts left)")  # fmt: skip
            world = next(p for p in self.run.processes if p.name == "world")
            self.pids["world"] = start(self.run, world, ["-p", "resume:=true"])
            return None
        if over or (name == "membership" and code == 0):
            return None  # the run is over: everyone leaves (the membership node at run_end)
        if name.startswith("agent_") and self.started:
            self.say(f"{name} (pid {pid}) died mid-run (exit code {code}); the world declares it failed after "
                     f"2 x {self.cfg['failure_timeout']:g} s without its liveliness")  # fmt: skip
            return None
        self.say(
            f"{name} (pid {pid}) died with exit code {code} before the result; see {self.run.file(name + '.log')}"
        )
        for line in _tail(self.run.file(f"{name}.log"), 3):
            print(line, file=self.err)
        return 1

    def _finish(self) -> int:
        self.end_progress()
        watch = self.pids.get("watch")
        if watch is not None and not self.stay:
            # The recorder closes its file a moment after the result (samples still on their way).
            for _ in range(100):
                if _reap(watch) is not None:
                    self.pids.pop("watch")
                    break
                time.sleep(POLL_S)
            if self.cfg["record"]:
                said = re.search(r"recorded \d+ messages on \d+ topics", _text(self.run.file("watch.log")))
                self.say(f"recorded {self.cfg['record']}" + (f": {said.group(0)}" if said else ""))
        if not self.stay:
            self.teardown()
        if self.cfg["result_file"]:  # a copy where the user asked for it
            try:
                shutil.copyfile(self.run.file(RESULT), self.cfg["result_file"])
            except OSError as exc:
                self.say(f"--result-file: cannot write {self.cfg['result_file']} ({exc.strerror})")
        code = report(self.run.file(RESULT), self.cfg["json"], self.out, self.err)
        if not self.cfg["json"]:
            self.say(f"logs and result in {self.run.dir}")
        if self.stay:  # --background: the result stays on <ns>/result until ost_down.sh
            ns = self.cfg["namespace"].strip("/")
            self.say(f"run over; the world stays up with the result on /{ns}/result until: "
                     f"bringup_scripts/ost_down.sh {self.run.dir}")  # fmt: skip
            try:
                while "world" in self.alive():
                    time.sleep(0.5)
            except Interrupted:
                pass
            self.teardown()
        return code

    # ------------------------------------------------------------------ helpers

    def ms(self) -> int:
        return int((time.monotonic() - self.t0) * 1000)

    def alive(self) -> list[str]:
        out = []
        for name, pid in list(self.pids.items()):
            if _reap(pid) is None:
                out.append(name)
            else:
                del self.pids[name]
        return out

    def progress(self) -> None:
        """A progress line on a terminal (quiet otherwise): step, objects delivered."""
        if not self.err.isatty() or self.stay:
            return
        line = _text(self.run.file(PROGRESS)).strip()
        if line and line != self.shown:
            self.shown = line
            step, done, total = (line.split() + ["?", "?", "?"])[:3]
            print(f"\r\033[Kost up: step {step}, delivered {done}/{total}", end="", file=self.err, flush=True)

    def end_progress(self) -> None:
        if self.shown:
            print("\r\033[K", end="", file=self.err, flush=True)
            self.shown = ""

    def teardown(self) -> None:
        """TERM every process, 3 s for a clean exit (destroy_node), then KILL; the Fast DDS files
        the run left in /dev/shm that no process maps; the PID files; what preparing took."""
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        for pid in self.pids.values():
            _signal(pid, signal.SIGTERM)
        end = time.monotonic() + 3.0
        while self.alive() and time.monotonic() < end:
            time.sleep(POLL_S)
        for pid in self.pids.values():
            _signal(pid, signal.SIGKILL)
            with contextlib.suppress(ChildProcessError):
                os.waitpid(pid, 0)
        self.pids.clear()
        _clean_shm(self.shm_before)
        for f in self.run.dir.glob("*.pid"):
            f.unlink(missing_ok=True)
        self.run.made_dir = False  # the run's directory stays: logs and result
        release(self.run)


def _signal(pid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, sig)


def _text(path: Path) -> str:
    try:
        return path.read_text()
    except OSError:
        return ""


def _tail(path: Path, n: int) -> list[str]:
    return _text(path).splitlines()[-n:]


def _clean_shm(before: set[str], prefixes: tuple[str, ...] = SHM_PREFIXES) -> None:
    """Shared-memory files (Fast DDS's, or those of ``prefixes``) that appeared since ``before``
    and no process maps any more."""
    if not SHM.is_dir():
        return
    new = [f for f in set(os.listdir(SHM)) - before if f.startswith(prefixes)]
    if not new:
        return
    mapped: set[str] = set()
    for maps in Path("/proc").glob("[0-9]*/maps"):
        mapped.update(m for m in re.findall(r"/dev/shm/(\S+)", _text(maps)))
    for f in new:
        if f not in mapped:
            (SHM / f).unlink(missing_ok=True)


def report(path: Path, as_json: bool, out: TextIO, err: TextIO) -> int:
    """Print a result file as ``ost sim`` does (``--json``: its JSON); 0 if the run completed."""
    from ost_ros.result import RunResult

    try:
        data = json.loads(path.read_text())
        print(json.dumps(data, indent=1) if as_json else RunResult.from_dict(data).summary(), file=out)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"ost up: error: {path}: cannot read the result ({exc.__class__.__name__})", file=err)
        return 2
    return 0 if data.get("completed") else 1


def wait_started(run_dir: Path, supervisor: int, err: TextIO = sys.stderr, limit_s: float = 120.0) -> int:
    """``--background``: until the supervisor has seen the run start (0) or gave up (1); its log
    so far is shown either way."""
    end = time.monotonic() + limit_s
    code = 1
    while time.monotonic() < end:
        if (run_dir / STARTED).exists():
            code = 0
            break
        try:
            os.kill(supervisor, 0)
        except ProcessLookupError:
            break
        time.sleep(POLL_S)
    err.write(_text(run_dir / "ost_up.log"))
    if code:
        alive = True
        try:
            os.kill(supervisor, 0)
        except ProcessLookupError:
            alive = False
        if alive:
            print(f"ost up: the run did not start within {limit_s:g} s; stopping it", file=err)
            stop(run_dir)
        else:
            print(f"ost up: the run failed to start (see {run_dir / 'ost_up.log'})", file=err)
    return code


def stop(run_dir: Path) -> int:
    """``ost_down.sh``: the supervisor tears the run down; processes still listed after 5 s are
    ended here (TERM, then KILL). The number ended here."""
    sup = _pid(run_dir / "ost_up.pid")
    if sup:
        _signal(sup, signal.SIGTERM)
        end = time.monotonic() + 5
        while time.monotonic() < end and _exists(sup):
            time.sleep(POLL_S)
    left = 0
    for f in run_dir.glob("*.pid"):
        pid = _pid(f)
        if f.name != "ost_up.pid" and pid and _exists(pid):
            left += 1
            _signal(pid, signal.SIGTERM)
            end = time.monotonic() + 3
            while time.monotonic() < end and _exists(pid):
                time.sleep(POLL_S)
            _signal(pid, signal.SIGKILL)
        f.unlink(missing_ok=True)
    # The simulated hosts, should no supervisor have removed them (a run prepared and never
    # supervised, or whose supervisor was killed). (A domain lock whose owner is gone is taken
    # over by the next run: left, since another run may hold that domain by now.)
    with contextlib.suppress(UsageError):
        run = Run.load(run_dir)
        run.domain_lock = ""
        release(run)
    return left


def _pid(path: Path) -> int:
    try:
        return int(path.read_text())
    except (OSError, ValueError):
        return 0


def _exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
