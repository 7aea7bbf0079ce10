"""The communication module of a CCP agent (paper §3, §4): shared knowledge and coordination.

Every found object is broadcast and stored by every agent. At each coordination point every agent
runs the same :func:`~ost_ros.coordination.coordinate` on the same knowledge, so all agents hold
the same global schedule without negotiating it. Each agent broadcasts its own selections; peers
recompute them and record any disagreement (a faulty or false peer is detected, not obeyed).

Comm FSA: LISTENING —(coordination point)→ COORDINATING → LISTENING;
LISTENING —(all agents finished searching)→ COORDINATING → CLOSED (final schedule known).
Any state —(the world's AgentLost)→ RECOVERING —(every survivor's Status, next step)→
COORDINATING → LISTENING or CLOSED: what the dead robot had not done is handed to survivors
(:mod:`ost_ros.recovery`, docs/interpretation.md "Robot failures").

Coordinator organisation (``policy.organisation == "coordinator"``): at a coordination point
every agent sets the same objects aside, but only the lowest-id agent runs Algorithm
Coordination — for schedules that start a step later — and broadcasts the result
(:class:`ScheduleUpdate`); everyone adopts it the next step (the final one closes the comm).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from ost_msgs_py.messages import (AgentLost, ObjectFound, ScheduledObject, ScheduleUpdate, SearchDone,
                                  Selection, Status)
from ost_ros.coordination import Assignment, CoordinationPolicy, coordinate
from ost_ros.model import Cell, ObjectSpec, arrival_np, group_period
from ost_ros.recovery import Sweep, drop_cell, remaining_sweep
from ost_ros.team import TeamInfo

# Selections of this many most recent coordinations are kept for cross-checking peers.
_SELECTION_MEMORY = 8


class CommState(str, Enum):
    LISTENING = "LISTENING"
    COORDINATING = "COORDINATING"
    NEGOTIATING = "NEGOTIATING"   # NCP only: a negotiation is under way (ost_ros.ncp)
    RECOVERING = "RECOVERING"     # a robot failed: waiting for every survivor's Status
    CLOSED = "CLOSED"


@dataclass
class CcpComm:
    """Shared knowledge of one CCP agent, and the coordination it runs."""

    me: int
    team: TeamInfo
    policy: CoordinationPolicy
    state: CommState = CommState.LISTENING
    objects: dict[int, ObjectSpec] = field(default_factory=dict)
    found_at: dict[int, int] = field(default_factory=dict)
    unscheduled: set[int] = field(default_factory=set)
    schedule: list[Assignment] = field(default_factory=list)
    searched: set[int] = field(default_factory=set)
    coordinations: int = 0
    predicted_makespan: int | None = None
    warnings: list[str] = field(default_factory=list)
    # Failures: dead agent -> step it failed in; the step a failure was learnt in (statuses are
    # due the next step); survivors' statuses; objects left where a failed group held them;
    # objects no survivor group is large enough for; sweeps nobody owns yet.
    lost: dict[int, int] = field(default_factory=dict)
    recovering: int | None = None
    statuses: dict[int, Status] = field(default_factory=dict)
    drops: dict[int, Cell] = field(default_factory=dict)
    impossible: set[int] = field(default_factory=set)
    orphans: list[tuple[Cell, ...]] = field(default_factory=list)
    reset: bool = False            # the agent drops its not-started tasks (set on a failure)
    # Coordinator organisation: objects set aside for the coordinator's next update, and
    # whether that update is the final one.
    awaiting: set[int] = field(default_factory=set)
    closing: bool = False
    _selections: dict[int, tuple[tuple[int, ...], np.ndarray]] = field(default_factory=dict)
    _outbox: list = field(default_factory=list)

    def __post_init__(self) -> None:
        n = self.team.size
        self._lengths = self.team.sweep_lengths()
        self.free_at = np.zeros(n, dtype=np.int64)   # finish of each agent's last scheduled object
        self.free_loc = self.team.sweep_ends()       # where it then stands (sweep end if none)
        # Search work still owed by each agent (its own sweep, then sweeps taken over).
        self.sweeps: dict[int, list[Sweep]] = {}
        self.owed = {j: 1 for j in self.team.agent_ids}

    # ------------------------------------------------------------------ incoming

    def note_found(self, obj: ObjectSpec, t: int) -> bool:
        """Store an object (sensed or heard of); True if it was new."""
        known = self.objects.get(obj.id)
        if known is None:
            self.objects[obj.id] = obj
            self.found_at[obj.id] = t
            self.unscheduled.add(obj.id)
            return True
        if known != obj and not (obj.id in self.drops and replace(known, location=obj.location) == obj):
            self.warnings.append(f"object {obj.id} reported as {obj} but known as {known}; kept")
        return False

    def receive(self, t: int, messages: list) -> None:
        """Comm module, step ``t``: take in every message of the step, then coordinate if due."""
        for msg in messages:
            if isinstance(msg, ObjectFound):
                self.note_found(msg.object, msg.t)
            elif isinstance(msg, SearchDone):
                if msg.sender in self.team.agent_ids and msg.sender not in self.lost:
                    self.owed[msg.sender] = max(0, self.owed[msg.sender] - 1)
                    if self.owed[msg.sender] == 0:
                        self.searched.add(msg.sender)
            elif isinstance(msg, Selection):
                self._check_selection(msg)
            elif isinstance(msg, Status):
                if msg.sender in self.team.agent_ids and msg.sender not in self.lost:
                    self.statuses[msg.sender] = msg
            elif isinstance(msg, AgentLost):
                self._lose(msg.agent, msg.t)
            elif isinstance(msg, ScheduleUpdate):
                self._adopt(t, msg)
        if self.recovering is not None:
            if self.recovering == t:
                return            # statuses come next step
            self._recover(t)
        if self.state is CommState.CLOSED or self.closing:
            return
        if self.all_searched:
            self._coordinate(t, final=True)
            if not self.closing:
                self.state = CommState.CLOSED
                self.predicted_makespan = self._predict_makespan(t)
        elif self.policy.due(t, len(self.unscheduled), self.team.searched_fraction(t - 1),
                             self.team.searched_fraction(t)):
            self._coordinate(t)

    def _check_selection(self, msg: Selection) -> None:
        if msg.sender == self.me or msg.sender not in self.team.agent_ids:
            return
        mine = self._selections.get(msg.coordination)
        if mine is None or msg.sender not in mine[0]:
            self.warnings.append(f"agent {msg.sender}: selection for unknown coordination "
                                 f"{msg.coordination}; ignored")
            return
        ids, selections = mine
        expected = tuple(int(x) for x in selections[:, ids.index(msg.sender)])
        if tuple(msg.objects) != expected:
            self.warnings.append(f"agent {msg.sender}: selection {list(msg.objects)} in coordination "
                                 f"{msg.coordination} contradicts the algorithm ({list(expected)}); "
                                 "ignored")

    # ------------------------------------------------------------------ coordination

    def costs(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """CA_j and loc_j for a coordination in step t: the schedule applies from step t+1."""
        return np.maximum(np.maximum(self.free_at, self._lengths), t + 1), self.free_loc.copy()

    @property
    def alive(self) -> tuple[int, ...]:
        """Agent ids not known to have failed, ascending."""
        return tuple(j for j in self.team.agent_ids if j not in self.lost)

    @property
    def all_searched(self) -> bool:
        """Every survivor has done all its search work and no sweep is left without an owner."""
        return (self.recovering is None and not self.orphans
                and all(j in self.searched for j in self.alive))

    def _coordinate(self, t: int, final: bool = False) -> None:
        survivors = self.alive
        for i in [i for i in self.unscheduled if self.objects[i].required > len(survivors)]:
            # Fewer robots survive than this object needs: it cannot be moved any more.
            self.unscheduled.discard(i)
            self.impossible.add(i)
        if not self.unscheduled:
            return
        if self.policy.centralised:
            self._hand_to_coordinator(t, final)
            return
        self.state = CommState.COORDINATING
        cost, loc = self.costs(t)
        idx = [self.team.index(j) for j in survivors]
        periods = self.team.speed_periods
        batch = [self.objects[i] for i in sorted(self.unscheduled)]
        result = coordinate(survivors, cost[idx], loc[idx], batch,
                            None if periods is None else [periods[k] for k in idx])
        for a in result.schedule:
            members = [self.team.index(j) for j in a.agents]
            self.free_at[members] = a.finish
            self.free_loc[members] = self.objects[a.object].destination
        self.schedule.extend(result.schedule)
        self.unscheduled.clear()
        self.coordinations += 1
        self._selections[self.coordinations] = (survivors, result.selections)
        self._selections.pop(self.coordinations - _SELECTION_MEMORY, None)
        mine = tuple(int(x) for x in result.selections[:, survivors.index(self.me)])
        self._outbox.append(Selection(self.me, t, self.coordinations, mine))
        self.state = CommState.LISTENING

    # ------------------------------------------------------------------ coordinator organisation

    @property
    def coordinator(self) -> int:
        return self.alive[0]

    def _hand_to_coordinator(self, t: int, final: bool) -> None:
        """Everyone sets the batch aside; the coordinator schedules it for steps from t+2 on
        (its update is read in step t+1) and queues the update."""
        batch = sorted(self.unscheduled)
        self.unscheduled.clear()
        self.awaiting.update(batch)
        self.closing = self.closing or final
        if self.me != self.coordinator:
            return
        cost, loc = self.costs(t + 1)
        idx = [self.team.index(j) for j in self.alive]
        periods = self.team.speed_periods
        result = coordinate(self.alive, cost[idx], loc[idx], [self.objects[i] for i in batch],
                            None if periods is None else [periods[k] for k in idx])
        entries = tuple(ScheduledObject(a.object, a.agents, a.start, a.finish) for a in result.schedule)
        self._outbox.append(ScheduleUpdate(self.me, t, self.coordinations + 1, entries, final))

    def _adopt(self, t: int, msg: ScheduleUpdate) -> None:
        if msg.sender != self.coordinator or msg.coordination != self.coordinations + 1:
            self.warnings.append(f"agent {msg.sender}: schedule update {msg.coordination} is not the "
                                 f"coordinator's next one; ignored")
            return
        for e in msg.assignments:
            if e.object not in self.awaiting:
                self.warnings.append(f"agent {msg.sender}: schedule update {msg.coordination} has "
                                     f"object {e.object}, which was not set aside; ignored")
                return
        for e in msg.assignments:
            a = Assignment(e.object, tuple(e.agents), e.start, e.finish)
            members = [self.team.index(j) for j in a.agents]
            self.free_at[members] = a.finish
            self.free_loc[members] = self.objects[a.object].destination
            self.schedule.append(a)
            self.awaiting.discard(a.object)
        self.coordinations += 1
        if msg.final:
            self.closing = False
            self.state = CommState.CLOSED
            self.predicted_makespan = self._predict_makespan(t)

    def _predict_makespan(self, t: int) -> int:
        cost, loc = self.costs(t)
        bases = np.array(self.team.bases, dtype=np.int64).reshape(-1, 2)
        home = arrival_np(cost, np.abs(loc - bases).sum(axis=1), self.team.period_array())
        return int(np.max(home[[self.team.index(j) for j in self.alive]]))

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
        period = self.team.periods[self.team.index(agent)] if self.team.periods else 1
        self.lost[agent] = t
        self.searched.discard(agent)
        if self.owed[agent] > 0:     # its unsensed cells: for a survivor to sweep
            for sw in self._sweeps_of(agent):
                rest = remaining_sweep(sw, t, period)
                if rest:
                    self.orphans.append(rest)
        self.owed[agent] = 0
        kept: list = []
        for a in self.schedule:
            if isinstance(a, Sweep):
                if a.agent == agent:     # the dead agent's: orphaned above
                    continue
                if a.start > t:          # a survivor's take-over not begun: back into the pool
                    self.orphans.append(a.path[a.walk:])
                    self._sweeps_of(a.agent).remove(a)
                    self.owed[a.agent] -= 1
                    if self.owed[a.agent] == 0:
                        self.searched.add(a.agent)
                else:
                    kept.append(a)
                continue
            if agent in a.agents and a.finish > t:
                if a.start < t:          # carried since a.start, held from step t on
                    o = self.objects[a.object]
                    k = group_period([self.team.periods[self.team.index(j)] for j in a.agents]) \
                        if self.team.periods else 1
                    self.drops[a.object] = drop_cell(o.location, o.destination, a.start, t, k)
                    self.objects[a.object] = replace(o, location=self.drops[a.object])
                self.unscheduled.add(a.object)
            elif a.start > t:            # not under way: re-planned with everything else
                self.unscheduled.add(a.object)
            else:
                kept.append(a)
        self.schedule[:] = kept
        # coordinator organisation: an update that may never come (the coordinator may be the
        # one that died) — its objects go back into the pool; the new coordinator re-plans them
        self.unscheduled |= self.awaiting
        self.awaiting.clear()
        self.closing = False
        self.predicted_makespan = None   # made with the dead agent; predicted anew at the close
        self.recovering = t
        self.statuses.clear()
        self.reset = True
        self.state = CommState.RECOVERING

    def status(self, t: int, at: Cell, current) -> Status:
        """This agent's Status in step t (the step after it learnt of a failure): a carry
        under way or its sweep runs on; otherwise it is free from t+1 where it stands (it waits
        in step t)."""
        if isinstance(current, Assignment) and current in self.schedule and current.finish > t:
            return Status(self.me, t, current.finish, tuple(self.objects[current.object].destination))
        if self.owed[self.me] > 0:
            sw = [s for s in self._sweeps_of(self.me) if s.finish >= t]
            if sw:
                return Status(self.me, t, sw[-1].finish, tuple(sw[-1].path[-1]))
        return Status(self.me, t, t + 1, tuple(at))

    def _recover(self, t: int) -> None:
        """Every survivor's Status is in: hand out the orphaned sweeps (each to the survivor free
        first, ties to the lower id), then coordinate every unscheduled object."""
        survivors = self.alive
        missing = [j for j in survivors if j not in self.statuses]
        if missing:   # cannot happen in lockstep; say so rather than plan on a guess
            self.warnings.append(f"recovery in step {t}: no status from agents {missing}; "
                                 "planning with what they were last known to do")
        for j, st in self.statuses.items():
            k = self.team.index(j)
            self.free_at[k] = st.free_at
            self.free_loc[k] = st.location
            self._lengths[k] = min(self._lengths[k], st.free_at)
        periods = self.team.period_array()
        for cells in self.orphans:
            cost, loc = self.costs(t)
            idx = [self.team.index(j) for j in survivors]
            k = idx[int(np.argmin(cost[idx]))]
            j = self.team.agent_ids[k]
            sw = Sweep.take_over(j, tuple(int(v) for v in loc[k]), int(cost[k]), cells, int(periods[k]))
            self.schedule.append(sw)
            self._sweeps_of(j).append(sw)
            self.owed[j] += 1
            self.searched.discard(j)
            self.free_at[k] = sw.finish
            self.free_loc[k] = sw.path[-1]
            self._lengths[k] = sw.finish
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

    @property
    def assignments(self) -> list[Assignment]:
        """The global schedule's objects (without take-over sweeps), in scheduling order."""
        return [a for a in self.schedule if isinstance(a, Assignment)]

    def drain(self) -> list:
        out, self._outbox = self._outbox, []
        return out
