"""The one study runner behind ``ost reproduce``, ``ost compare``, ``ost negotiate reproduce`` and
``ost faults report``.

A study is a list of run specs and a pure function of a spec that gives its row. The runner
sends the specs out in chunks (heaviest first, chunks shrinking towards the end, so the workers
finish together and per-task overhead stays small), takes the rows back in completion order —
into a journal on disk and a progress bar — and hands them over in spec order, so what a study
writes does not depend on the executor, the number of workers or the order the runs finished in.

The journal (``partial-<study>.jsonl`` in the output directory) makes a study resumable: killed
half-way and started again with the same output directory, it runs only the specs that have no
row yet. Every row, fresh or resumed, goes through the journal's encoding, so a resumed study
writes the same bytes as one that ran straight through. The journal goes once the study's files
are written (``Outcome.finish``).
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, is_dataclass
from functools import partial
from pathlib import Path
from typing import Any

from ost_ros.errors import UsageError
from ost_ros.study.executors import Executor

TASKS_PER_WORKER = 4  # chunks at a time: a chunk is at most 1/(this × workers) of what is left
MAX_CHUNKS_PER_WORKER = 64  # the smallest chunk is at least 1/(this × workers) of the study


@dataclass(frozen=True)
class Study[S, R]:
    """``run`` must be a module-level function (it is pickled to the workers) and pure: its row
    depends on the spec alone. ``weight``: a spec's relative cost (for the chunks); ``row_type``:
    the rows' dataclass (rows are plain JSON values when None)."""

    name: str
    specs: Sequence[S]
    run: Callable[[S], R]
    weight: Callable[[S], float] | None = None
    row_type: type | None = None

    def fingerprint(self) -> str:
        """The study's identity: its name and every spec (a journal only resumes its own study)."""
        text = repr((self.name, list(self.specs)))
        return hashlib.sha256(text.encode()).hexdigest()

    def encode(self, row: Any) -> Any:
        return asdict(row) if is_dataclass(row) and not isinstance(row, type) else row

    def decode(self, data: Any) -> Any:
        return data if self.row_type is None else self.row_type(**data)


@dataclass(frozen=True)
class Timing:
    wall: float  # seconds, start to finish of the runs made now
    cpu: float  # CPU seconds of every run, summed over the workers (resumed runs included)
    workers: int  # runs at once
    load: float  # 1-minute load average when the runs ended (a shared machine shows here)
    executor: str = ""  # where they ran
    resumed: int = 0  # runs taken from the journal of an interrupted start


@dataclass
class Outcome[R]:
    """The rows in spec order, each run's CPU seconds, and how long it took."""

    rows: list[R]
    cpu: list[float]
    timing: Timing
    journal: Path | None = field(default=None, repr=False)

    def finish(self) -> None:
        """The study's files are written: its journal is no longer needed."""
        if self.journal is not None:
            self.journal.unlink(missing_ok=True)


def chunks[S](todo: list[tuple[int, S]], weights: list[float], workers: int) -> list[list[tuple[int, S]]]:
    """Consecutive specs grouped so that a chunk holds at most 1/(TASKS_PER_WORKER × workers) of
    the weight still to come (guided scheduling: big chunks first, small ones at the end, when
    the workers should finish together) and at least 1/(MAX_CHUNKS_PER_WORKER × workers) of the
    study (so per-task overhead stays a small share)."""
    remaining = sum(weights)
    floor = remaining / (MAX_CHUNKS_PER_WORKER * workers)
    out: list[list[tuple[int, S]]] = []
    current: list[tuple[int, S]] = []
    load = 0.0
    for item, w in zip(todo, weights):
        current.append(item)
        load += w
        if load >= max(floor, remaining / (TASKS_PER_WORKER * workers)):
            out.append(current)
            remaining -= load
            current, load = [], 0.0
    if current:
        out.append(current)
    return out


def run_chunk[S, R](run: Callable[[S], R], chunk: list[tuple[int, S]]) -> list[tuple[int, R, float]]:
    """A worker's task: each spec's row and the CPU seconds it took."""
    out = []
    for i, spec in chunk:
        cpu = time.process_time()
        row = run(spec)
        out.append((i, row, time.process_time() - cpu))
    return out


def _plain(value: Any) -> Any:
    """json's fallback: numpy scalars as Python numbers."""
    item = getattr(value, "item", None)
    if item is None:
        raise TypeError(f"a study row holds a {type(value).__name__}, which JSON cannot carry")
    return item()


class Journal:
    """Rows as they come, one JSON line each, after a header naming the study."""

    def __init__(self, path: Path, study: Study) -> None:
        self.path = path
        self.study = study
        self._fh: Any = None

    def open(self) -> dict[int, tuple[Any, float]]:
        """The rows already there (a torn last line dropped), and the file ready to append."""
        header = {
            "study": self.study.name,
            "fingerprint": self.study.fingerprint(),
            "runs": len(self.study.specs),
        }
        done: dict[int, tuple[Any, float]] = {}
        if self.path.exists():
            data = self.path.read_bytes()
            lines = data.split(b"\n")
            try:
                first = json.loads(lines[0])
            except ValueError:
                first = None
            if first != header:
                raise UsageError(
                    f"{self.path} is the journal of an unfinished study with other options: run it "
                    "again with those, or delete the file to start this one"
                )
            good = len(lines[0]) + 1
            for line in lines[1:]:
                try:
                    entry = json.loads(line)
                    done[entry["i"]] = (self.study.decode(entry["row"]), entry["cpu"])
                except (ValueError, KeyError, TypeError):
                    break  # the line a kill tore (the last one): it is run again
                good += len(line) + 1
            with self.path.open("r+b") as fh:
                fh.truncate(min(good, len(data)))
            self._fh = self.path.open("a")
        else:
            self._fh = self.path.open("w")
            self._fh.write(json.dumps(header) + "\n")
            self._fh.flush()
        return done

    def append(self, results: list[tuple[int, Any, float]]) -> list[tuple[int, Any, float]]:
        """Write the rows; give them back as a resumed study would read them."""
        lines = []
        back = []
        for i, row, cpu in results:
            data = self.study.encode(row)
            text = json.dumps({"i": i, "cpu": cpu, "row": data}, default=_plain, separators=(",", ":"))
            lines.append(text + "\n")
            back.append((i, self.study.decode(json.loads(text)["row"]), cpu))
        self._fh.write("".join(lines))
        self._fh.flush()
        return back

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()


class _Memory(Journal):
    """No output directory: the same encoding, nothing on disk."""

    def __init__(self, study: Study) -> None:
        super().__init__(Path(os.devnull), study)

    def open(self) -> dict[int, tuple[Any, float]]:
        return {}

    def append(self, results: list[tuple[int, Any, float]]) -> list[tuple[int, Any, float]]:
        out = []
        for i, row, cpu in results:
            text = json.dumps(self.study.encode(row), default=_plain)
            out.append((i, self.study.decode(json.loads(text)), cpu))
        return out


def _bar(total: int, done: int, desc: str, progress: bool | None):
    from tqdm import tqdm

    show = sys.stderr.isatty() if progress is None else progress
    return tqdm(total=total, initial=done, desc=desc, unit="run", file=sys.stderr, disable=not show)


def run_study[S, R](
    study: Study[S, R],
    executor: Executor,
    out: Path | None = None,
    progress: bool | None = None,
    on_rows: Callable[[int], None] | None = None,
) -> Outcome[R]:
    """Every spec's row (those in ``out``'s journal of an interrupted start are not run again).
    ``progress``: a tqdm bar on stderr (default: when stderr is a terminal); ``on_rows``: called
    with the count of rows so far after every chunk."""
    journal = Journal(out / f"partial-{study.name}.jsonl", study) if out is not None else _Memory(study)
    done = journal.open()
    resumed = len(done)
    todo = [(i, s) for i, s in enumerate(study.specs) if i not in done]
    weights = [1.0 if study.weight is None else study.weight(s) for _, s in todo]
    parts = chunks(todo, weights, executor.workers)
    start = time.perf_counter()
    try:
        with _bar(len(study.specs), resumed, study.name, progress) as bar:
            results: Iterator[list[tuple[int, R, float]]] = executor.map_unordered(
                partial(run_chunk, study.run), parts
            )
            for got in results:
                for i, row, seconds in journal.append(got):
                    done[i] = (row, seconds)
                bar.update(len(got))
                if on_rows is not None:
                    on_rows(len(done))
    finally:
        journal.close()
    wall = time.perf_counter() - start
    rows = [done[i][0] for i in range(len(study.specs))]
    cpu = [done[i][1] for i in range(len(study.specs))]
    timing = Timing(wall, sum(cpu), executor.workers, os.getloadavg()[0], executor.name, resumed)
    return Outcome(rows, cpu, timing, journal.path if out is not None else None)
