"""Motion primitives: 4-connected moves, one cell per step, x first then y.

Every agent uses the same rule, so a carrying group computes the same next cell and moves as
one, and every planned travel time equals the Manhattan distance.
"""

from __future__ import annotations

from ost_ros.messages import Cell

DIRECTIONS: tuple[Cell, ...] = ((1, 0), (-1, 0), (0, 1), (0, -1))


def step_toward(cur: Cell, target: Cell) -> Cell:
    """The unit move from ``cur`` toward ``target`` (x first), or (0, 0) when there."""
    if cur[0] != target[0]:
        return (1 if target[0] > cur[0] else -1, 0)
    if cur[1] != target[1]:
        return (0, 1 if target[1] > cur[1] else -1)
    return (0, 0)


def apply(cur: Cell, direction: Cell) -> Cell:
    return (cur[0] + direction[0], cur[1] + direction[1])
