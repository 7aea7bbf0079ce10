"""Where a study's runs execute: in this process, on a local process pool (the default), or on a
Dask distributed cluster (``--cluster``). Each executor takes a function and its items and gives
the results back in completion order; the runner (``runner.py``) makes the files independent of
that order.

Dask is imported only when a cluster is asked for, so ``ost`` starts as fast without it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ost_ros.errors import UsageError

CONNECT_TIMEOUT_S = 20.0  # for a scheduler to answer, and for its first worker to join


@dataclass(frozen=True)
class ClusterSpec:
    """What ``--cluster`` names: a running scheduler (``tcp://HOST:PORT``, ``tls://…``), a
    scheduler file (``FILE.json``), or a cluster of K worker processes on this machine
    (``local:K``)."""

    kind: str  # "address" | "file" | "local"
    target: str  # the address, the file, or K
    workers: int = 0  # local:K

    @classmethod
    def parse(cls, text: str) -> ClusterSpec:
        if text.startswith("local:"):
            k = text.partition(":")[2]
            if not k.isdigit() or not 1 <= int(k) <= 256:
                raise ValueError(f"{text!r}: local:K needs K worker processes, 1 to 256")
            return cls("local", text, int(k))
        if "://" in text:
            scheme, _, rest = text.partition("://")
            host, sep, port = rest.rpartition(":")
            if scheme not in ("tcp", "tls") or not sep or not host or not port.isdigit():
                raise ValueError(f"{text!r}: expected tcp://HOST:PORT or tls://HOST:PORT")
            return cls("address", text)
        if text.endswith(".json"):
            return cls("file", text)
        raise ValueError(f"{text!r}: expected tcp://HOST:PORT, a scheduler file FILE.json, or local:K")


class Executor:
    """Runs ``fn`` over items; results in completion order. ``workers``: runs at once."""

    workers: int = 1
    name: str = "this process"

    def map_unordered(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        return map(fn, items)

    def close(self) -> None:
        pass

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ProcessPool(Executor):
    """Worker processes on this machine. forkserver, not fork: the calling process may hold
    threads (tqdm's monitor, rclpy's executor), and forking those is unsafe."""

    def __init__(self, workers: int) -> None:
        from multiprocessing import get_context

        self.workers = workers
        self.name = f"{workers} worker processes"
        self._pool = get_context("forkserver").Pool(workers)
        self._finished = False

    def map_unordered(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        yield from self._pool.imap_unordered(fn, items, chunksize=1)
        self._finished = True

    def close(self) -> None:
        if self._finished:
            self._pool.close()
        else:  # interrupted, or a run raised: do not wait for the rest
            self._pool.terminate()
        self._pool.join()


class DaskCluster(Executor):
    """A Dask distributed cluster. Every item is one task, submitted with ``pure=False`` (two
    equal items are two tasks), at most ``in_flight`` at a time (so a large study does not flood
    the scheduler), each future released as soon as its result is read (a kept future makes the
    scheduler re-gather it when a worker dies). A worker that dies has its tasks re-run on
    another; ``retries`` covers a task that raises."""

    def __init__(self, spec: ClusterSpec, retries: int = 2) -> None:
        if spec.kind == "file" and not Path(spec.target).is_file():
            raise UsageError(f"--cluster {spec.target}: no such scheduler file")
        try:
            from distributed import Client, LocalCluster
        except ImportError as exc:  # pragma: no cover - the lock installs it
            raise UsageError(f"--cluster needs Dask distributed ({exc})") from None
        self.retries = retries
        self._cluster = None
        try:
            if spec.kind == "local":
                self._cluster = LocalCluster(
                    n_workers=spec.workers,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address=None,
                    silence_logs=40,  # logging.ERROR: no worker chatter on the study's stderr
                )
                self.client = Client(self._cluster)
            elif spec.kind == "file":
                self.client = Client(scheduler_file=spec.target, timeout=CONNECT_TIMEOUT_S)
            else:
                self.client = Client(spec.target, timeout=CONNECT_TIMEOUT_S)
            self.client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            self.close()
            raise UsageError(f"--cluster {spec.target}: {exc}".splitlines()[0]) from None
        self.workers = max(1, sum(self.client.nthreads().values()))
        self.in_flight = 2 * self.workers + 2
        self.name = (
            f"Dask cluster {self.client.scheduler_info().get('address', spec.target)}, {self.workers} workers"
        )

    def map_unordered(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        from distributed import as_completed

        todo = iter(items)
        running = as_completed(with_results=True)

        def submit() -> None:
            for item in todo:
                running.add(self.client.submit(fn, item, pure=False, retries=self.retries))
                return

        for _ in range(self.in_flight):
            submit()
        for future, result in running:
            future.release()
            submit()
            yield result

    def close(self) -> None:
        client = getattr(self, "client", None)
        if client is not None:
            client.close()
        if self._cluster is not None:
            self._cluster.close()


def open_executor(jobs: int | None = None, cluster: ClusterSpec | None = None) -> Executor:
    """The executor the flags ask for: ``--cluster`` if given, else ``jobs`` local processes
    (every core by default; one: in this process)."""
    if cluster is not None:
        return DaskCluster(cluster)
    jobs = jobs or os.cpu_count() or 1
    return Executor() if jobs == 1 else ProcessPool(jobs)
