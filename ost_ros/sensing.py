"""What a sweeping agent senses, computed for a whole path at once (the event engines and the
makespan bound use it; the world senses step by step).

The sensor covers the 3×3 block around the agent; an agent on its sweep stands on ``path[i]``
once it has made i moves.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ost_ros.model import Cell, Scenario, Subarea
from ost_ros.search import agent_plan, route

# The sensor's 3×3 block around the agent, as offsets, in the order the world lists what it
# senses (an observation's order, which a planned step's expected reading must match).
BLOCK: tuple[Cell, ...] = tuple((dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1))


def sweep_paths(scenario: Scenario) -> list[np.ndarray]:
    """Each agent's cell-by-cell search path ((L_j + 1) × 2): it stands on row t at time t."""
    return list(
        _paths(
            scenario.subareas, tuple(a.base for a in scenario.agents), tuple(a.sweep for a in scenario.agents)
        )
    )


@lru_cache(maxsize=8)
def _paths(areas: tuple[Subarea, ...], bases: tuple, sweeps: tuple) -> tuple[np.ndarray, ...]:
    # A study runs many object sets on one team: the sweeps are computed once per team.
    out = []
    for area, base, sweep in zip(areas, bases, sweeps):
        path = np.array(route(agent_plan(area, base, sweep)), dtype=np.int64).reshape(-1, 2)
        path.flags.writeable = False
        out.append(path)
    return tuple(out)


@lru_cache(maxsize=4)
def first_sensings(scenario: Scenario) -> np.ndarray:
    """(N, M): the first index of agent j's sweep path at which it senses object i (-1: never).
    A study bounds a scenario and runs it under several protocols and triggers: computed once."""
    paths = sweep_paths(scenario)
    cells = np.array([o.location for o in scenario.objects], dtype=np.int64).reshape(-1, 2)
    first = np.array([first_sensing(p, cells) for p in paths], dtype=np.int64).reshape(len(paths), -1)
    first.flags.writeable = False
    return first


def first_sensing(path: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """For each cell, the first index of ``path`` whose 3×3 block covers it (-1: never)."""
    if len(cells) == 0:
        return np.zeros(0, dtype=np.int64)
    out = np.full(len(cells), -1, dtype=np.int64)
    lo, hi = path.min(axis=0) - 1, path.max(axis=0) + 1
    near = np.all((cells >= lo) & (cells <= hi), axis=1)
    for k in np.flatnonzero(near):
        cover = np.max(np.abs(path - cells[k]), axis=1) <= 1
        hit = int(np.argmax(cover))
        if cover[hit]:
            out[k] = hit
    return out
