"""Private rewards g_i (weighted terms of Table 1) and the global coverage index G (§2).

Each robot owns one reward object; its private constraints (a no-fly zone, unreachable
targets) live only here and never enter a message.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from .tasks import AreaTask, TargetTask


def ill_shape(share: BaseGeometry) -> float:
    """ill(S) = perimeter / area (§4.1); 0 for an empty share (nothing to penalise)."""
    return float(share.length / share.area) if share.area > 0 else 0.0


@dataclass(frozen=True)
class AreaReward:
    """g_i(S) = w_dim·dim(S ∩ T0) − w_out·dim(S \\ T0) − w_overlap·Σ_j dim(S ∩ S_j) − w_ill·ill(S)
    − w_forbidden·dim(S ∩ F) − w_dist·dist(start, S).

    With ``value_inside=False`` the first term is the literal dim(S) (leaving T0 is then free,
    +1 − 1, and the ill-shape term pushes claims outward); with ``value_inside`` (default) both
    the first term and ill(S) are taken on S ∩ T0, the part of the claim that is task.
    Defaults are §4.1 (1, 1, 2, 0.2); the §2.2 example uses w_overlap = 1, w_ill = 0 and a
    forbidden zone F with w_forbidden = 1000.
    """

    w_dim: float = 1.0
    w_out: float = 1.0
    w_overlap: float = 2.0
    w_ill: float = 0.2
    forbidden: Polygon | None = None
    w_forbidden: float = 1000.0
    start: tuple[float, float] | None = None
    w_dist: float = 0.0
    value_inside: bool = True  # dim term counts only the part in T0 (see interpretation notes)

    def terms(self, task: AreaTask, share: BaseGeometry, others: Sequence[BaseGeometry]) -> dict[str, float]:
        """The individual terms (unweighted), for reports and hand checks."""
        return {
            "dim": task.dim(task.inside(share)) if self.value_inside else task.dim(share),
            "out": task.dim(task.outside(share)),
            "overlap": sum(task.dim(task.overlap(share, o)) for o in others),
            "ill": ill_shape(task.inside(share) if self.value_inside else share),
            "forbidden": self.constraint_violation(share),
            "dist": self._dist(share),
        }

    def value(self, task: AreaTask, share: BaseGeometry, others: Sequence[BaseGeometry]) -> float:
        t = self.terms(task, share, others)
        return (
            self.w_dim * t["dim"]
            - self.w_out * t["out"]
            - self.w_overlap * t["overlap"]
            - self.w_ill * t["ill"]
            - self.w_forbidden * t["forbidden"]
            - self.w_dist * t["dist"]
        )

    def constraint_violation(self, share: BaseGeometry) -> float:
        """Size of the share inside the private forbidden zone (0 = acceptable)."""
        if self.forbidden is None or share.is_empty:
            return 0.0
        return float(share.intersection(self.forbidden).area)

    def _dist(self, share: BaseGeometry) -> float:
        if self.start is None or self.w_dist == 0 or share.is_empty:
            return 0.0
        return float(shapely.distance(shapely.Point(self.start), share))

    def batch_values(
        self,
        task: AreaTask,
        polys: np.ndarray,
        others: Sequence[BaseGeometry],
        inside_known: bool = False,
    ) -> np.ndarray:
        """g for many candidate polygons at once (shapely's vectorised ops); invalid → −inf.
        ``inside_known``: the candidates lie in T0 already (clipped), so ill(S) is taken on them
        as they are rather than on their intersection with T0 (the same value)."""
        out = np.full(len(polys), -np.inf)
        ok = shapely.is_valid(polys) & (shapely.area(polys) > 0)
        if not ok.any():
            return out
        p = polys[ok]
        area = shapely.area(p)
        inside = shapely.area(shapely.intersection(p, task.t0))
        val = self.w_dim * (inside if self.value_inside else area) - self.w_out * (area - inside)
        for o in others:
            if not o.is_empty:
                val -= self.w_overlap * shapely.area(shapely.intersection(p, o))
        if inside_known or not self.value_inside:
            val -= self.w_ill * shapely.length(p) / area
        elif self.w_ill:
            # the sub-task is its part in T0 (value_inside): a bulge outside T0 must not make a
            # claim look rounder; a claim with nothing inside is worth nothing anyway
            shape = shapely.intersection(p, task.t0)
            shape_area = shapely.area(shape)
            ill = np.where(shape_area > 0, shapely.length(shape) / np.maximum(shape_area, 1e-300), 0.0)
            val -= self.w_ill * ill
        if self.forbidden is not None:
            val -= self.w_forbidden * shapely.area(shapely.intersection(p, self.forbidden))
        if self.start is not None and self.w_dist:
            val -= self.w_dist * shapely.distance(shapely.Point(self.start), p)
        out[ok] = val
        return out


@dataclass(frozen=True)
class TargetReward:
    """g_i(S) = w_dim·dim(S) − w_overlap·Σ_j dim(S ∩ S_j) − w_path·path(S) − w_forbidden·|S ∩ F|.

    §4.2 uses w_dim = w_overlap = 1, w_path = 0; §5.1 adds the shortest path p(S) from the
    robot's start. ``forbidden`` holds indices of targets this robot must not take.
    """

    start: tuple[float, float] = (0.5, 0.0)
    w_dim: float = 1.0
    w_overlap: float = 1.0
    w_path: float = 0.0
    forbidden: frozenset[int] = field(default_factory=frozenset)
    w_forbidden: float = 1000.0

    def constraint_violation(self, share: frozenset[int]) -> float:
        return float(len(share & self.forbidden))

    def value(self, task: TargetTask, share: frozenset[int], others: Sequence[frozenset[int]]) -> float:
        from .optimal import route_length  # local: optimal imports nothing from here

        val = self.w_dim * task.dim(share) - self.w_overlap * sum(task.dim(share & o) for o in others)
        if self.w_path and share:
            val -= self.w_path * route_length(self.start, task.points[sorted(share)])
        return val - self.w_forbidden * self.constraint_violation(share)


def global_coverage(task: AreaTask | TargetTask, shares: Sequence) -> float:
    """G = Σ_r g(S_r) − Σ_{i<j} g(S_i ∩ S_j) with g = dim of the part inside T0 (§2)."""
    inside = [task.inside(s) for s in shares]
    total = sum(task.dim(s) for s in inside)
    return total - sum(task.dim(task.overlap(a, b)) for a, b in combinations(inside, 2))
