"""Exact allocation of target points to robots (the reference of Tables 3 and 4).

Per-robot routes are optimal open paths from the robot's start through its targets
(Held–Karp dynamic programme over subsets). The allocation is a depth-first branch and
bound over target→robot assignments, pruning a branch as soon as its partial cost — which
can only grow as targets are added (triangle inequality) — reaches the best complete one.
Robots sharing a start are interchangeable, so an empty robot is only tried once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import permutations, product

import numpy as np
from numpy.typing import ArrayLike

from .errors import NegotiationError

MAX_TARGETS = 14  # 2^N·N² table; beyond this use a heuristic, not this solver
EXACT_ROUTE = 12  # one route of up to this many targets is exact; longer ones use ``heuristic_route``


def subset_route_costs(start: ArrayLike, points: np.ndarray) -> np.ndarray:
    """cost[mask] = length of the shortest open path from ``start`` visiting the targets in mask."""
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    if n > MAX_TARGETS:
        raise NegotiationError(f"exact solver handles at most {MAX_TARGETS} targets, got {n}")
    d0 = np.hypot(*(pts - np.asarray(start, dtype=float)).T)
    d = np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1])
    full = 1 << n
    end = np.full((full, max(n, 1)), np.inf)  # end[mask, j]: best path over mask ending at j
    for j in range(n):
        end[1 << j, j] = d0[j]
    for mask in range(1, full):
        row = end[mask]
        if not np.isfinite(row).any():
            continue
        for j in range(n):
            if mask >> j & 1:
                continue
            cand = row + d[:, j]  # entries outside mask are inf already
            best = cand.min()
            nm = mask | 1 << j
            if best < end[nm, j]:
                end[nm, j] = best
    cost = end.min(axis=1) if n else np.zeros(1)
    cost[0] = 0.0
    return cost


def route_length(start: ArrayLike, points: np.ndarray) -> float:
    """Shortest open path from start through all points: exact (Held–Karp) up to
    ``EXACT_ROUTE`` points, the nearest-neighbour + 2-opt tour of ``heuristic_route`` above."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) > EXACT_ROUTE:
        return heuristic_route(start, pts)
    return float(subset_route_costs(start, pts)[(1 << len(pts)) - 1]) if len(pts) else 0.0


def route_is_exact(n: int) -> bool:
    """Whether ``route_length`` of n points is the exact shortest path."""
    return n <= EXACT_ROUTE


def heuristic_route(start: ArrayLike, points: np.ndarray, max_passes: int = 50) -> float:
    """An open path from start through every point: nearest neighbour, then 2-opt moves until
    none shortens it (at most ``max_passes`` sweeps, so the work is bounded). Deterministic."""
    pts = np.vstack([np.asarray(start, dtype=float).reshape(1, 2), np.asarray(points, dtype=float)])
    n = len(pts)
    d = np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1])
    order, left = [0], set(range(1, n))
    while left:
        nxt = min(left, key=lambda j: (d[order[-1], j], j))
        order.append(nxt)
        left.discard(nxt)
    for _ in range(max_passes):
        improved = False
        for i in range(1, n - 1):
            for k in range(i + 1, n):
                a, b = order[i - 1], order[i]
                # reversing order[i..k]: an open path has no edge after its last point
                after = d[order[k], order[k + 1]] if k + 1 < n else 0.0
                new_after = d[b, order[k + 1]] if k + 1 < n else 0.0
                if d[a, order[k]] + new_after < d[a, b] + after - 1e-12:
                    order[i : k + 1] = order[i : k + 1][::-1]
                    improved = True
        if not improved:
            break
    return float(sum(d[order[i], order[i + 1]] for i in range(n - 1)))


@dataclass(frozen=True)
class Allocation:
    """Targets per robot (index sets) and their optimal route lengths."""

    shares: tuple[frozenset[int], ...]
    lengths: tuple[float, ...]

    @property
    def total(self) -> float:
        return float(sum(self.lengths))

    @property
    def max_individual(self) -> float:
        return float(max(self.lengths)) if self.lengths else 0.0


def evaluate_allocation(
    starts: np.ndarray, points: np.ndarray, shares: Sequence[frozenset[int]]
) -> Allocation:
    """Route lengths of a given allocation, each robot taking its optimal route."""
    lengths = tuple(route_length(s, np.asarray(points)[sorted(sh)]) for s, sh in zip(starts, shares))
    return Allocation(tuple(frozenset(s) for s in shares), lengths)


def optimal_allocation(starts: ArrayLike, points: ArrayLike, objective: str = "total") -> Allocation:
    """Exact optimum over all assignments: objective "total" (sum of route lengths) or
    "max" (longest individual route, i.e. mission time)."""
    if objective not in ("total", "max"):
        raise NegotiationError(f"unknown objective {objective!r} (expected total or max)")
    st = np.asarray(starts, dtype=float).reshape(-1, 2)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    r, n = len(st), len(pts)
    if r == 0:
        raise NegotiationError("need at least one robot")
    keys = [tuple(s) for s in st]
    tables = {k: subset_route_costs(k, pts) for k in dict.fromkeys(keys)}
    cost = [tables[k] for k in keys]
    combine = (lambda a, b: a + b) if objective == "total" else max
    # Assign far targets first: they decide most of the cost, so good bounds come early.
    order = sorted(range(n), key=lambda j: -min(np.hypot(*(pts[j] - s)) for s in st))
    best_value = np.inf
    best_masks: list[int] = []
    masks = [0] * r

    def value() -> float:
        v = 0.0
        for i in range(r):
            v = combine(v, cost[i][masks[i]])
        return v

    def dfs(depth: int) -> None:
        nonlocal best_value, best_masks
        v = value()
        if v >= best_value - 1e-12:
            return
        if depth == n:
            best_value, best_masks = v, list(masks)
            return
        j = order[depth]
        tried_empty: set[tuple[float, float]] = set()
        for i in range(r):
            if masks[i] == 0:  # interchangeable empty robots: try one per start position
                if keys[i] in tried_empty:
                    continue
                tried_empty.add(keys[i])
            masks[i] |= 1 << j
            dfs(depth + 1)
            masks[i] &= ~(1 << j)

    dfs(0)
    shares = tuple(frozenset(j for j in range(n) if m >> j & 1) for m in best_masks)
    return Allocation(shares, tuple(float(cost[i][m]) for i, m in enumerate(best_masks)))


def brute_force_allocation(starts: ArrayLike, points: ArrayLike, objective: str = "total") -> float:
    """Reference for tests: every assignment, every visiting order. Tiny cases only."""
    st = np.asarray(starts, dtype=float).reshape(-1, 2)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    best = np.inf
    for assign in product(range(len(st)), repeat=len(pts)):
        lengths = []
        for i, s in enumerate(st):
            mine = [j for j, a in enumerate(assign) if a == i]
            bl = (
                0.0
                if not mine
                else min(
                    sum(
                        np.hypot(*(b - a))
                        for a, b in zip([s] + [pts[k] for k in perm], [pts[k] for k in perm])
                    )
                    for perm in permutations(mine)
                )
            )
            lengths.append(bl)
        v = sum(lengths) if objective == "total" else max(lengths)
        best = min(best, v)
    return float(best)
