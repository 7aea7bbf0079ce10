"""Task abstraction (§2): a task is a parameter vector; each task type defines dim, overlap,
union and "outside T0" on its sub-tasks, and how a sub-task maps to/from a flat number list.

* ``AreaTask``: T0 is a polygon; a sub-task is a polygon (vertices x1,y1,...,xk,yk).
* ``TargetTask``: T0 is a set of weighted points; a sub-task is a subset of them
  (encoded as the claimed points' coordinates, as in the paper's x = (p1..pn)).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely
from numpy.typing import ArrayLike
from shapely.geometry import MultiPolygon, Polygon, box
from shapely.geometry.base import BaseGeometry

from .errors import NegotiationError

EMPTY = Polygon()


def polygon_from_vertices(vertices: Sequence[Sequence[float]] | np.ndarray, what: str = "polygon") -> Polygon:
    """A valid, non-degenerate simple polygon from a vertex list, else NegotiationError."""
    try:
        arr = np.asarray(vertices, dtype=float)
    except (TypeError, ValueError):
        raise NegotiationError(f"{what}: vertices must be pairs of numbers") from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise NegotiationError(f"{what}: vertices must be a list of [x, y] pairs")
    if not np.all(np.isfinite(arr)):
        raise NegotiationError(f"{what}: vertices must be finite numbers")
    if len(np.unique(arr, axis=0)) < 3:
        raise NegotiationError(
            f"{what}: needs at least 3 distinct vertices, got {len(np.unique(arr, axis=0))}"
        )
    poly = Polygon(arr)
    if not poly.is_valid:
        raise NegotiationError(
            f"{what}: self-intersecting or otherwise invalid ({shapely.is_valid_reason(poly)})"
        )
    if poly.area <= 1e-9:
        raise NegotiationError(f"{what}: degenerate (zero area)")
    return poly


def make_task_polygon(area: float = 0.673) -> Polygon:
    """The fixed 6-vertex test polygon inside the unit square, scaled to ``area`` (§4.1, Fig. 4).

    The paper does not print its polygon; we use one irregular hexagon so all runs share T0.
    """
    base = np.array([(0.06, 0.05), (0.66, 0.01), (0.99, 0.40), (0.90, 0.96), (0.36, 0.99), (0.01, 0.58)])
    poly = Polygon(base)
    c = np.array(poly.centroid.coords[0])
    scaled = c + (base - c) * np.sqrt(area / poly.area)
    if scaled.min() < 0 or scaled.max() > 1:
        raise NegotiationError(f"task area {area} does not fit in the unit square")
    return Polygon(scaled)


def largest_polygon(geom: BaseGeometry) -> Polygon:
    """The largest polygonal piece of a geometry (empty polygon if none)."""
    if geom.is_empty:
        return EMPTY
    if isinstance(geom, Polygon):
        return geom
    polys = [g for g in getattr(geom, "geoms", []) if isinstance(g, (Polygon, MultiPolygon))]
    flat = [p for g in polys for p in (g.geoms if isinstance(g, MultiPolygon) else [g])]
    return max(flat, key=lambda p: p.area) if flat else EMPTY


def hole_free(poly: Polygon) -> Polygon:
    """A polygon without holes, by cutting through each hole and keeping the larger side.

    Offers are single rings (x1,y1,...), so a share must not have holes; this is used when
    an agent takes "what the others left", which can enclose someone else's share.
    """
    while not poly.is_empty and poly.interiors:
        hole = Polygon(poly.interiors[0])
        x = hole.centroid.x
        minx, miny, _, maxy = poly.bounds
        left = box(minx - 1, miny - 1, x, maxy + 1)
        sides = [largest_polygon(poly.intersection(left)), largest_polygon(poly.difference(left))]
        poly = max(sides, key=lambda p: p.area)
    return poly


@dataclass(frozen=True)
class AreaTask:
    """Area partitioning: T0 is a polygon; sub-tasks are polygons; dim is area."""

    t0: Polygon
    kind: str = field(default="area", init=False)

    @classmethod
    def from_vertices(cls, vertices: Sequence[Sequence[float]]) -> AreaTask:
        return cls(polygon_from_vertices(vertices, "task polygon"))

    @property
    def size(self) -> float:
        return float(self.t0.area)

    def full(self) -> Polygon:
        """The largest claim: the whole task."""
        return self.t0

    @staticmethod
    def dim(share: BaseGeometry) -> float:
        return float(share.area)

    @staticmethod
    def overlap(a: BaseGeometry, b: BaseGeometry) -> BaseGeometry:
        return a.intersection(b) if not (a.is_empty or b.is_empty) else EMPTY

    @staticmethod
    def union(shares: Sequence[BaseGeometry]) -> BaseGeometry:
        shares = [s for s in shares if not s.is_empty]
        return shapely.union_all(shares) if shares else EMPTY

    def outside(self, share: BaseGeometry) -> BaseGeometry:
        """Part of the sub-task outside T0 (S \\ T0)."""
        return share.difference(self.t0) if not share.is_empty else EMPTY

    def inside(self, share: BaseGeometry) -> BaseGeometry:
        return share.intersection(self.t0) if not share.is_empty else EMPTY

    # -- messages -------------------------------------------------------------------------------
    @staticmethod
    def encode(share: Polygon) -> tuple[float, ...]:
        """Polygon -> (x1, y1, ..., xk, yk), exterior ring without the closing vertex."""
        if share.is_empty:
            return ()
        if share.interiors:
            raise NegotiationError("a polygon with holes cannot be sent as one offer")
        return tuple(float(v) for v in np.asarray(share.exterior.coords)[:-1].ravel())

    @staticmethod
    def decode(params: Sequence[float]) -> Polygon:
        if len(params) == 0:
            return EMPTY
        if len(params) % 2:
            raise NegotiationError("area offer must have an even number of coordinates")
        return polygon_from_vertices(np.asarray(params, dtype=float).reshape(-1, 2), "offered polygon")


@dataclass(frozen=True)
class TargetTask:
    """Target points: T0 is N weighted points; a sub-task is a set of point indices; dim is
    the sum of the weights (§4.2). Nothing can lie outside T0."""

    points: np.ndarray
    weights: np.ndarray
    kind: str = field(default="targets", init=False)

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0:
            raise NegotiationError("targets: need at least one [x, y] point")
        if not np.all(np.isfinite(pts)):
            raise NegotiationError("targets: coordinates must be finite numbers")
        w = np.asarray(self.weights, dtype=float)
        if w.shape != (len(pts),) or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise NegotiationError("targets: need one positive weight per point")
        if len(np.unique(pts, axis=0)) != len(pts):
            raise NegotiationError("targets: points must be distinct")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "weights", w)

    @classmethod
    def from_points(cls, points: ArrayLike, weights: ArrayLike | None = None) -> TargetTask:
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        return cls(pts, np.ones(len(pts)) if weights is None else np.asarray(weights, dtype=float))

    @property
    def n(self) -> int:
        return len(self.points)

    @property
    def size(self) -> float:
        return float(self.weights.sum())

    def full(self) -> frozenset[int]:
        return frozenset(range(self.n))

    def dim(self, share: frozenset[int]) -> float:
        return float(self.weights[list(share)].sum()) if share else 0.0

    @staticmethod
    def overlap(a: frozenset[int], b: frozenset[int]) -> frozenset[int]:
        return a & b

    @staticmethod
    def union(shares: Sequence[frozenset[int]]) -> frozenset[int]:
        return frozenset().union(*shares) if shares else frozenset()

    @staticmethod
    def outside(share: frozenset[int]) -> frozenset[int]:
        return frozenset()  # a subset of T0's points is never outside T0

    @staticmethod
    def inside(share: frozenset[int]) -> frozenset[int]:
        return share

    def encode(self, share: frozenset[int]) -> tuple[float, ...]:
        """Claimed points as (x1, y1, ..., xm, ym), in index order."""
        return tuple(float(v) for v in self.points[sorted(share)].ravel())

    def decode(self, params: Sequence[float]) -> frozenset[int]:
        if len(params) % 2:
            raise NegotiationError("target offer must have an even number of coordinates")
        out = set()
        for xy in np.asarray(params, dtype=float).reshape(-1, 2):
            d = np.hypot(*(self.points - xy).T)
            i = int(np.argmin(d))
            if d[i] > 1e-9:
                raise NegotiationError(
                    f"offered point ({xy[0]:g}, {xy[1]:g}) is not one of the task's targets"
                )
            out.add(i)
        return frozenset(out)
