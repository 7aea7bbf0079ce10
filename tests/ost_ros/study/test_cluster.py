"""Studies on a real Dask distributed cluster on this machine (marker ``cluster``: worker
processes, all bound to 127.0.0.1 and ended by the test): the quick ``ost reproduce`` writes the
bytes the local process pool writes (the behaviour corpus' digests) on a LocalCluster and on a
``dask scheduler`` + ``dask worker`` pair whose workers hash differently and one of which is
killed mid-study; a study killed half-way resumes and ends with the same files."""

import contextlib
import io
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from ost_ros.cli import main
from ost_ros.commands import supervise
from tests.corpus.harness import EXPECTED, digests_of, run_reproduction

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


@pytest.fixture(autouse=True)
def _semaphores_left():
    """The worker processes these tests kill leave their multiprocessing semaphores in /dev/shm
    (``sem.mp-*``, 12 a run): removed after each test, those no live process maps."""
    shm = Path("/dev/shm")
    before = set(os.listdir(shm)) if shm.is_dir() else set()
    yield
    supervise._clean_shm(before, ("sem.mp-",))


WANT = json.loads(EXPECTED.read_text())["reproduce-quick"]
QUICK = ["reproduce", "--quick", "--out", "{out}"]
BIN = Path(sys.executable).parent


def rows_in(journal: Path) -> int:
    """Complete rows in a study's journal (after its header)."""
    if not journal.exists():
        return 0
    count = 0
    for line in journal.read_bytes().split(b"\n")[1:]:
        try:
            json.loads(line)
        except ValueError:
            break  # the line a kill tore, or the end
        count += 1
    return count


def when(check, then, timeout: float = 120.0) -> threading.Thread:
    """Run ``then()`` in a thread once ``check()`` holds (polled every 20 ms)."""

    def watch() -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if check():
                then()
                return
            time.sleep(0.02)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def group_gone(pgid: int, timeout: float = 30.0) -> bool:
    """Whether every process of the group has ended."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def test_local_cluster_writes_what_the_process_pool_writes(tmp_path):
    assert run_reproduction(QUICK + ["--cluster", "local:2"], tmp_path) == WANT
    assert not (tmp_path / "partial-reproduce.jsonl").exists()


@pytest.fixture
def scheduler(tmp_path):
    """``dask scheduler`` on 127.0.0.1 (a free port, its address in a scheduler file), and a
    way to start ``dask worker`` processes on it; every process is ended afterwards."""
    file = tmp_path / "scheduler.json"
    procs = [
        subprocess.Popen(
            [BIN / "dask", "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"]
            + ["--scheduler-file", str(file)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    ]

    def worker(**env: str) -> subprocess.Popen:
        p = subprocess.Popen(
            [BIN / "dask", "worker", "--scheduler-file", str(file), "--nthreads", "1", "--no-nanny"]
            + ["--host", "127.0.0.1", "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env={**os.environ, **env},
        )
        procs.append(p)
        return p

    try:
        end = time.monotonic() + 60
        while not file.exists() and time.monotonic() < end:
            time.sleep(0.05)
        yield file, worker
    finally:
        for p in procs:
            p.kill()
            p.wait(timeout=30)


def test_scheduler_and_workers_one_killed_mid_study(tmp_path, scheduler):
    file, worker = scheduler
    # Two workers that hash strings differently: the rows must not depend on it.
    a, b = worker(PYTHONHASHSEED="1"), worker(PYTHONHASHSEED="2")
    from distributed import Client

    with Client(scheduler_file=str(file), timeout=60) as client:
        client.wait_for_workers(2, timeout=60)
    out = tmp_path / "out"
    journal = out / "partial-reproduce.jsonl"
    killed = when(lambda: rows_in(journal) >= 10, lambda: os.kill(b.pid, signal.SIGKILL))
    assert run_reproduction(QUICK + ["--cluster", str(file)], out) == WANT
    killed.join(timeout=1)
    assert b.poll() == -signal.SIGKILL and a.poll() is None  # one died; the other ran its runs


def test_a_killed_study_resumes_with_the_same_files(tmp_path):
    out = tmp_path / "out"
    journal = out / "partial-reproduce.jsonl"
    argv = [a.replace("{out}", str(out)) for a in QUICK] + ["--cluster", "local:2"]
    study = subprocess.Popen(
        [sys.executable, "-m", "ost_ros", *argv, "--no-progress"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # its own process group: the study and its cluster's processes
    )
    try:
        end = time.monotonic() + 120
        while rows_in(journal) < 20 and study.poll() is None and time.monotonic() < end:
            time.sleep(0.02)
    finally:
        os.killpg(study.pid, signal.SIGKILL)
        study.wait(timeout=30)
    assert group_gone(study.pid)  # the scheduler and workers went with it
    done = rows_in(journal)
    assert 20 <= done < 160, done
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(argv) == 0
    resumed = re.search(r"\((\d+) more taken from the interrupted start\)", err.getvalue())
    assert resumed and int(resumed.group(1)) == done  # only the rest was run
    assert digests_of(out) == WANT and not journal.exists()
