"""Proposal level (§3.2, §3.2.2): find the best (counter)offer near the previous one.

* Areas: a small elitist evolutionary search over polygon vertices. It starts from the
  previous offer and from the response (the part of T0 the others left free), so the search
  "learns" where the opponents' claims and hidden constraints are.
* Targets: a discrete step that drops contested points until the claim fits its size cap,
  choosing the point whose removal raises the reward most; ties go to the farthest point
  (§4.2) or to the one that shortens the route most (§5.1).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import Polygon

from .errors import NegotiationError
from .optimal import route_length
from .rewards import AreaReward, TargetReward
from .tasks import AreaTask, TargetTask, hole_free, largest_polygon


@dataclass(frozen=True)
class AreaSearch:
    """Evolutionary search settings: children per generation, generations, elites kept,
    mutation step (fraction of the claim's linear size), smallest shrink allowed per offer
    (the search may claim less than the δ cap when that pays), vertices per offered polygon."""

    population: int = 16
    generations: int = 3
    elites: int = 4
    sigma: float = 0.05
    min_scale: float = 1.0
    n_vertices: int = 8

    def __post_init__(self) -> None:
        if self.population < 1 or self.generations < 1 or self.elites < 1:
            raise NegotiationError("search population, generations and elites must be at least 1")
        if not 0.0 < self.min_scale <= 1.0:
            raise NegotiationError("min_scale must be in (0, 1]")
        if self.n_vertices < 3:
            raise NegotiationError("offered polygons need at least 3 vertices")


def densify(coords: np.ndarray, n: int) -> np.ndarray:
    """Insert midpoints on the longest edges until the ring has n vertices (shape kept exactly)."""
    c = np.asarray(coords, dtype=float)
    while len(c) < n:
        edges = np.roll(c, -1, axis=0) - c
        k = int(np.argmax(np.hypot(*edges.T)))
        c = np.insert(c, k + 1, c[k] + edges[k] / 2, axis=0)
    return c


def resample_ring(poly: Polygon, n: int) -> np.ndarray:
    """n points evenly spaced along a polygon's exterior (approximate shape, fixed size)."""
    ring = poly.exterior
    pts = [ring.interpolate(f, normalized=True).coords[0] for f in np.arange(n) / n]
    return np.asarray(pts)


def ring_coords(poly: Polygon, n: int) -> np.ndarray:
    c = np.asarray(poly.exterior.coords)[:-1]
    return densify(c, n) if len(c) <= n else resample_ring(poly, n)


def _shoelace(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed area and centroid of many rings at once (c: (M, n, 2))."""
    x, y = c[..., 0], c[..., 1]
    xn, yn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * yn - xn * y
    a = cross.sum(axis=1) / 2
    safe = np.where(np.abs(a) < 1e-15, 1e-15, a)
    cx = ((x + xn) * cross).sum(axis=1) / (6 * safe)
    cy = ((y + yn) * cross).sum(axis=1) / (6 * safe)
    return a, np.stack([cx, cy], axis=1)


def scale_to_area(c: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Scale each ring about its centroid so its area equals target (vectorised)."""
    a, cen = _shoelace(c)
    f = np.sqrt(np.asarray(target) / np.maximum(np.abs(a), 1e-15))
    return cen[:, None, :] + (c - cen[:, None, :]) * f[:, None, None]


def scale_to_inside_area(
    c: np.ndarray, target: np.ndarray, region, iters: int = 4, tol: float = 0.005
) -> tuple[np.ndarray, np.ndarray]:
    """Scale rings so their part inside ``region`` has the target area: a claim is a share
    *of the task*, so area outside T0 must not count towards it. Fixed-point iterations,
    repeated only for the rings not yet within ``tol``. Returns (rings, clipped geometries);
    invalid rings are returned unclipped (they score −inf)."""
    target = np.broadcast_to(np.asarray(target, dtype=float), (len(c),))
    c = scale_to_area(c, target)
    clipped = shapely.polygons(c)
    todo = np.arange(len(c))
    for k in range(iters + 1):
        polys = shapely.polygons(c[todo])
        ok = shapely.is_valid(polys)
        inside = np.zeros(len(todo))
        if ok.any():
            cut = shapely.intersection(polys[ok], region)
            clipped[todo[ok]] = cut
            inside[ok] = shapely.area(cut)
        clipped[todo[~ok]] = polys[~ok]
        good = ok & (inside > 1e-12)
        f = np.where(good, target[todo] / np.maximum(inside, 1e-12), 1.0)
        todo = todo[good & (np.abs(f - 1) > tol)]
        f = f[good & (np.abs(f - 1) > tol)]
        if len(todo) == 0 or k == iters:
            break
        a, _ = _shoelace(c[todo])
        c[todo] = scale_to_area(c[todo], np.abs(a) * f)
    return c, clipped


def propose_area(
    task: AreaTask,
    reward: AreaReward,
    prev: Polygon,
    cap: float,
    others: Sequence[Polygon],
    rng: np.random.Generator,
    search: AreaSearch,
    region=None,
) -> Polygon:
    """Best polygon near ``prev`` whose part inside the open region (T0 minus the shares of
    agents that already left) has area in [min_scale·cap, cap].

    Genotype: rings of ``n_vertices`` points; phenotype: their part inside the region (area
    outside T0 is worth nothing to anyone, so a rational claim never includes it).
    """
    region = task.t0 if region is None else region
    n = search.n_vertices
    seeds = [ring_coords(prev, n)]
    # Learning from the response: the part of our previous claim nobody else wants, and the
    # largest free region, are promising starting points.
    free = region.difference(task.union(list(others))) if others else region
    for area in (prev.intersection(free), free):
        piece = largest_polygon(area)
        if piece.area > 1e-6:
            seeds.append(resample_ring(piece, n))
    parents = np.stack(seeds)
    best_poly, best_v = None, -np.inf
    lin = math.sqrt(cap)
    for _ in range(search.generations):
        m = search.population
        pick = parents[rng.integers(0, len(parents), m)]
        kind = rng.integers(0, 3, m)
        noise = rng.normal(0.0, search.sigma * lin, (m, n, 2))
        one = np.zeros((m, n, 2))
        one[np.arange(m), rng.integers(0, n, m)] = rng.normal(0.0, 3 * search.sigma * lin, (m, 2))
        shift = rng.normal(0.0, search.sigma * lin, (m, 1, 2))
        child = pick + np.where(
            kind[:, None, None] == 0, noise, np.where(kind[:, None, None] == 1, one, shift)
        )
        scale = np.where(rng.random(m) < 0.5, 1.0, rng.uniform(search.min_scale, 1.0, m))
        raw = np.concatenate([parents, child])
        cand, clipped = scale_to_inside_area(
            raw, cap * np.concatenate([np.ones(len(parents)), scale]), region
        )
        vals = reward.batch_values(task, clipped, others)
        # Keep to the size rule (§3.2.1: dim T(t) = δ·dim T(t−1)): a claim whose part in the
        # region missed its size by more than 2 % only wins if nothing else is feasible.
        size = shapely.area(clipped)
        dev = (
            np.maximum(0.0, np.maximum(size / cap - 1.0, search.min_scale - size / cap))
            if cap > 0
            else 0 * size
        )
        vals = np.where(dev <= 0.02, vals, -1e6 - dev)
        if reward.forbidden is not None:
            # private constraints are hard: a claim on forbidden ground is never offered
            ok = shapely.is_valid(clipped)
            bad = np.zeros(len(clipped), dtype=bool)
            bad[ok] = shapely.area(shapely.intersection(clipped[ok], reward.forbidden)) > 1e-12
            vals = np.where(bad, -np.inf, vals)
        order = np.argsort(-vals)
        if vals[order[0]] > best_v:
            best_v, best_poly = vals[order[0]], hole_free(largest_polygon(clipped[order[0]]))
        keep = [k for k in order[: search.elites] if np.isfinite(vals[k])]
        if keep:
            parents = cand[keep]
    if (
        best_poly is None
        or best_poly.is_empty  # every candidate invalid: keep the previous claim
        or reward.constraint_violation(best_poly) > 0.0
    ):
        return prev
    return best_poly


def drop_targets(
    task: TargetTask,
    reward: TargetReward,
    prev: frozenset[int],
    cap: int,
    others: Sequence[frozenset[int]],
    rule: str = "farthest",
) -> frozenset[int]:
    """Shrink a target claim to at most ``cap`` points, dropping only points someone else
    also claims (dropping an uncontested point would leave it to nobody)."""
    if rule not in ("farthest", "path"):
        raise NegotiationError(f"unknown drop rule {rule!r} (expected farthest or path)")
    cur = set(prev)
    start = np.asarray(reward.start, dtype=float)
    claimed = task.union(list(others))
    while len(cur) > cap:
        contested = sorted(j for j in cur if j in claimed)
        if not contested:
            break
        base_route = route_length(start, task.points[sorted(cur)]) if rule == "path" else 0.0

        def key(j: int, base_route: float = base_route) -> tuple[float, float]:
            rest = frozenset(cur - {j})
            gain = reward.value(task, rest, others)
            if rule == "farthest":
                tie = float(np.hypot(*(task.points[j] - start)))
            else:
                tie = base_route - route_length(start, task.points[sorted(rest)])
            return (round(gain, 12), tie)

        cur.discard(max(contested, key=key))
    return frozenset(cur)
