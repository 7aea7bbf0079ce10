"""Exhaustive subarea search (paper §5.1): a row-major boustrophedon sweep, and the search module.

The sensor covers the 3×3 block around the agent, so one pass along row y0+1 clears rows
y0..y0+2. Passes run every 3 rows, alternating direction (left→right first); the last pass is
clamped to the subarea's last row. An agent whose base is not its sweep start first walks there
(sensing on the way).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from ost_ros.model import Cell, Subarea, manhattan
from ost_ros.motion import step_toward


def sweep_waypoints(area: Subarea) -> list[Cell]:
    """Corner cells of the boustrophedon, starting at the subarea's (0, 1) cell."""
    left, right = area.x0, area.x0 + area.width - 1
    last_row = area.y0 + area.height - 1
    passes = -(-area.height // 3)  # ceil: one pass per 3 rows
    points: list[Cell] = []
    for k in range(passes):
        y = min(area.y0 + 1 + 3 * k, last_row)
        a, b = (left, right) if k % 2 == 0 else (right, left)
        points.append((a, y))
        points.append((b, y))
    return points


def route(waypoints: list[Cell]) -> list[Cell]:
    """Expand waypoints into the cell-by-cell path (x first, then y, between waypoints)."""
    path = [waypoints[0]]
    for target in waypoints[1:]:
        cur = path[-1]
        while cur != target:
            dx, dy = step_toward(cur, target)
            cur = (cur[0] + dx, cur[1] + dy)
            path.append(cur)
    return path


def sweep_plan(area: Subarea, base: Cell) -> list[Cell]:
    """Waypoints of an agent's whole search: from its base to the sweep start, then the sweep."""
    points = sweep_waypoints(area)
    return ([base] + points) if base != points[0] else points


def agent_plan(area: Subarea, base: Cell, sweep: tuple[Cell, ...] = ()) -> list[Cell]:
    """An agent's search waypoints: its own ``sweep`` if it has one (a negotiated partition),
    else its subarea's boustrophedon — from its base either way."""
    if not sweep:
        return sweep_plan(area, base)
    points: list[Cell] = [(c[0], c[1]) for c in sweep]
    return ([base] + points) if base != points[0] else points


def plan_length(waypoints: list[Cell]) -> int:
    """Number of steps needed to follow the waypoints (the time the search ends)."""
    return sum(manhattan(a, b) for a, b in zip(waypoints, waypoints[1:]))


@dataclass(frozen=True)
class SweepSummary:
    """What every agent knows about a peer's search without hearing from it: when it ends, where."""

    length: int
    end: Cell

    @classmethod
    def of(cls, area: Subarea, base: Cell, sweep: tuple[Cell, ...] = ()) -> SweepSummary:
        points = agent_plan(area, base, sweep)
        return cls(plan_length(points), points[-1])


class SearchState(str, Enum):
    SWEEPING = "SWEEPING"
    DONE = "DONE"


@dataclass
class SearchModule:
    """The search module FSA: SWEEPING → DONE. Follows the sweep path one cell per step."""

    path: list[Cell]
    index: int = 0
    state: SearchState = SearchState.SWEEPING

    @classmethod
    def for_area(cls, area: Subarea, base: Cell) -> SearchModule:
        return cls(route(sweep_plan(area, base)))

    @property
    def length(self) -> int:
        return len(self.path) - 1

    def at_end(self, position: Cell) -> bool:
        return self.index >= len(self.path) - 1 and position == self.path[-1]

    def next_cell(self, position: Cell) -> Cell:
        """Where to go next; advances along the path once the agent stands on its current cell."""
        if self.index < len(self.path) - 1 and position == self.path[self.index]:
            self.index += 1
        return self.path[self.index]
