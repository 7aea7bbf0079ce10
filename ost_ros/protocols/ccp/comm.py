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
(:mod:`ost_ros.protocols.shared.failures`, docs/interpretation.md "Robot failures").

Coordinator organisation (``policy.organisation == "coordinator"``): at a coordination point
every agent sets the same objects aside, but only the lowest-id agent runs Algorithm
Coordination — for schedules that start a step later — and broadcasts the result
(:class:`ScheduleUpdate`); everyone adopts it the next step (the final one closes the comm).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

from ost_ros.coordination import Assignment, CoordinationPolicy, coordinate
from ost_ros.messages import AgentLost, AgentMessage, ObjectFound, ScheduledObject, SearchDone, Status
from ost_ros.planner import improve
from ost_ros.protocols.ccp.messages import ScheduleUpdate, Selection
from ost_ros.protocols.shared.failures import Recovery
from ost_ros.protocols.shared.knowledge import Knowledge, QueuedMessages
from ost_ros.team import TeamInfo

# Selections of this many most recent coordinations are kept for cross-checking peers.
_SELECTION_MEMORY = 8


class CommState(str, Enum):
    LISTENING = "LISTENING"
    COORDINATING = "COORDINATING"
    RECOVERING = "RECOVERING"  # a robot failed: waiting for every survivor's Status
    CLOSED = "CLOSED"


@dataclass
class CcpComm(Recovery, QueuedMessages):
    """The comm module of one CCP agent (``voices``: the agents it speaks for — itself, or the
    whole team when one module computes a run for everyone, :mod:`ost_ros.engines.analytic`)."""

    me: int
    team: TeamInfo
    policy: CoordinationPolicy
    voices: tuple[int, ...] = ()
    planner: str = "paper"  # "improved": re-plan what has not started (ost_ros.planner)
    state: CommState = CommState.LISTENING
    replanned: bool = False  # the improved planner moved tasks not taken up yet
    # Coordinator organisation: objects set aside for the coordinator's next update, and
    # whether that update is the final one.
    awaiting: set[int] = field(default_factory=set)
    closing: bool = False
    # per coordination: its survivors, and each one's selections as Python ints (read once:
    # a peer's selection is checked against them as it comes, 50 a coordination at N=50)
    _selections: dict[int, tuple[tuple[int, ...], dict[int, tuple[int, ...]]]] = field(default_factory=dict)
    _outbox: list[AgentMessage] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.knowledge = Knowledge(self.me, self.team)
        self.voices = self.voices or (self.me,)
        self._init_recovery()

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
        elif self.policy.due_in(t, len(k.unscheduled), self.team):
            self._coordinate(t)

    def _take(self, t: int, msg: AgentMessage) -> None:
        """One message of step ``t``, by kind."""
        k = self.knowledge
        if isinstance(msg, ObjectFound):
            k.note_found(msg.object, msg.t)
        elif isinstance(msg, SearchDone):
            self._search_done(msg)
        elif isinstance(msg, Selection):
            self._check_selection(msg)
        elif isinstance(msg, Status):
            self._status(msg)
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
        expected = mine[1][msg.sender]
        if tuple(msg.objects) != expected:
            self.knowledge.warnings.append(
                f"agent {msg.sender}: selection {list(msg.objects)} in coordination "
                f"{msg.coordination} contradicts the algorithm ({list(expected)}); ignored"
            )

    # ------------------------------------------------------------------ coordination

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
        # each survivor's selections as Python ints, read once (a team model speaks for all N)
        picks = dict(zip(survivors, map(tuple, result.selections.T.tolist())))
        self._selections[k.coordinations] = (survivors, picks)
        self._selections.pop(k.coordinations - _SELECTION_MEMORY, None)
        for voice in self.voices:
            if voice in picks:  # (a robot declared out follows the team's view, selecting nothing)
                self._outbox.append(Selection(voice, t, k.coordinations, picks[voice]))
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

    def _cancel_pending(self, t: int) -> None:
        """A failure: a coordinator's update may never come (the coordinator may be the one that
        died) — its objects go back into the pool; the new coordinator re-plans them."""
        self.knowledge.unscheduled |= self.awaiting
        self.awaiting.clear()
        self.closing = False
        self.state = CommState.RECOVERING

    def _after_recovery(self, t: int) -> None:
        self.state = CommState.LISTENING
        self._coordinate(t)
        self.state = CommState.LISTENING

    @property
    def closed(self) -> bool:
        """All agents have searched and every object is scheduled: nothing more will come."""
        return self.state is CommState.CLOSED
