"""Runs a design's tasks on every core (multiprocessing, forkserver: the CLI process may hold
threads, e.g. of rclpy, so plain fork is unsafe), with a progress bar."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from multiprocessing import get_context

from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.result import RunResult
from ost_ros.study.design import Design, Task, scenario_of


@dataclass(frozen=True)
class Row:
    agents: int
    objects: int
    set: int
    seed: int
    variant: str
    protocol: str
    ci: str
    makespan: int
    last_delivery: int
    lower_bound: int
    messages: int
    coordinations: int
    study_seed: int = 1
    search_end: int = 0  # the last agent's end of search (its search steps)
    first_carry: int = 0  # the first step any object was carried


def run_task(task: Task) -> tuple[list[Row], float]:
    """The task's rows, and the CPU seconds it took."""
    cpu = time.process_time()
    scenario = scenario_of(task)
    bound = lower_bound(scenario).value
    rows = []
    done: dict[tuple[str, int], RunResult] = {}
    for v in task.variants:
        if v.ci is None:  # a protocol without coordination triggers
            r = simulate(scenario, v.protocol, engine="event")
        else:
            ci = task.objects if v.ci == "M" else int(v.ci)
            # Every CI > M is the same run (coordination only once everyone has searched).
            ci = min(max(ci, 1), task.objects + 1)
            if (v.protocol, ci) not in done:
                done[(v.protocol, ci)] = simulate(
                    scenario, v.protocol, CoordinationPolicy(ci=ci), engine="event"
                )
            r = done[(v.protocol, ci)]
        if not r.completed or r.rejections or r.warnings:
            raise RuntimeError(
                f"{v.label} on N={task.agents} M={task.objects} set {task.set}: "
                f"{r.error or (r.rejections + r.warnings)[:1]}"
            )
        rows.append(
            Row(
                task.agents,
                task.objects,
                task.set,
                task.seed,
                v.label,
                v.protocol,
                "" if v.ci is None else str(v.ci),
                int(r.makespan or 0),
                r.last_delivery,
                bound,
                r.messages,
                r.coordinations,
                task.study_seed,
                max((a.search for a in r.agents), default=0),
                min((o.start for o in r.objects if o.start is not None), default=0),
            )
        )
    return rows, time.process_time() - cpu


@dataclass(frozen=True)
class Timing:
    wall: float  # seconds, start to finish of the runs
    cpu: float  # CPU seconds summed over the workers
    workers: int
    load: float  # 1-minute load average when the runs ended (a shared machine shows here)


def run_design(
    design: Design, workers: int | None = None, progress: bool | None = None
) -> tuple[list[Row], Timing]:
    """All runs of the design (sorted), and how long they took."""
    tasks = design.tasks()
    workers = workers or os.cpu_count() or 1
    show = sys.stderr.isatty() if progress is None else progress
    from tqdm import tqdm

    rows: list[Row] = []
    cpu = 0.0
    start = time.perf_counter()
    with tqdm(total=len(tasks), desc="runs", unit="task", file=sys.stderr, disable=not show) as bar:
        results: Iterator[tuple[list[Row], float]]
        if workers == 1:
            results = map(run_task, tasks)
            pool = None
        else:
            pool = get_context("forkserver").Pool(workers)
            results = pool.imap_unordered(run_task, tasks, chunksize=1)
        try:
            for out, seconds in results:
                rows.extend(out)
                cpu += seconds
                bar.update()
        finally:
            if pool is not None:
                pool.close()
                pool.join()
    wall = time.perf_counter() - start
    rows.sort(key=lambda r: (r.study_seed, r.agents, r.objects, r.variant, r.set))
    return rows, Timing(wall, cpu, workers, os.getloadavg()[0])


def row_dicts(rows: list[Row]) -> list[dict]:
    return [asdict(r) for r in rows]
