"""Time Algorithm Coordination on the paper's largest case (M=200 objects, N=50 agents).

    .venv/bin/python benchmarks/bench_coordination.py [--objects 200] [--agents 50] [--repeat 20]

Prints the median and best wall time of one full coordination (all M objects in one batch).
"""

import argparse
import statistics
import time

import numpy as np

from ost_ros.coordination import coordinate
from ost_ros.model import Grid
from ost_ros.scenario import generate_objects


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--objects", type=int, default=200)
    p.add_argument("--agents", type=int, default=50)
    p.add_argument("--repeat", type=int, default=20)
    a = p.parse_args()
    grid = Grid()
    objects = generate_objects(a.objects, seed=1, grid=grid)
    rng = np.random.default_rng(2)
    ids = list(range(a.agents))
    cost = rng.integers(0, 3000, a.agents)
    loc = np.stack([rng.integers(0, grid.width, a.agents), rng.integers(0, grid.height, a.agents)], 1)
    times = []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        coordinate(ids, cost, loc, objects)
        times.append(time.perf_counter() - t0)
    print(
        f"coordinate M={a.objects} N={a.agents}: median {statistics.median(times) * 1e3:.1f} ms, "
        f"best {min(times) * 1e3:.1f} ms over {a.repeat} runs"
    )


if __name__ == "__main__":
    main()
