"""What every agent knows before the run: the area, the team, the partition and everyone's sweep.

This is configuration, not ground truth about objects: agents learn objects only by sensing or by
messages. From it every agent can compute when and where each peer's search ends, which CCP
needs for a peer's cost CA_j while that peer is still searching.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ost_ros.model import Cell, Grid, Scenario, Subarea, arrival_np
from ost_ros.search import SweepSummary, agent_plan, route


@dataclass(frozen=True)
class TeamInfo:
    grid: Grid
    agent_ids: tuple[int, ...]  # ascending: the tie-break order of the protocol
    bases: tuple[Cell, ...]
    areas: tuple[Subarea, ...]
    sweeps: tuple[SweepSummary, ...]
    periods: tuple[int, ...] = ()  # each agent moves every k steps (empty: all 1)
    plans: tuple[tuple[Cell, ...], ...] = ()  # each agent's search waypoints (from its base)

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> TeamInfo:
        agents = scenario.agents  # sorted by id; agents[k] searches subareas[k]
        return cls(
            grid=scenario.grid,
            agent_ids=tuple(a.id for a in agents),
            bases=tuple(a.base for a in agents),
            areas=scenario.subareas,
            sweeps=tuple(
                SweepSummary.of(area, a.base, a.sweep) for area, a in zip(scenario.subareas, agents)
            ),
            periods=tuple(a.period for a in agents),
            plans=tuple(
                tuple(agent_plan(area, a.base, a.sweep)) for area, a in zip(scenario.subareas, agents)
            ),
        )

    def search_path(self, k: int) -> list[Cell]:
        """Agent k's search, cell by cell (its own sweep or its subarea's)."""
        return route(list(self.plans[k]))

    @property
    def size(self) -> int:
        return len(self.agent_ids)

    def index(self, agent_id: int) -> int:
        return self.agent_ids.index(agent_id)

    @property
    def speed_periods(self) -> tuple[int, ...] | None:
        """The periods for the cost model, or None for a unit-speed team (the paper's case)."""
        return self.periods if any(k != 1 for k in self.periods) else None

    def period_array(self) -> np.ndarray:
        return np.array(self.periods or (1,) * self.size, dtype=np.int64)

    def sweep_moves(self) -> np.ndarray:
        """Cells each agent's search walks (its path length)."""
        return np.array([s.length for s in self.sweeps], dtype=np.int64)

    def sweep_lengths(self) -> np.ndarray:
        """When each agent's search ends (L_j): its path walked at its own period."""
        return arrival_np(np.zeros(self.size, dtype=np.int64), self.sweep_moves(), self.period_array())

    def sweep_ends(self) -> np.ndarray:
        return np.array([s.end for s in self.sweeps], dtype=np.int64).reshape(-1, 2)

    def searched_fractions(self, ts: np.ndarray) -> np.ndarray:
        """:meth:`searched_fraction` at every step of ``ts`` at once (the same floats)."""
        moves = self.sweep_moves()
        total = int(moves.sum())
        if total == 0:
            return np.ones(len(ts))
        done = -(-np.maximum(np.asarray(ts, dtype=np.int64), 0)[:, None] // self.period_array()[None, :])
        return np.minimum(moves[None, :], done).sum(axis=1) / total

    def searched_fraction(self, t: int) -> float:
        """Share of the whole team's sweep done by time ``t`` (same for every agent)."""
        moves = self.sweep_moves()
        total = int(moves.sum())
        k = self.period_array()
        done = -(-max(t, 0) // k)  # movable steps 0, k, 2k, ... before t
        return 1.0 if total == 0 else float(np.minimum(moves, done).sum()) / total
