"""The Object-Sorting Task model (paper §2.1, §5.1): grid, objects, agents, scenario.

Coordinates are cells ``(x, y)`` with ``0 <= x < width`` and ``0 <= y < height``; agents move
4-connected, one cell per time step, and several agents may share a cell.

Heterogeneous teams: an agent may have a ``period`` k ≥ 1 — it moves only at steps t with
t mod k = 0 (one cell every k steps; k = 1 is the paper's robot). A group carries an object at
the steps all its members can move (t mod lcm of their periods = 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ost_ros.messages import Cell, ObjectInfo

DEFAULT_WIDTH = 500
DEFAULT_HEIGHT = 200
DEFAULT_NMAX = 10


def manhattan(a: Cell, b: Cell) -> int:
    """Length of a shortest 4-connected path between two cells."""
    return abs(a[0] - b[0]) + abs(a[1] - b[1])


def can_move(t: int, period: int) -> bool:
    """Whether an agent (or group) of this period may move in step t."""
    return t % period == 0


def arrival(t0: int, d: int, period: int = 1) -> int:
    """When d moves started at step t0 (or later) are done: the first movable step s ≥ t0, then
    one move every ``period`` steps; a move in step s ends at s + 1. d = 0: t0."""
    if d <= 0:
        return t0
    first = -(-t0 // period) * period
    return first + (d - 1) * period + 1


def arrival_np(t0: np.ndarray, d: np.ndarray, period: np.ndarray | int = 1) -> np.ndarray:
    """:func:`arrival` elementwise (int64 arrays broadcast)."""
    t0, d = np.asarray(t0, dtype=np.int64), np.asarray(d, dtype=np.int64)
    k = np.asarray(period, dtype=np.int64)
    first = -(-t0 // k) * k
    return np.where(d > 0, first + (d - 1) * k + 1, t0)


def moves_between(a: int, b: int, period: int = 1) -> int:
    """Steps s in [a, b) with s % period == 0: the moves of an agent walking from step a."""
    if b <= a:
        return 0
    return (b - 1) // period - (a - 1) // period if a > 0 else (b - 1) // period + 1


def walk(cur: Cell, target: Cell, moves: int) -> Cell:
    """Where ``moves`` x-first unit moves from ``cur`` toward ``target`` end (at most at it)."""
    dx = target[0] - cur[0]
    mx = min(moves, abs(dx))
    x = cur[0] + (mx if dx > 0 else -mx)
    moves -= mx
    dy = target[1] - cur[1]
    my = min(moves, abs(dy))
    return (x, cur[1] + (my if dy > 0 else -my))


def group_period(periods: Sequence[int] | np.ndarray) -> int:
    """The period of a group carrying together: the lcm of its members' periods."""
    return math.lcm(*(int(p) for p in periods)) if len(periods) else 1


@dataclass(frozen=True)
class Grid:
    width: int = DEFAULT_WIDTH
    height: int = DEFAULT_HEIGHT

    def contains(self, cell: Cell) -> bool:
        return 0 <= cell[0] < self.width and 0 <= cell[1] < self.height

    @property
    def cells(self) -> int:
        return self.width * self.height


# An object o_i = (l_i, d_i, n_i). The sensed view and the ground truth carry the same fields,
# so the truth type is the message type: nothing is translated between world and agents.
ObjectSpec = ObjectInfo


@dataclass(frozen=True)
class AgentSpec:
    """A robot of the team: its id, its base (where it starts and returns to), its period (it
    moves one cell every ``period`` steps; 1 = the paper's robots), and optionally its own sweep
    and forbidden zones."""

    id: int
    base: Cell
    period: int = 1
    # Its own sweep's waypoints when it does not sweep its subarea of the equal partition (a
    # negotiated partition, ``ost_ros.negotiation.partition``); empty: its subarea's sweep.
    sweep: tuple[Cell, ...] = ()
    # Private no-search zones [x0, y0, x1, y1] (inclusive cells): a negotiated partition never
    # gives the robot these cells to search. Its moves to objects are not re-routed around them.
    forbidden: tuple[tuple[int, int, int, int], ...] = ()


@dataclass(frozen=True)
class Subarea:
    """A rectangle of the equal partition, searched by one agent."""

    x0: int
    y0: int
    width: int
    height: int

    @property
    def start(self) -> Cell:
        """The sweep's initial cell: the subarea's (0, 1) cell (the middle of its first 3 rows)."""
        return (self.x0, self.y0 + min(1, self.height - 1))

    def contains(self, cell: Cell) -> bool:
        return self.x0 <= cell[0] < self.x0 + self.width and self.y0 <= cell[1] < self.y0 + self.height


@dataclass(frozen=True)
class Scenario:
    """A complete OST instance: the area, its partition, the team and the objects.

    ``agents[k]`` searches ``subareas[k]`` (row-major over the m×n partition). Objects are kept
    sorted by id; the id is the object's priority in coordination.
    """

    grid: Grid
    partition: tuple[int, int]
    agents: tuple[AgentSpec, ...]
    objects: tuple[ObjectSpec, ...]
    nmax: int = DEFAULT_NMAX
    subareas: tuple[Subarea, ...] = field(default=(), compare=False)

    @property
    def n_agents(self) -> int:
        return len(self.agents)

    @property
    def n_objects(self) -> int:
        return len(self.objects)

    @property
    def periods(self) -> tuple[int, ...]:
        return tuple(a.period for a in self.agents)

    @property
    def heterogeneous(self) -> bool:
        """Some agent is slower than one cell per step."""
        return any(a.period != 1 for a in self.agents)
