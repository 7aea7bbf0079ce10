"""The communication module of a CCP agent (paper §3, §4): coordination on shared knowledge.

Every found object is broadcast and stored by every agent (:class:`Knowledge`). At each
coordination point every agent runs the same :func:`~ost_ros.coordination.coordinate` on the same
knowledge, so all agents hold the same global schedule without negotiating it. Each agent
broadcasts its own selections; peers recompute them and record any disagreement (a faulty or false
peer is detected, not obeyed).

Comm FSA: LISTENING —(coordination point)→ COORDINATING → LISTENING;
LISTENING —(all agents finished searching)→ COORDINATING → CLOSED (final schedule known).
Any state —(the world's AgentLost)→ RECOVERING —(every survivor's Status, next step)→
COORDINATING → LISTENING or CLOSED: what the dead robot had not done is handed to survivors
(:mod:`ost_ros.protocols.shared.recovery`, docs/interpretation.md "Robot failures").

Coordinator organisation (``policy.organisation == "coordinator"``): at a coordination point
every agent sets the same objects aside, but only the lowest-id agent runs Algorithm
Coordination — for schedules that start a step later — and broadcasts the result
(:class:`ScheduleUpdate`); everyone adopts it the next step (the final one closes the comm).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from ost_msgs_py.messages import (
    AgentLost,
    AgentMessage,
    ObjectFound,
    ScheduledObject,
    ScheduleUpdate,
    SearchDone,
    Selection,
    Status,
)
from ost_ros.coordination import Assignment, CoordinationPolicy, coordinate
from ost_ros.model import Cell, group_period
from ost_ros.planner import improve
from ost_ros.protocols.shared.knowledge import Knowledge, QueuedMessages
from ost_ros.protocols.shared.recovery import Sweep, drop_cell, remaining_sweep
from ost_ros.team import TeamInfo

# Selections of this many most recent coordinations are kept for cross-checking peers.
_SELECTION_MEMORY = 8


class CommState(str, Enum):
    LISTENING = "LISTENING"
    COORDINATING = "COORDINATING"
    RECOVERING = "RECOVERING"  # a robot failed: waiting for every survivor's Status
    CLOSED = "CLOSED"


@dataclass
class CcpComm(QueuedMessages):
    """The comm module of one CCP agent (``voices``: the agents it speaks for — itself, or the
    whole team when one module computes a run for everyone, :mod:`ost_ros.engines.analytic`)."""

    me: int
    team: TeamInfo
    policy: CoordinationPolicy
    voices: tuple[int, ...] = ()
    planner: str = "paper"  # "improved": re-plan what has not started (ost_ros.planner)
    state: CommState = CommState.LISTENING
    # Failures: dead agent -> step it failed in; the step a failure was learnt in (statuses are
    # due the next step); survivors' statuses; objects no survivor group is large enough for;
    # sweeps nobody owns yet.
    lost: dict[int, int] = field(default_factory=dict)
    recovering: int | None = None
    statuses: dict[int, Status] = field(default_factory=dict)
    impossible: set[int] = field(default_factory=set)
    orphans: list[tuple[Cell, ...]] = field(default_factory=list)
    reset: bool = False  # the agent drops its not-started tasks (set on a failure)
    replanned: bool = False  # the improved planner moved tasks not taken up yet
    # Coordinator organisation: objects set aside for the coordinator's next update, and
    # whether that update is the final one.
    awaiting: set[int] = field(default_factory=set)
    closing: bool = False
    _selections: dict[int, tuple[tuple[int, ...], np.ndarray]] = field(default_factory=dict)
    _outbox: list[AgentMessage] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.knowledge = Knowledge(self.me, self.team)
        self.voices = self.voices or (self.me,)
        # Search work still owed by each agent (its own sweep, then sweeps taken over).
        self.sweeps: dict[int, list[Sweep]] = {}
        self.owed = {j: 1 for j in self.team.agent_ids}

    # ------------------------------------------------------------------ incoming

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None:
        """Comm module, step ``t``: take in every message of the step, then coordinate if due."""
        k = self.knowledge
        for msg in messages:
            self._take(t, msg)
        if self.recovering is not None:
            if self.recovering == t:
                return  # statuses come next step
            self._recover(t)
        if self.state is CommState.CLOSED or self.closing:
            return
        if self.all_searched:
            self._coordinate(t, final=True)
            if self.awaiting:  # a coordinator's update still to come (a re-plan): it closes
                self.closing = True
            elif not self.closing:
                self.state = CommState.CLOSED
                k.predicted_makespan = k.predict_makespan(t, self.alive)
        elif self.policy.due(
            t, len(k.unscheduled), self.team.searched_fraction(t - 1), self.team.searched_fraction(t)
        ):
            self._coordinate(t)

    def _take(self, t: int, msg: AgentMessage) -> None:
        """One message of step ``t``, by kind."""
        k = self.knowledge
        if isinstance(msg, ObjectFound):
            k.note_found(msg.object, msg.t)
        elif isinstance(msg, SearchDone):
            if msg.sender in self.team.agent_ids and msg.sender not in self.lost:
                self.owed[msg.sender] = max(0, self.owed[msg.sender] - 1)
                if self.owed[msg.sender] == 0:
                    k.searched.add(msg.sender)
        elif isinstance(msg, Selection):
            self._check_selection(msg)
        elif isinstance(msg, Status):
            if msg.sender in self.team.agent_ids and msg.sender not in self.lost:
                self.statuses[msg.sender] = msg
        elif isinstance(msg, AgentLost):
            self._lose(msg.agent, msg.t)
        elif isinstance(msg, ScheduleUpdate):
            self._adopt(t, msg)

    def next_event(self, t: int) -> int | None:
        """The first step s >= t in which :meth:`receive` acts with no message (None: never)."""
        if self.recovering is not None or (self.all_searched and not self.closed and not self.closing):
            return t
        if self.closed or self.closing:
            return None
        return self.policy.next_due(t, len(self.knowledge.unscheduled), self.team)

    def _check_selection(self, msg: Selection) -> None:
        if msg.sender in self.voices or msg.sender not in self.team.agent_ids:
            return
        mine = self._selections.get(msg.coordination)
        if mine is None or msg.sender not in mine[0]:
            self.knowledge.warnings.append(
                f"agent {msg.sender}: selection for unknown coordination {msg.coordination}; ignored"
            )
            return
        ids, selections = mine
        expected = tuple(int(x) for x in selections[:, ids.index(msg.sender)])
        if tuple(msg.objects) != expected:
            self.knowledge.warnings.append(
                f"agent {msg.sender}: selection {list(msg.objects)} in coordination "
                f"{msg.coordination} contradicts the algorithm ({list(expected)}); ignored"
            )

    # ------------------------------------------------------------------ coordination

    @property
    def alive(self) -> tuple[int, ...]:
        """Agent ids not known to have failed, ascending."""
        return tuple(j for j in self.team.agent_ids if j not in self.lost)

    @property
    def all_searched(self) -> bool:
        """Every survivor has done all its search work and no sweep is left without an owner."""
        return (
            self.recovering is None
            and not self.orphans
            and all(j in self.knowledge.searched for j in self.alive)
        )

    def _schedule_batch(self, t: int, batch: list[int], hint: list[int] | None = None):
        """Algorithm Coordination of ``batch`` among the survivors, for steps after ``t`` (with
        the improved planner: starting from ``hint``, the plan as it stood, if it is better)."""
        cost, loc = self.knowledge.costs(t)
        idx = [self.team.index(j) for j in self.alive]
        periods = self.team.speed_periods
        args = (
            self.alive,
            cost[idx],
            loc[idx],
            [self.knowledge.objects[i] for i in batch],
        )
        per = None if periods is None else [periods[k] for k in idx]
        if self.planner == "improved":
            return improve(*args, [self.team.bases[k] for k in idx], per, hint=hint or ())
        return coordinate(*args, per)

    def _reopen(self, s: int) -> list[int]:
        """Improved planner: take what no member has taken up by step ``s`` (the first the new
        plan applies to) back out of the schedule: its objects, in the order they were planned."""
        k = self.knowledge
        if self.planner != "improved":
            return []
        reopened = k.reopen(k.open_entries(s))
        if reopened:
            self.replanned = True
        return reopened

    def _coordinate(self, t: int, final: bool = False) -> None:
        k = self.knowledge
        survivors = self.alive
        for i in [i for i in k.unscheduled if k.objects[i].required > len(survivors)]:
            # Fewer robots survive than this object needs: it cannot be moved any more.
            k.unscheduled.discard(i)
            self.impossible.add(i)
        if not k.unscheduled:
            return
        if self.policy.centralised:
            self._hand_to_coordinator(t, final)
            return
        self.state = CommState.COORDINATING
        reopened = self._reopen(t + 1)
        result = self._schedule_batch(t, reopened + sorted(k.unscheduled), reopened)
        k.assign(result.schedule)
        k.unscheduled.clear()
        k.coordinations += 1
        self._selections[k.coordinations] = (survivors, result.selections)
        self._selections.pop(k.coordinations - _SELECTION_MEMORY, None)
        for voice in self.voices:
            mine = tuple(int(x) for x in result.selections[:, survivors.index(voice)])
            self._outbox.append(Selection(voice, t, k.coordinations, mine))
        self.state = CommState.LISTENING

    # ------------------------------------------------------------------ coordinator organisation

    @property
    def coordinator(self) -> int:
        return self.alive[0]

    def _hand_to_coordinator(self, t: int, final: bool) -> None:
        """Everyone sets the batch aside; the coordinator schedules it for steps from t+2 on
        (its update is read in step t+1) and queues the update."""
        k = self.knowledge
        reopened = self._reopen(t + 2)
        batch = reopened + sorted(k.unscheduled)
        k.unscheduled.clear()
        self.awaiting.update(batch)
        self.closing = self.closing or final
        if self.me != self.coordinator:
            return
        result = self._schedule_batch(t + 1, batch, reopened)
        entries = tuple(ScheduledObject(a.object, a.agents, a.start, a.finish) for a in result.schedule)
        self._outbox.append(ScheduleUpdate(self.me, t, k.coordinations + 1, entries, final))

    def _adopt(self, t: int, msg: ScheduleUpdate) -> None:
        k = self.knowledge
        if msg.sender != self.coordinator or msg.coordination != k.coordinations + 1:
            k.warnings.append(
                f"agent {msg.sender}: schedule update {msg.coordination} is not the "
                f"coordinator's next one; ignored"
            )
            return
        for e in msg.assignments:
            if e.object not in self.awaiting:
                k.warnings.append(
                    f"agent {msg.sender}: schedule update {msg.coordination} has "
                    f"object {e.object}, which was not set aside; ignored"
                )
                return
        k.assign([Assignment(e.object, tuple(e.agents), e.start, e.finish) for e in msg.assignments])
        self.awaiting.difference_update(e.object for e in msg.assignments)
        k.coordinations += 1
        if msg.final or (self.closing and not self.awaiting):
            self.closing = False
            self.state = CommState.CLOSED
            k.predicted_makespan = k.predict_makespan(t, self.alive)

    # ------------------------------------------------------------------ failures

    def _sweeps_of(self, agent: int) -> list[Sweep]:
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
        k.searched.discard(agent)
        if self.owed[agent] > 0:  # its unsensed cells: for a survivor to sweep
            for sw in self._sweeps_of(agent):
                rest = remaining_sweep(sw, t, period)
                if rest:
                    self.orphans.append(rest)
        self.owed[agent] = 0
        k.schedule[:] = [a for a in k.schedule if self._keeps(a, agent, t)]
        # coordinator organisation: an update that may never come (the coordinator may be the
        # one that died) — its objects go back into the pool; the new coordinator re-plans them
        k.unscheduled |= self.awaiting
        self.awaiting.clear()
        self.closing = False
        k.predicted_makespan = None  # made with the dead agent; predicted anew at the close
        self.recovering = t
        self.statuses.clear()
        self.reset = True
        self.state = CommState.RECOVERING

    def _keeps(self, a: Assignment | Sweep, agent: int, t: int) -> bool:
        """Whether schedule entry ``a`` survives ``agent``'s failure in step t; what does not goes
        back into the pool (an object carried part of the way: from where it was dropped)."""
        k = self.knowledge
        if isinstance(a, Sweep):
            if a.agent == agent:  # the dead agent's: orphaned in _lose
                return False
            if a.start > t:  # a survivor's take-over not begun: back into the pool
                self.orphans.append(a.path[a.walk :])
                self._sweeps_of(a.agent).remove(a)
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
            sw = [s for s in self._sweeps_of(self.me) if s.finish >= t]
            if sw:
                return Status(self.me, t, sw[-1].finish, sw[-1].path[-1])
        return Status(self.me, t, t + 1, (at[0], at[1]))

    def _recover(self, t: int) -> None:
        """Every survivor's Status is in: hand out the orphaned sweeps (each to the survivor free
        first, ties to the lower id), then coordinate every unscheduled object."""
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
            self._sweeps_of(j).append(sw)
            self.owed[j] += 1
            k.searched.discard(j)
            k.free_at[i] = sw.finish
            k.free_loc[i] = sw.path[-1]
            k.lengths[i] = sw.finish
        self.orphans.clear()
        self.recovering = None
        self.statuses.clear()
        self.state = CommState.LISTENING
        self._coordinate(t)
        self.state = CommState.LISTENING

    @property
    def closed(self) -> bool:
        """All agents have searched and every object is scheduled: nothing more will come."""
        return self.state is CommState.CLOSED
