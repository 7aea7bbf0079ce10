"""Negotiated search subareas for a heterogeneous team (``ost negotiate partition``).

The OST grid is split among robots that move at different speeds (robot i moves one cell every
``period`` steps) by Rossi et al.'s area negotiation, instead of the paper's equal m×n
partition. Steps:

1. The grid rectangle, scaled uniformly so that its longer side is 1 (cell (x, y) is the square
   [x, x+1]×[y, y+1] / L, L = max(W, H)), is the ``AreaTask``.
2. Each robot gets a target share proportional to its speed 1/period. That preference is private:
   it sets the robot's discount factor (its patience, see ``patience_discounts``), or, with
   ``rule="reward"``, a size term in its reward. Its forbidden zones go into its own reward
   (``SearchReward``, an ``AreaReward``) only. ``negotiate`` runs the rounds strategy with the
   exit option.
3. Rasterise: a cell goes to the robot whose polygon holds the cell centre. Cells nobody got,
   cells two got and cells in the receiver's forbidden zone are settled by ``resolve``.
4. Each robot sweeps its cells (``region_sweep``: one pass per 3 rows, as ``ost_ros.search``),
   at one cell per ``period`` steps (the OST's clock, ``search_time``); the team's search time is
   the slowest robot's. The paper's equal partition (``ost_ros.partition``) is timed the same way.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import box

from ost_ros.messages import Cell

from .agents import AgentSpec
from .errors import NegotiationError
from .multiparty import NegotiationResult, negotiate
from .proposals import AreaSearch
from .rewards import AreaReward
from .tasks import AreaTask

Rect = tuple[int, int, int, int]  # x0, y0, x1, y1 in cells, inclusive

RULES = ("patience", "reward")
TEAM_KEYS = ("grid", "robots", "delta", "seed", "max_rounds", "rule")
ROBOT_KEYS = ("id", "period", "forbidden")
GRID_KEYS = ("width", "height")


# ------------------------------------------------------------------ the team --------------------
@dataclass(frozen=True)
class SearchRobot:
    """One robot: moves one cell every ``period`` steps; never searches its forbidden cells."""

    id: int
    period: int = 1
    forbidden: tuple[Rect, ...] = ()

    @property
    def speed(self) -> float:
        return 1.0 / self.period


@dataclass(frozen=True)
class SearchTeam:
    """The grid, the robots (negotiation order = list order) and the negotiation settings.

    delta: the fastest robot's discount factor (the others' follow from their speed, see
    ``patience_discounts``); rule: where the speed preference lives (``patience`` or ``reward``).
    """

    width: int
    height: int
    robots: tuple[SearchRobot, ...]
    delta: float = 0.95
    seed: int = 0
    max_rounds: int = 200
    rule: str = "patience"

    def __post_init__(self) -> None:
        _check_int(self.width, "grid width", 1)
        _check_int(self.height, "grid height", 1)
        if not self.robots:
            raise NegotiationError("need at least one robot")
        if len(self.robots) > self.width * self.height:
            raise NegotiationError(
                f"{len(self.robots)} robots for a {self.width}x{self.height} grid: more robots than cells"
            )
        ids = [r.id for r in self.robots]
        if len(set(ids)) != len(ids):
            raise NegotiationError(f"robot ids must be unique, got {ids}")
        for r in self.robots:
            _check_int(r.id, "robot id", 0)
            _check_int(r.period, f"robot {r.id}: period", 1)
            for k, z in enumerate(r.forbidden):
                _check_rect(z, f"robot {r.id}: forbidden[{k}]", self.width, self.height)
        if not 0.0 < self.delta < 1.0:
            raise NegotiationError(f"delta must be in (0, 1), got {self.delta:g}")
        _check_int(self.seed, "seed", 0)
        _check_int(self.max_rounds, "max_rounds", 1)
        if self.rule not in RULES:
            raise NegotiationError(f"unknown rule {self.rule!r} (expected one of {', '.join(RULES)})")

    @property
    def scale(self) -> float:
        """Length of one cell in task units: the grid's longer side is 1."""
        return 1.0 / max(self.width, self.height)

    def speed_shares(self) -> np.ndarray:
        """Target fraction of the grid per robot, proportional to speed (equal sweep times)."""
        s = np.array([r.speed for r in self.robots])
        return s / s.sum()

    def allowed(self) -> np.ndarray:
        """(R, H, W) bool: robot i may be given cell (x, y) iff allowed[i, y, x]."""
        ok = np.ones((len(self.robots), self.height, self.width), dtype=bool)
        for i, r in enumerate(self.robots):
            for x0, y0, x1, y1 in r.forbidden:
                ok[i, y0 : y1 + 1, x0 : x1 + 1] = False
        return ok

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> SearchTeam:
        """Build from the YAML/flag dict: ``grid: {width, height}``, ``robots:`` (a count or a
        list of ``{id, period, forbidden}``), ``delta``, ``seed``, ``max_rounds``, ``rule``."""
        from ost_ros.validate import FieldError, integer, listing, mapping

        try:
            mapping(spec, "team", TEAM_KEYS)
            grid = mapping(spec.get("grid", {}), "grid", GRID_KEYS)
            width = integer(grid.get("width", 100), "grid.width", 1)
            height = integer(grid.get("height", 40), "grid.height", 1)
            raw = spec.get("robots", 4)
            if isinstance(raw, list):
                entries = raw
            else:
                entries = [{} for _ in range(integer(raw, "robots", 1))]
            if not entries:
                raise FieldError("robots: need at least one robot, got an empty list")
            robots = []
            for i, e in enumerate(entries):
                where = f"robots[{i}]"
                mapping(e, where, ROBOT_KEYS)
                zones: list[tuple[int, int, int, int]] = []
                for k, z in enumerate(listing(e.get("forbidden", []), f"{where}.forbidden")):
                    if not isinstance(z, (list, tuple)) or len(z) != 4:
                        raise FieldError(f"{where}.forbidden[{k}]: expected [x0, y0, x1, y1], got {z!r}")
                    x0, y0, x1, y1 = (integer(v, f"{where}.forbidden[{k}]", 0) for v in z)
                    zones.append((x0, y0, x1, y1))
                robots.append(
                    SearchRobot(
                        integer(e.get("id", i), f"{where}.id", 0),
                        integer(e.get("period", 1), f"{where}.period", 1),
                        tuple(zones),
                    )
                )
            delta = spec.get("delta", 0.95)
            if isinstance(delta, bool) or not isinstance(delta, (int, float)):
                raise FieldError(f"delta: expected a number, got {delta!r}")
            return cls(
                width,
                height,
                tuple(robots),
                float(delta),
                integer(spec.get("seed", 0), "seed", 0),
                integer(spec.get("max_rounds", 200), "max_rounds", 1),
                str(spec.get("rule", "patience")),
            )
        except FieldError as exc:
            raise NegotiationError(str(exc)) from None


def apply_flags(
    spec: dict[str, Any],
    *,
    width: int | None = None,
    height: int | None = None,
    robots: int | None = None,
    periods: str | None = None,
    delta: float | None = None,
    seed: int | None = None,
    max_rounds: int | None = None,
    rule: str | None = None,
) -> dict[str, Any]:
    """The team file's dict with command-line flags laid over it (None = flag not given).

    ``periods`` ("1,2,1") sets every robot's period; with a robot list in the file its length
    must match, as must ``robots``. Without a list, the team has ``robots`` robots (else as many
    as ``periods`` name, else the file's count, else 4)."""
    out = dict(spec)
    if width is not None or height is not None:
        grid = out.get("grid", {})
        if isinstance(grid, dict):
            grid = dict(grid)
            grid.update({k: v for k, v in (("width", width), ("height", height)) if v is not None})
            out["grid"] = grid
    plist: list[int] | None = None
    if periods is not None:
        try:
            plist = [int(p) for p in periods.split(",")]
        except ValueError:
            raise NegotiationError(
                f"--periods must be integers separated by commas, got {periods!r}"
            ) from None
    entries = out.get("robots")
    if isinstance(entries, list):
        if robots is not None and robots != len(entries):
            raise NegotiationError(
                f"--robots {robots} does not match the {len(entries)} robots in the team file"
            )
        if plist is not None:
            if len(plist) != len(entries):
                raise NegotiationError(
                    f"got {len(plist)} periods for the {len(entries)} robots in the team file"
                )
            out["robots"] = [dict(e, period=p) if isinstance(e, dict) else e for e, p in zip(entries, plist)]
    else:
        n = robots if robots is not None else len(plist) if plist is not None else entries
        if n is None:
            n = 4
        if plist is not None:
            if isinstance(n, int) and not isinstance(n, bool) and n != len(plist):
                raise NegotiationError(f"got {len(plist)} periods for {n} robots")
            out["robots"] = [{"period": p} for p in plist]
        else:
            out["robots"] = n
    for key, value in (("delta", delta), ("seed", seed), ("max_rounds", max_rounds), ("rule", rule)):
        if value is not None:
            out[key] = value
    return out


def _check_int(v: Any, what: str, minimum: int) -> None:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < minimum:
        raise NegotiationError(f"{what} must be an integer ≥ {minimum}, got {v!r}")


def _check_rect(z: Sequence[int], what: str, width: int, height: int) -> None:
    if len(z) != 4 or any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in z):
        raise NegotiationError(f"{what}: expected four integers [x0, y0, x1, y1], got {list(z)!r}")
    x0, y0, x1, y1 = z
    if not (0 <= x0 <= x1 < width and 0 <= y0 <= y1 < height):
        raise NegotiationError(
            f"{what}: [{x0}, {y0}, {x1}, {y1}] must satisfy 0 ≤ x0 ≤ x1 < {width} and 0 ≤ y0 ≤ y1 < {height}"
        )


# ------------------------------------------------------------------ negotiation set-up ----------
@dataclass(frozen=True)
class SearchReward(AreaReward):
    """AreaReward (w_ill = 0) plus two private terms for a robot that has to sweep its share.

    * waste: −w_rect·(swept − area), swept being the area a boustrophedon over the share's
      bounding box covers: ⌈box height / 3 cells⌉ passes, each the box's width long and 3 cells
      high, plus the walks between passes. It prices what the sweep walks for nothing (ragged
      edges, L shapes, a height that is not a multiple of 3 rows) and so favours axis-parallel
      strips, which also tile the grid without gaps.
    * size (only with a ``target``, ``rule="reward"``): −w_size·|area inside T0 − target|. With
      w_size = 3 the share is worth most at the target and no overlap saving (2 per unit) makes
      a smaller claim pay.
    """

    cell: float = 0.0  # one cell's side in task units (0: no banding, plain box)
    w_rect: float = 0.5
    target: float | None = None
    w_size: float = 3.0
    w_ill: float = 0.0  # see negotiation_setup

    def swept(self, bounds: np.ndarray) -> np.ndarray:
        """Swept area of the bounding boxes (rows: minx, miny, maxx, maxy)."""
        w, h = bounds[:, 2] - bounds[:, 0], bounds[:, 3] - bounds[:, 1]
        if self.cell <= 0:
            return w * h
        c = self.cell
        passes = np.ceil(h / (3 * c) - 1e-6)
        return 3 * c * (passes * w + 3 * c * np.maximum(passes - 1, 0))

    def terms(self, task: AreaTask, share, others) -> dict[str, float]:
        t = super().terms(task, share, others)
        t["waste"] = (
            0.0
            if share.is_empty
            else max(0.0, float(self.swept(np.array([share.bounds]))[0]) - float(share.area))
        )
        t["size"] = 0.0 if self.target is None else abs(task.dim(task.inside(share)) - self.target)
        return t

    def value(self, task: AreaTask, share, others) -> float:
        t = self.terms(task, share, others)
        return super().value(task, share, others) - self.w_rect * t["waste"] - self.w_size * t["size"]

    def batch_values(
        self, task: AreaTask, polys: np.ndarray, others, inside_known: bool = False
    ) -> np.ndarray:
        out = super().batch_values(task, polys, others, inside_known)
        ok = np.isfinite(out)
        if ok.any():
            p = polys[ok]
            out[ok] -= self.w_rect * np.maximum(0.0, self.swept(shapely.bounds(p)) - shapely.area(p))
            if self.target is not None:
                out[ok] -= self.w_size * np.abs(shapely.area(shapely.intersection(p, task.t0)) - self.target)
        return out


def patience_discounts(shares: np.ndarray, delta_max: float) -> np.ndarray:
    """δ_i = t_i^(1/K), K = ln t_max / ln δ_max: claims δ_i^k (Eq. 1) all reach their target
    t_i in the same round K, and stay in proportion t_i^(k/K) on the way, so the claims stop
    colliding at about speed-proportional sizes. The fastest robot has δ_max; equal speeds give
    everyone δ_max. A lone robot keeps δ_max (nothing to share)."""
    shares = np.asarray(shares, dtype=float)
    t_max = float(shares.max())
    if t_max >= 1.0 - 1e-12:
        return np.full(len(shares), delta_max)
    k = math.log(t_max) / math.log(delta_max)
    return np.clip(shares ** (1.0 / k), 1e-6, delta_max)


def forbidden_polygon(zones: Sequence[Rect], scale: float):
    """A robot's forbidden cells as one geometry in task units (None if it has none)."""
    if not zones:
        return None
    return shapely.union_all(
        [box(x0 * scale, y0 * scale, (x1 + 1) * scale, (y1 + 1) * scale) for x0, y0, x1, y1 in zones]
    )


@dataclass(frozen=True)
class NegotiationSetup:
    """What goes into ``negotiate``: the task, one AgentSpec per robot (its δ and its private
    reward, holding only its own forbidden zones), and the proposal-search settings."""

    task: AreaTask
    agents: tuple[AgentSpec, ...]
    search: AreaSearch
    targets: tuple[float, ...]  # fraction of the grid per robot


def negotiation_setup(team: SearchTeam) -> NegotiationSetup:
    """Task and agents for the team.

    patience (default): δ_i from ``patience_discounts``, strict size rule (min_scale = 1).
    reward: everyone has δ_max; the reward's size term aims at (t_i / t_max)·dim T0 and the search
    may undercut the δ cap down to half of it, so claims fall quickly to sizes in speed proportion
    and then shrink together. Both use ``SearchReward`` with w_ill = 0: the ill-shape term favours
    round claims, which cannot tile a rectangle, and the gaps they leave are taken by the robot
    that exits next to them (docs/negotiation.md has the measurements).
    """
    s = team.scale
    task = AreaTask(box(0.0, 0.0, team.width * s, team.height * s))
    shares = team.speed_shares()
    if team.rule == "patience":
        deltas = patience_discounts(shares, team.delta)
        search = AreaSearch()
    else:
        deltas = np.full(len(shares), team.delta)
        search = AreaSearch(min_scale=0.5)
    agents = []
    for r, d, t in zip(team.robots, deltas, shares):
        zone = forbidden_polygon(r.forbidden, s)  # private: only this robot's reward holds it
        target = None if team.rule == "patience" else float(t / shares.max()) * task.size
        reward = SearchReward(forbidden=zone, cell=s, target=target)
        agents.append(AgentSpec(float(d), reward, name=f"robot {r.id}"))
    return NegotiationSetup(task, tuple(agents), search, tuple(float(t) for t in shares))


# ------------------------------------------------------------------ rasterisation ---------------
def rasterise(shares: Sequence, width: int, height: int, scale: float) -> np.ndarray:
    """(R, H, W) bool: claims[i, y, x] iff robot i's share holds the centre of cell (x, y)."""
    xs, ys = np.meshgrid((np.arange(width) + 0.5) * scale, (np.arange(height) + 0.5) * scale)
    out = np.zeros((len(shares), height, width), dtype=bool)
    for i, share in enumerate(shares):
        if share is not None and not share.is_empty:
            out[i] = shapely.contains_xy(share, xs, ys)
    return out


@dataclass(frozen=True)
class Resolution:
    """The final owner map and how many cells each rule settled."""

    owner: np.ndarray  # (H, W) robot index (list order)
    fragments: int  # claimed cells cut off from their claimant's main piece, released
    unclaimed: int  # no polygon held the centre
    contested: int  # two or more polygons did
    forbidden: int  # the only claimant may not take it


def resolve(claims: np.ndarray, allowed: np.ndarray, periods: Sequence[int]) -> Resolution:
    """Every cell to exactly one allowed robot.

    First, a claim's cells not 4-connected to its largest piece are released: a share is one
    polygon, and a piece that the rasterisation cut off (a neck thinner than a cell) would only
    stretch the robot's sweep over more rows. Then a cell claimed by one allowed robot is its.
    Otherwise, in row-major order, a contested cell goes to the allowed claimant with the least
    expected search time (load = period × cells so far, a sweep being about cells / 3 moves; ties
    to the lower index). What is left grows
    from its owned 4-neighbours in waves (neighbours as at the start of the wave, so no direction
    is favoured): to the allowed neighbour owner with the least load. A cell no allowed robot
    borders goes to the allowed robot with the least load.
    """
    r_n, h, w = claims.shape
    if not allowed.any(axis=0).all():
        y, x = np.argwhere(~allowed.any(axis=0))[0]
        raise NegotiationError(f"cell ({x}, {y}) is forbidden to every robot")
    period = np.asarray(periods, dtype=float)
    claims = claims.copy()
    fragments = 0
    for i in range(r_n):
        labels, n = ndimage.label(claims[i])  # default structure: 4-connectivity
        if n > 1:
            sizes = np.bincount(labels.ravel(), minlength=n + 1)[1:]
            keep = labels == 1 + int(np.argmax(sizes))  # largest; ties to the first in row-major order
            fragments += int((claims[i] & ~keep).sum())
            claims[i] = keep
    n_claims = claims.sum(axis=0)
    mine = claims & allowed
    owner = np.where((n_claims == 1) & mine.any(axis=0), np.argmax(claims, axis=0), -1)
    load = period * np.bincount(owner[owner >= 0], minlength=r_n)

    def take(y: int, x: int, cands: np.ndarray) -> None:
        k = int(cands[np.argmin(load[cands])])  # argmin: first (lowest index) on ties
        owner[y, x] = k
        load[k] += period[k]

    contested = forbidden = 0
    for y, x in np.argwhere(owner < 0):
        if n_claims[y, x] >= 2:
            contested += 1
            cands = np.flatnonzero(mine[:, y, x])
            if len(cands):
                take(y, x, cands)
        elif n_claims[y, x] == 1:
            forbidden += 1
    unclaimed = int((n_claims == 0).sum())  # released fragments included
    while (owner < 0).any():
        snap = owner.copy()
        progress = False
        for y, x in np.argwhere(snap < 0):
            near = {
                snap[y + dy, x + dx]
                for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1))
                if 0 <= y + dy < h and 0 <= x + dx < w and snap[y + dy, x + dx] >= 0
            }
            cands = np.array(sorted(k for k in near if allowed[k, y, x]), dtype=int)
            if len(cands):
                take(y, x, cands)
                progress = True
        if not progress:
            # enclosed by robots that may not have it: any allowed robot, least loaded
            y, x = np.argwhere(owner < 0)[0]
            take(y, x, np.flatnonzero(allowed[:, y, x]))
    return Resolution(owner, fragments, unclaimed, contested, forbidden)


# ------------------------------------------------------------------ sweeping --------------------
def region_sweep(mask: np.ndarray) -> list[Cell]:
    """Waypoints of a boustrophedon over a region (mask[y, x]), as ``ost_ros.search`` sweeps a
    rectangle: bands of 3 rows; in each band one pass along its middle row (clamped into the
    region's first..last row) from the band's leftmost to its rightmost region cell, in
    alternating direction; bands without region cells are skipped. Passes may cross other
    robots' cells; travel between passes is a Manhattan walk.

    The bands may start at the region's first row or one or two rows above it, and the first
    pass may run either way: the shortest of these 6 sweeps is taken (ties: first row, left→right
    first). For a rectangle that is exactly ``ost_ros.search.sweep_waypoints``."""
    rows = np.flatnonzero(mask.any(axis=1))
    if len(rows) == 0:
        return []
    y_first, y_last = int(rows[0]), int(rows[-1])
    best: list[Cell] | None = None
    for offset in (0, 1, 2):
        bands = []
        for top in range(y_first - offset, y_last + 1, 3):
            cols = np.flatnonzero(mask[max(top, 0) : top + 3].any(axis=0))
            if len(cols):
                bands.append((min(max(top + 1, y_first), y_last), int(cols[0]), int(cols[-1])))
        for flip in (0, 1):
            points: list[Cell] = []
            for k, (y, a, b) in enumerate(bands):
                if (k + flip) % 2:
                    a, b = b, a
                points += [(a, y), (b, y)]
            if best is None or sweep_length(points) < sweep_length(best):
                best = points
    return best or []


def sweep_length(points: Sequence[Cell]) -> int:
    """Moves needed to follow the waypoints (one cell per move)."""
    return int(sum(abs(a[0] - b[0]) + abs(a[1] - b[1]) for a, b in zip(points, points[1:])))


def search_time(moves: int, period: int) -> int:
    """Steps a robot of this period needs for ``moves`` moves from step 0, on the OST's clock
    (``ost_ros.model.arrival``: it moves in steps t with t mod period = 0, a move of step s ends
    at s + 1): (moves − 1)·period + 1, i.e. moves × period less the wait after the last move."""
    from ost_ros.model import arrival

    return int(arrival(0, moves, period))


def sweep_path(points: Sequence[Cell]) -> list[Cell]:
    """Every cell visited along the waypoints (x first, then y, as ``ost_ros.motion``)."""
    from ost_ros.search import route

    return route(list(points)) if points else []


# ------------------------------------------------------------------ the whole job ---------------
@dataclass(frozen=True)
class RobotOutcome:
    """One robot's line of the table."""

    id: int
    period: int
    target: float  # speed-proportional fraction of the grid
    cells: int
    moves: int  # sweep length
    search_time: int  # steps to sweep, ``search_time(moves, period)``
    equal_cells: int
    equal_search_time: int
    equal_violations: int  # cells of its forbidden zones inside its equal rectangle

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass
class PartitionResult:
    """Negotiated vs equal partition of one team."""

    team: SearchTeam
    setup: NegotiationSetup
    negotiation: NegotiationResult
    resolution: Resolution
    equal_owner: np.ndarray
    equal_partition: tuple[int, int]
    robots: list[RobotOutcome]
    elapsed_s: float = 0.0
    routes: list[list[Cell]] = field(default_factory=list)

    @property
    def owner(self) -> np.ndarray:
        return self.resolution.owner

    @property
    def team_time(self) -> int:
        return max(r.search_time for r in self.robots)

    @property
    def equal_team_time(self) -> int:
        return max(r.equal_search_time for r in self.robots)

    def to_dict(self) -> dict[str, Any]:
        t = self.team
        return {
            "grid": {"width": t.width, "height": t.height},
            "scale": t.scale,
            "rule": t.rule,
            "delta": t.delta,
            "seed": t.seed,
            "discounts": [a.delta for a in self.setup.agents],
            "status": self.negotiation.status,
            "rounds": self.negotiation.rounds,
            "messages": self.negotiation.messages,
            "resolved": {
                "fragments": self.resolution.fragments,
                "unclaimed": self.resolution.unclaimed,
                "contested": self.resolution.contested,
                "forbidden": self.resolution.forbidden,
            },
            "equal_partition": list(self.equal_partition),
            "robots": [r.to_dict() for r in self.robots],
            "team_search_time": {"negotiated": self.team_time, "equal": self.equal_team_time},
            "equal_violations": sum(r.equal_violations for r in self.robots),
            "elapsed_s": round(self.elapsed_s, 3),
        }

    def table(self) -> str:
        """The text report."""
        t, n = self.team, self.negotiation
        z = self.resolution
        lines = [
            f"{t.width}x{t.height} grid, {len(t.robots)} robots, rule {t.rule}, δ_max {t.delta:g}, "
            f"seed {t.seed}: {n.status} after {n.rounds} rounds, {n.messages} messages, "
            f"{self.elapsed_s:.2f} s",
            f"resolved cells: {z.fragments} cut off from their claim, {z.unclaimed} unclaimed, "
            f"{z.contested} contested, {z.forbidden} forbidden to their claimant",
            "",
            f"{'robot':>5} {'period':>6} {'target %':>8} {'cells':>6} {'time':>6} │ "
            f"{'equal cells':>11} {'equal time':>10} {'violations':>10}",
        ]
        for r in self.robots:
            lines.append(
                f"{r.id:>5} {r.period:>6} {100 * r.target:>8.1f} {r.cells:>6} {r.search_time:>6} │ "
                f"{r.equal_cells:>11} {r.equal_search_time:>10} {r.equal_violations:>10}"
            )
        gain = 100.0 * (1 - self.team_time / self.equal_team_time) if self.equal_team_time else 0.0
        m, k = self.equal_partition
        lines += [
            "",
            f"team search time: negotiated {self.team_time}, equal ({m}x{k}) {self.equal_team_time} "
            f"({gain:+.1f} % saved)",
        ]
        viol = sum(r.equal_violations for r in self.robots)
        if viol:
            lines.append(f"the equal partition gives {viol} forbidden cell(s) to their robot")
        return "\n".join(lines)

    def plot(self, path: str | Path) -> None:
        plot_partition(self, path)


def equal_owner_map(team: SearchTeam) -> tuple[np.ndarray, tuple[int, int]]:
    """The paper's equal partition (``ost_ros.partition``): robot k gets rectangle k."""
    from ost_ros.model import Grid
    from ost_ros.partition import choose_partition, subareas

    grid = Grid(team.width, team.height)
    try:
        part = choose_partition(len(team.robots), grid)
        rects = subareas(grid, part)
    except ValueError as exc:
        raise NegotiationError(f"equal partition: {exc}") from None
    owner = np.full((team.height, team.width), -1, dtype=int)
    for k, a in enumerate(rects):
        owner[a.y0 : a.y0 + a.height, a.x0 : a.x0 + a.width] = k
    return owner, part


def negotiate_partition(team: SearchTeam, search: AreaSearch | None = None) -> PartitionResult:
    """Negotiate, rasterise, resolve and time the sweeps; also time the equal partition.
    ``search`` overrides the rule's proposal-search settings (tests use a cheaper one)."""
    t0 = time.perf_counter()
    allowed = team.allowed()
    if not allowed.any(axis=0).all():  # fail before the (slow) negotiation
        y, x = np.argwhere(~allowed.any(axis=0))[0]
        raise NegotiationError(f"cell ({x}, {y}) is forbidden to every robot")
    equal, part = equal_owner_map(team)
    setup = negotiation_setup(team)
    res = negotiate(
        setup.task,
        list(setup.agents),
        strategy="rounds",
        seed=team.seed,
        max_rounds=team.max_rounds,
        search=search or setup.search,
        trace=False,
        stopping="overlap",  # every cell must get an owner: the clipped, low-overlap rule
    )
    cells = rasterise(res.shares, team.width, team.height, team.scale)
    resolution = resolve(cells, allowed, [r.period for r in team.robots])
    robots, routes = [], []
    for i, r in enumerate(team.robots):
        pts = region_sweep(resolution.owner == i)
        moves, eq_moves = sweep_length(pts), sweep_length(region_sweep(equal == i))
        routes.append(pts)
        robots.append(
            RobotOutcome(
                r.id,
                r.period,
                setup.targets[i],
                int((resolution.owner == i).sum()),
                moves,
                search_time(moves, r.period),
                int((equal == i).sum()),
                search_time(eq_moves, r.period),
                int(((equal == i) & ~allowed[i]).sum()),
            )
        )
    return PartitionResult(
        team, setup, res, resolution, equal, part, robots, time.perf_counter() - t0, routes
    )


# ------------------------------------------------------------------ plot ------------------------
def plot_partition(result: PartitionResult, path: str | Path) -> None:
    """Two maps, negotiated and equal: cell ownership in one colour per robot, each robot's
    forbidden zones hatched in its colour, its sweep drawn on the negotiated map."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch, Rectangle

    team = result.team
    n = len(team.robots)
    colours = [plt.get_cmap("tab20" if n > 10 else "tab10")(i % 20) for i in range(n)]
    cmap = ListedColormap(colours)
    aspect = team.height / team.width
    fig, axes = plt.subplots(2, 1, figsize=(10, max(3.0, 2 * 10 * aspect + 1.6)))
    panels = [
        (axes[0], result.owner, f"negotiated: team search time {result.team_time}"),
        (
            axes[1],
            result.equal_owner,
            f"equal {result.equal_partition[0]}x{result.equal_partition[1]}: "
            f"team search time {result.equal_team_time}",
        ),
    ]
    for ax, owner, title in panels:
        ax.imshow(
            owner,
            cmap=cmap,
            vmin=-0.5,
            vmax=n - 0.5,
            origin="upper",
            interpolation="nearest",
            extent=(-0.5, team.width - 0.5, team.height - 0.5, -0.5),
            alpha=0.75,
        )
        for i, r in enumerate(team.robots):
            for x0, y0, x1, y1 in r.forbidden:
                ax.add_patch(
                    Rectangle(
                        (x0 - 0.5, y0 - 0.5),
                        x1 - x0 + 1,
                        y1 - y0 + 1,
                        fill=False,
                        hatch="///",
                        ec=colours[i],
                        lw=1.2,
                    )
                )
        ax.set_xlim(-0.5, team.width - 0.5)
        ax.set_ylim(team.height - 0.5, -0.5)  # rows grow downward, as the sweep's
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=10)
    for pts in result.routes:
        if pts:
            xy = np.array(sweep_path(pts))
            axes[0].plot(xy[:, 0], xy[:, 1], color="k", lw=0.5, alpha=0.6)
    handles = [
        Patch(color=colours[i], label=f"r{r.id} (period {r.period})") for i, r in enumerate(team.robots)
    ]
    if any(r.forbidden for r in team.robots):
        handles.append(Patch(fill=False, hatch="///", label="forbidden (robot's colour)"))
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 6), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------ into an OST scenario -------
def team_of(
    scenario, *, delta: float = 0.95, seed: int = 0, max_rounds: int = 200, rule: str = "patience"
) -> SearchTeam:
    """The negotiation team of an OST scenario: its grid, its robots (periods, forbidden zones)."""
    robots = tuple(SearchRobot(a.id, a.period, tuple(a.forbidden)) for a in scenario.agents)
    return SearchTeam(scenario.grid.width, scenario.grid.height, robots, delta, seed, max_rounds, rule)


def negotiated_scenario(
    scenario,
    *,
    delta: float = 0.95,
    seed: int = 0,
    max_rounds: int = 200,
    rule: str = "patience",
    search: AreaSearch | None = None,
):
    """The scenario with every robot sweeping its negotiated region instead of its equal
    subarea (``AgentSpec.sweep``); a robot based at its subarea's sweep start (the default) is
    based at its region's sweep start instead. Returns (scenario, PartitionResult)."""
    from dataclasses import replace

    from ost_ros.scenario import build_scenario

    result = negotiate_partition(
        team_of(scenario, delta=delta, seed=seed, max_rounds=max_rounds, rule=rule), search
    )
    agents = []
    for k, a in enumerate(scenario.agents):
        pts = tuple(tuple(int(v) for v in p) for p in result.routes[k]) or (a.base,)
        base = pts[0] if a.base == scenario.subareas[k].start else a.base
        agents.append(replace(a, sweep=pts, base=base))
    out = build_scenario(
        scenario.grid, list(scenario.objects), partition=scenario.partition, agents=agents, nmax=scenario.nmax
    )
    return out, result
