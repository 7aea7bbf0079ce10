"""The Object-Sorting Task model (paper §2.1, §5.1): grid, objects, agents, scenario.

Coordinates are cells ``(x, y)`` with ``0 <= x < width`` and ``0 <= y < height``; agents move
4-connected, one cell per time step, and several agents may share a cell.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ost_msgs_py.messages import ObjectInfo

Cell = tuple[int, int]

DEFAULT_WIDTH = 500
DEFAULT_HEIGHT = 200
DEFAULT_NMAX = 10


def manhattan(a: Cell, b: Cell) -> int:
    """Length of a shortest 4-connected path between two cells."""
    return abs(a[0] - b[0]) + abs(a[1] - b[1])


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
    """A robot of the team: its id and its base (where it starts and returns to)."""

    id: int
    base: Cell


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
        return (self.x0 <= cell[0] < self.x0 + self.width
                and self.y0 <= cell[1] < self.y0 + self.height)


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
