"""The study runner on the local process pool against a Dask LocalCluster of as many workers, in
one run: the full ``ost reproduce`` and a larger ``ost compare`` (the study's grid, 2 object sets
by default), each on both, back to back.

    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_study.py [--rounds R] [--compare-sets K] [--skip-compare]

Prints, with the load average at each figure: wall time (runs, and end to end with tables and
plots; the cluster's start counted in its end to end), CPU seconds, the cluster's overhead as a
ratio of wall times (goal ≤ 1.10), CPU per run for each variant, whether both wrote the same
CSVs, and what a 10⁵-run sweep would take on K machines of this kind from the measured figures.
Targets: the full ``ost reproduce`` under 120 s on the local pool (2 cores).
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from ost_ros.study import compare, report
from ost_ros.study.design import Design
from ost_ros.study.executors import ClusterSpec, DaskCluster, Executor, ProcessPool
from ost_ros.study.reproduce import run_design

SWEEP = 100_000  # runs in the sweep projected at the end


def load() -> str:
    return f"load {os.getloadavg()[0]:.1f}"


def reproduce(ex: Executor, out: Path):
    design = replace(Design(seed=1), table3_seeds=tuple(range(1, 6)))  # as `ost reproduce`
    rows, outcome = run_design(design, ex, progress=False)
    report.write_all(out, design, rows, outcome.timing, quick=False)
    return outcome


def larger_compare(sets: int) -> Callable[[Executor, Path], object]:
    def go(ex: Executor, out: Path):
        rows, outcome = compare.run_all(compare.grid(False, sets), ex, progress=False)
        compare.write_all(rows, outcome.timing, out)
        return outcome

    return go


def per_variant(outcome) -> dict[str, list[float]]:
    cpu: dict[str, list[float]] = defaultdict(list)
    for row, seconds in zip(outcome.rows, outcome.cpu):
        cpu[row.variant].append(seconds)
    return cpu


def same_csvs(a: Path, b: Path) -> bool:
    """Every CSV the same, byte for byte — but for the measured CPU column (ost compare's cpu_s)."""
    names = sorted(p.name for p in a.glob("*.csv"))
    return bool(names) and all(_untimed(a / n) == _untimed(b / n) for n in names)


def _untimed(path: Path) -> list[list[str]]:
    rows = list(csv.reader(path.open()))
    drop = {i for i, name in enumerate(rows[0] if rows else []) if name == "cpu_s"}
    return [[x for i, x in enumerate(r) if i not in drop] for r in rows]


def measure(
    name: str, study: Callable[[Executor, Path], object], workers: int, tmp: Path, rounds: int
) -> dict:
    """The study on the pool and on the cluster, alternately ``rounds`` times (a shared machine's
    load moves between runs: the ratio is taken of each one's best, and shown round by round)."""
    runs: dict[str, list] = {"pool": [], "cluster": []}
    for k in range(rounds):
        for label, make in (
            ("pool", lambda: ProcessPool(workers)),
            ("cluster", lambda: DaskCluster(ClusterSpec.parse(f"local:{workers}"))),
        ):
            out = tmp / f"{name}-{label}-{k}"
            out.mkdir()
            t0 = time.perf_counter()
            with make() as ex:
                started = time.perf_counter() - t0
                outcome = study(ex, out)
            total = time.perf_counter() - t0
            t = outcome.timing  # type: ignore[attr-defined]
            runs[label].append((t, total, outcome, out))
            print(
                f"{name} on the {label} ({t.executor}): {len(outcome.rows)} runs in {t.wall:.1f} s, "  # type: ignore[attr-defined]
                f"{total:.1f} s end to end ({started:.1f} s to start), {t.cpu:.1f} CPU s, {load()}",
                flush=True,
            )
    pool = min(runs["pool"], key=lambda r: r[0].wall)
    cluster = min(runs["cluster"], key=lambda r: r[0].wall)
    pairs = ", ".join(f"{c[0].wall / p[0].wall:.3f}" for p, c in zip(runs["pool"], runs["cluster"]))
    same = all(same_csvs(runs["pool"][0][3], r[3]) for r in runs["pool"][1:] + runs["cluster"])
    print(
        f"{name}: cluster / pool wall, best of each: {cluster[0].wall / pool[0].wall:.3f} (runs), "
        f"{cluster[1] / pool[1]:.3f} (end to end, the cluster's start included); round by round: {pairs}; "
        f"CPU {cluster[0].cpu / pool[0].cpu:.3f}; every run wrote the same CSVs: {same}; {load()}"
    )
    print(f"{name}: CPU per run by variant (pool): variant, runs, mean ms, total s, share")
    cpu = per_variant(pool[2])
    total_cpu = sum(map(sum, cpu.values()))
    for v, xs in sorted(cpu.items(), key=lambda kv: -sum(kv[1])):
        print(
            f"  {v:24s} {len(xs):5d} {1000 * statistics.fmean(xs):9.1f} {sum(xs):8.1f} {sum(xs) / total_cpu:6.1%}"
        )
    return {"name": name, "per_run": total_cpu / len(pool[2].rows), "ratio": cluster[0].wall / pool[0].wall}


def sweep(measured: list[dict], workers: int) -> None:
    """A 10⁵-run sweep on K machines like this one (``workers`` each): the runs' CPU spread over
    K·workers, times the overhead ratio the cluster showed here."""
    print(f"\n{SWEEP:,} runs, machines of {workers} cores (from the measured CPU per run and ratio):")
    for m in measured:
        one = SWEEP * m["per_run"] / workers
        line = ", ".join(f"{k}: {one * max(m['ratio'], 1) / k / 3600:.2f} h" for k in (1, 2, 4, 8, 16))
        print(
            f"  at {m['name']}'s mix ({1000 * m['per_run']:.1f} ms CPU a run): the local pool of one machine "
            f"{one / 3600:.2f} h; a Dask cluster of K machines, K = {line}"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--compare-sets", type=int, default=2, help="object sets of the larger ost compare (2)")
    p.add_argument("--skip-compare", action="store_true")
    p.add_argument("--skip-reproduce", action="store_true")
    p.add_argument("--rounds", type=int, default=1, help="pool and cluster alternately, this many times (1)")
    a = p.parse_args()
    print(f"{os.cpu_count()} cores, {a.workers} workers, {load()}", flush=True)
    measured = []
    with tempfile.TemporaryDirectory(prefix="ost_bench_study_") as tmp:
        if not a.skip_reproduce:
            measured.append(measure("reproduce", reproduce, a.workers, Path(tmp), a.rounds))
        if not a.skip_compare:
            measured.append(
                measure("compare", larger_compare(a.compare_sets), a.workers, Path(tmp), a.rounds)
            )
    sweep(measured, a.workers)


if __name__ == "__main__":
    main()
