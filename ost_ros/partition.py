"""Equal partition of the working area into one subarea per agent (paper §2.3, §5.1, Table 2)."""

from __future__ import annotations

import math

from ost_ros.model import Grid, Subarea

# Table 2 of the paper: number of agents -> partition m×n (m along x, n along y).
TABLE2: dict[int, tuple[int, int]] = {10: (5, 2), 20: (5, 4), 30: (6, 5), 40: (10, 4), 50: (10, 5)}


def choose_partition(n_agents: int, grid: Grid) -> tuple[int, int]:
    """The paper's partition for N in Table 2; otherwise the factorisation m·n = N whose m/n is
    closest (in log ratio) to the grid's aspect ratio width/height, ties to the larger m."""
    if n_agents < 1:
        raise ValueError("the team needs at least one agent")
    if n_agents in TABLE2:
        m, n = TABLE2[n_agents]
        if m <= grid.width and n <= grid.height:
            return m, n
    aspect = math.log(grid.width / grid.height)
    best: tuple[float, int, int] | None = None
    for m in range(1, n_agents + 1):
        if n_agents % m:
            continue
        n = n_agents // m
        if m > grid.width or n > grid.height:
            continue
        score = abs(math.log(m / n) - aspect)
        key = (round(score, 12), -m, n)
        if best is None or key < best:
            best = key
    if best is None:
        raise ValueError(f"{n_agents} agents cannot partition a {grid.width}x{grid.height} grid")
    return (-best[1], best[2])


def split(length: int, parts: int) -> list[tuple[int, int]]:
    """Split ``length`` cells into ``parts`` runs as equal as integer division allows
    (the first ``length % parts`` runs get one extra cell). Returns (start, size) pairs."""
    base, extra = divmod(length, parts)
    runs, start = [], 0
    for k in range(parts):
        size = base + (1 if k < extra else 0)
        runs.append((start, size))
        start += size
    return runs


def subareas(grid: Grid, partition: tuple[int, int]) -> tuple[Subarea, ...]:
    """The m×n subareas in row-major order: index k = j·m + i for column i, row j."""
    m, n = partition
    if m < 1 or n < 1 or m > grid.width or n > grid.height:
        raise ValueError(f"partition {m}x{n} does not fit a {grid.width}x{grid.height} grid")
    cols, rows = split(grid.width, m), split(grid.height, n)
    return tuple(Subarea(x0, y0, w, h) for (y0, h) in rows for (x0, w) in cols)
