"""Recovery from a failed robot: what every survivor can work out alone from the shared
schedule, with no word from the dead robot — planned = executed makes the past computable.

- :func:`drop_cell`: where an object lies when a carrier failed in step t (carried since its
  assignment's start along the carry route, held from step t on);
- :func:`remaining_sweep`: the cells of a sweep that a robot failing in step t never sensed;
- :class:`Sweep`: a search task — an agent's own sweep, or a dead robot's remainder taken over
  by a survivor (walk there, then follow the remainder).

Readings in docs/interpretation.md ("Robot failures").
"""

from __future__ import annotations

from dataclasses import dataclass

from ost_ros.model import Cell, arrival, manhattan, moves_between
from ost_ros.search import route


@dataclass(frozen=True)
class Sweep:
    """Search task of ``agent``: follow ``path`` from step ``start`` (one cell per move of its
    period), sensing all the way; the first ``walk`` moves only lead to the cells to search.
    ``finish``: the step it stands on the last cell (its SearchDone step)."""

    agent: int
    path: tuple[Cell, ...]
    start: int
    finish: int
    walk: int = 0

    @property
    def agents(self) -> tuple[int, ...]:  # the schedule's interface: who executes it
        return (self.agent,)

    @classmethod
    def take_over(cls, agent: int, at: Cell, free: int, cells: tuple[Cell, ...], period: int = 1) -> Sweep:
        """``agent``, free at step ``free`` at cell ``at``, walks to ``cells[0]`` and sweeps on."""
        lead = route([at, cells[0]])
        path = tuple(lead) + tuple(cells[1:])
        return cls(agent, path, free, arrival(free, len(path) - 1, period), manhattan(at, cells[0]))


def remaining_sweep(sweep: Sweep, t: int, period: int = 1) -> tuple[Cell, ...]:
    """Cells of ``sweep`` its agent, failing in step t (no observation in t), had not sensed.

    The agent stands on ``path[i]`` in step t, i = its moves since ``start``; cells before i were
    sensed from their own cell. Its lead-in walk is never owed. Empty once the sweep was done
    (its agent stood on the last cell and sensed it before step t)."""
    if sweep.finish < t:
        return ()
    i = moves_between(sweep.start, t, period) if t > sweep.start else 0
    return sweep.path[max(min(i, len(sweep.path) - 1), sweep.walk) :]


def drop_cell(location: Cell, destination: Cell, start: int, t: int, period: int = 1) -> Cell:
    """Where an object carried from ``location`` since step ``start`` (group period ``period``)
    lies once a carrier failed in step t: the carry moved it in steps [start, t) only."""
    path = route([location, destination])
    return path[min(moves_between(start, t, period), len(path) - 1)]
