"""Proposal level (§3.2, §3.2.2): find the best (counter)offer near the previous one.

* Areas: a small elitist evolutionary search over polygon vertices. It starts from the
  previous offer and from the response (the part of T0 the others left free), so the search
  "learns" where the opponents' claims and hidden constraints are.
* Targets: a complete search over which contested points to drop when the claim's size cap
  falls (``search_target_offer``), ranked by the update rule: the furthest points (§4.2), the
  drop that shortens the route most (§5.1), or the largest reward gain (``reward``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

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
    clip: bool = True,
) -> Polygon:
    """Best polygon near ``prev`` whose part inside the open region (T0 minus the shares of
    agents that already left) has area in [min_scale·cap, cap].

    Genotype: rings of ``n_vertices`` points. With ``clip`` the phenotype is their part inside
    the region (area outside T0 is worth nothing to anyone, so a rational claim never includes
    it); without, the ring itself is offered and scored, so the reward's out-of-T0 and overlap
    penalties — not the search — keep it inside (the paper's protocol, Table 2's "area out").
    """
    region = task.t0 if region is None else region
    # Unclipped offers are judged against what is still being negotiated: once partners have
    # left with their shares, the rest is the task, and a ring reaching into a share already
    # taken is partly outside it (the paper's "another round ... sharing the remaining task").
    judged = task if clip or region is task.t0 else AreaTask(region)
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
        offered = clipped if clip else shapely.polygons(cand)
        if not clip and reward.forbidden is not None:
            # its own forbidden ground is cut out of every ring it could offer (private: the
            # partner only ever sees the notch)
            ok = shapely.is_valid(offered)
            offered = offered.copy()
            offered[ok] = shapely.difference(offered[ok], reward.forbidden)
        vals = reward.batch_values(judged, offered, others, inside_known=clip)
        # Keep to the size rule (§3.2.1: dim T(t) = δ·dim T(t−1)): a claim whose part in the
        # region missed its size by more than 2 % only wins if nothing else is feasible.
        size = shapely.area(clipped)
        dev = (
            np.maximum(0.0, np.maximum(size / cap - 1.0, search.min_scale - size / cap))
            if cap > 0
            else 0 * size
        )
        vals = np.where(dev <= 0.02, vals, -1e6 - dev)
        if not clip:
            # a sliver cannot be sent as an offer (the receiver refuses a zero-area polygon);
            # unclipped rings are rescaled to their part in the region, which can leave one
            vals = np.where(shapely.area(offered) > 1e-9, vals, -np.inf)
        if reward.forbidden is not None:
            # private constraints are hard: a claim on forbidden ground is never offered
            ok = shapely.is_valid(offered)
            bad = np.zeros(len(offered), dtype=bool)
            bad[ok] = shapely.area(shapely.intersection(offered[ok], reward.forbidden)) > 1e-12
            vals = np.where(bad, -np.inf, vals)
        order = np.argsort(-vals)
        if vals[order[0]] > best_v:
            best_v, best_poly = vals[order[0]], hole_free(largest_polygon(offered[order[0]]))
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


DROP_RULES = ("furthest", "path", "reward")
SEARCH_BUDGET = 5000  # drop sets ranked per offer; beyond it, one point at a time (bounded work)


def check_drop_rule(rule: str) -> str:
    """``rule`` if it is one of ``DROP_RULES``, else a one-line NegotiationError."""
    if rule not in DROP_RULES:
        raise NegotiationError(f"unknown drop rule {rule!r} (expected one of {', '.join(DROP_RULES)})")
    return rule


def search_target_offer(
    task: TargetTask,
    reward: TargetReward,
    prev: frozenset[int],
    cap: int,
    others: Sequence[frozenset[int]],
    rule: str = "furthest",
) -> frozenset[int]:
    """The next target offer: ``prev`` shrunk to at most ``cap`` points.

    Only points someone else also claims are dropped (dropping an uncontested one would leave
    it to nobody, and §4.2 ends every run with G = N). Which ones is decided by a complete
    search over the sets of contested points of the size to drop, ranked by the update rule:

    * ``furthest`` (§4.2, "the offer update removes from the set the furthest one"): the points
      furthest from the robot;
    * ``path`` (§5.1, "removes … the one that reduces by the most the total path"): the set whose
      removal shortens the robot's route p(S) most;
    * ``reward``: the largest private reward g_i after the drop (points claimed by the most
      partners first), the furthest breaking ties — this library's rule before the paper's.

    The ranking is a complete enumeration (the paper's "complete discrete search", §3.2); when
    more than ``SEARCH_BUDGET`` sets would have to be ranked it drops one point at a time with
    the same ranking, so the work stays bounded.
    """
    check_drop_rule(rule)
    cur = frozenset(prev)
    claimed = task.union(list(others))
    contested = sorted(j for j in cur if j in claimed)
    k = min(len(cur) - cap, len(contested))
    if k <= 0:
        return cur
    if k > 1 and math.comb(len(contested), k) > SEARCH_BUDGET:
        for _ in range(k):
            cur = search_target_offer(task, reward, cur, len(cur) - 1, others, rule)
        return cur
    key = _drop_key(task, reward, cur, others, rule)
    best = max(combinations(contested, k), key=key)
    return cur - frozenset(best)


def _drop_key(task: TargetTask, reward: TargetReward, cur: frozenset[int], others, rule: str):
    """Ranking of a drop set (larger is better); index order breaks exact ties (determinism)."""
    start = np.asarray(reward.start, dtype=float)
    dist = np.hypot(*(task.points - start).T)

    def furthest(drop: tuple[int, ...]) -> tuple:
        return tuple(sorted((round(float(dist[j]), 12) for j in drop), reverse=True))

    if rule == "furthest":
        return furthest
    if rule == "path":
        return lambda drop: -round(route_length(start, task.points[sorted(cur - frozenset(drop))]), 12)
    return lambda drop: (round(reward.value(task, cur - frozenset(drop), others), 12), furthest(drop))
