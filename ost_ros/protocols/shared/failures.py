"""Recovery from a failed robot, for the comm modules that keep a shared schedule (CCP and its
coordinator organisation, NCP, the auction): what every survivor works out alike when the world
says a robot failed in step t.

1. step t (the world's AgentLost): the dead robot's unsensed cells become orphaned sweeps;
   everything not under way by step t leaves the schedule and goes back into the pool (an object
   carried part of the way, from where it was dropped); the protocol cancels what it had pending
   (``_cancel_pending``: a coordinator's update, a negotiation, auctions);
2. step t+1: every survivor broadcasts its Status (when it is free of what it keeps doing, and
   where); the agent drops its cancelled tasks (``reset``);
3. step t+1, every Status in: the orphaned sweeps go to the survivors free first, then the
   protocol plans the pool again (``_after_recovery``: coordinate, negotiate, auction).

Readings in docs/interpretation.md ("Robot failures").
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ost_ros.coordination import Assignment
from ost_ros.messages import SearchDone, Status
from ost_ros.model import Cell, group_period
from ost_ros.protocols.shared.knowledge import Knowledge
from ost_ros.protocols.shared.recovery import Sweep, drop_cell, remaining_sweep
from ost_ros.team import TeamInfo


class Recovery:
    """The failure handling a shared-schedule comm module mixes in (call ``_init_recovery`` in
    its ``__post_init__``; implement ``_cancel_pending`` and ``_after_recovery``)."""

    me: int
    team: TeamInfo
    knowledge: Knowledge

    def _init_recovery(self) -> None:
        # dead agent -> step it failed in; the step a failure was learnt in (statuses are due
        # the next step); survivors' statuses; objects no survivor group is large enough for;
        # sweeps nobody owns yet; whether the agent must drop its not-started tasks
        self.lost: dict[int, int] = {}
        self._alive: tuple[int, ...] | None = None  # cached survivors (reset on a failure)
        self.recovering: int | None = None
        self.statuses: dict[int, Status] = {}
        self.impossible: set[int] = set()
        self.orphans: list[tuple[Cell, ...]] = []
        self.reset = False
        # search work still owed by each agent (its own sweep, then sweeps taken over)
        self.sweeps: dict[int, list[Sweep]] = {}
        self.owed = {j: 1 for j in self.team.agent_ids}

    def _cancel_pending(self, t: int) -> None:
        """What the protocol had under way when a robot failed in step t goes back to the pool."""
        raise NotImplementedError

    def _after_recovery(self, t: int) -> None:
        """Every survivor's Status is in and the orphaned sweeps are handed out: plan the pool."""
        raise NotImplementedError

    @property
    def alive(self) -> tuple[int, ...]:
        """Agent ids not known to have failed, ascending."""
        if self._alive is None:
            self._alive = tuple(j for j in self.team.agent_ids if j not in self.lost)
        return self._alive

    @property
    def all_searched(self) -> bool:
        """Every survivor has done all its search work and no sweep is left without an owner."""
        return (
            self.recovering is None
            and not self.orphans
            and all(j in self.knowledge.searched for j in self.alive)
        )

    def _search_done(self, msg: SearchDone) -> None:
        """A SearchDone: one search task of the sender done (its sweep, or one taken over)."""
        if msg.sender in self.team.agent_ids and msg.sender not in self.lost:
            self.owed[msg.sender] = max(0, self.owed[msg.sender] - 1)
            if self.owed[msg.sender] == 0:
                self.knowledge.searched.add(msg.sender)

    def _status(self, msg: Status) -> None:
        if msg.sender in self.team.agent_ids and msg.sender not in self.lost:
            self.statuses[msg.sender] = msg

    def sweeps_of(self, agent: int) -> list[Sweep]:
        """An agent's search tasks: its own sweep (configuration every team mate can compute),
        then the sweeps it took over."""
        if agent not in self.sweeps:
            k = self.team.index(agent)
            path = tuple(self.team.search_path(k))
            self.sweeps[agent] = [Sweep(agent, path, 0, int(self.team.sweep_lengths()[k]))]
        return self.sweeps[agent]

    def _lose(self, agent: int, t: int) -> None:
        """The world says ``agent`` failed in step t (it did not act in t). Everything not under
        way by step t is cancelled and re-planned once every survivor has said where it stands
        (its Status, next step); what the dead agent owed goes back into the pool."""
        if agent not in self.team.agent_ids or agent in self.lost:
            return
        k = self.knowledge
        period = self.team.periods[self.team.index(agent)] if self.team.periods else 1
        self.lost[agent] = t
        self._alive = None
        k.searched.discard(agent)
        if self.owed[agent] > 0:  # its unsensed cells: for a survivor to sweep
            for sw in self.sweeps_of(agent):
                rest = remaining_sweep(sw, t, period)
                if rest:
                    self.orphans.append(rest)
        self.owed[agent] = 0
        k.schedule[:] = [a for a in k.schedule if self._keeps(a, agent, t)]
        k.predicted_makespan = None  # made with the dead agent; predicted anew at the close
        self.recovering = t
        self.statuses.clear()
        self.reset = True
        self._cancel_pending(t)

    def _keeps(self, a: Assignment | Sweep, agent: int, t: int) -> bool:
        """Whether schedule entry ``a`` survives ``agent``'s failure in step t; what does not goes
        back into the pool (an object carried part of the way: from where it was dropped)."""
        k = self.knowledge
        if isinstance(a, Sweep):
            if a.agent == agent:  # the dead agent's: orphaned in _lose
                return False
            if a.start > t:  # a survivor's take-over not begun: back into the pool
                self.orphans.append(a.path[a.walk :])
                self.sweeps_of(a.agent).remove(a)
                self.owed[a.agent] -= 1
                if self.owed[a.agent] == 0:
                    k.searched.add(a.agent)
                return False
            return True
        if agent in a.agents and a.finish > t:
            if a.start < t:  # carried since a.start, held from step t on
                o = k.objects[a.object]
                period = (
                    group_period([self.team.periods[self.team.index(j)] for j in a.agents])
                    if self.team.periods
                    else 1
                )
                k.drops[a.object] = drop_cell(o.location, o.destination, a.start, t, period)
                k.objects[a.object] = replace(o, location=k.drops[a.object])
            k.unscheduled.add(a.object)
            return False
        if a.start > t:  # not under way: re-planned with everything else
            k.unscheduled.add(a.object)
            return False
        return True

    def status(self, t: int, at: Cell, current: Assignment | None) -> Status:
        """This agent's Status in step t (the step after it learnt of a failure): a carry
        under way or its sweep runs on; otherwise it is free from t+1 where it stands (it waits
        in step t)."""
        k = self.knowledge
        if isinstance(current, Assignment) and current in k.schedule and current.finish > t:
            return Status(self.me, t, current.finish, k.objects[current.object].destination)
        if self.owed[self.me] > 0:
            sw = [s for s in self.sweeps_of(self.me) if s.finish >= t]
            if sw:
                return Status(self.me, t, sw[-1].finish, sw[-1].path[-1])
        return Status(self.me, t, t + 1, (at[0], at[1]))

    def _recover(self, t: int) -> None:
        """Every survivor's Status is in: hand out the orphaned sweeps (each to the survivor free
        first, ties to the lower id), then the protocol plans every unscheduled object."""
        k = self.knowledge
        survivors = self.alive
        missing = [j for j in survivors if j not in self.statuses]
        if missing:  # cannot happen in lockstep; say so rather than plan on a guess
            k.warnings.append(
                f"recovery in step {t}: no status from agents {missing}; "
                "planning with what they were last known to do"
            )
        for j, st in self.statuses.items():
            i = self.team.index(j)
            k.free_at[i] = st.free_at
            k.free_loc[i] = st.location
            k.lengths[i] = min(k.lengths[i], st.free_at)
        k.rebase()  # what is planned from here on starts where each survivor says it stands
        periods = self.team.period_array()
        for cells in self.orphans:
            cost, loc = k.costs(t)
            idx = [self.team.index(j) for j in survivors]
            i = idx[int(np.argmin(cost[idx]))]
            j = self.team.agent_ids[i]
            sw = Sweep.take_over(j, (int(loc[i][0]), int(loc[i][1])), int(cost[i]), cells, int(periods[i]))
            k.schedule.append(sw)
            self.sweeps_of(j).append(sw)
            self.owed[j] += 1
            k.searched.discard(j)
            k.free_at[i] = sw.finish
            k.free_loc[i] = sw.path[-1]
            k.lengths[i] = sw.finish
        self.orphans.clear()
        self.recovering = None
        self.statuses.clear()
        self._after_recovery(t)
