"""The communication module of a CCP agent (paper §3, §4): shared knowledge and coordination.

Every found object is broadcast and stored by every agent. At each coordination point every agent
runs the same :func:`~ost_ros.coordination.coordinate` on the same knowledge, so all agents hold
the same global schedule without negotiating it. Each agent broadcasts its own selections; peers
recompute them and record any disagreement (a faulty or false peer is detected, not obeyed).

Comm FSA: LISTENING —(coordination point)→ COORDINATING → LISTENING;
LISTENING —(all agents finished searching)→ COORDINATING → CLOSED (final schedule known).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ost_msgs_py.messages import ObjectFound, SearchDone, Selection
from ost_ros.coordination import Assignment, CoordinationPolicy, coordinate
from ost_ros.model import ObjectSpec, arrival_np
from ost_ros.team import TeamInfo

# Selections of this many most recent coordinations are kept for cross-checking peers.
_SELECTION_MEMORY = 8


class CommState(str, Enum):
    LISTENING = "LISTENING"
    COORDINATING = "COORDINATING"
    NEGOTIATING = "NEGOTIATING"   # NCP only: a negotiation is under way (ost_ros.ncp)
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
    _selections: dict[int, np.ndarray] = field(default_factory=dict)
    _outbox: list = field(default_factory=list)

    def __post_init__(self) -> None:
        n = self.team.size
        self._lengths = self.team.sweep_lengths()
        self.free_at = np.zeros(n, dtype=np.int64)   # finish of each agent's last scheduled object
        self.free_loc = self.team.sweep_ends()       # where it then stands (sweep end if none)

    # ------------------------------------------------------------------ incoming

    def note_found(self, obj: ObjectSpec, t: int) -> bool:
        """Store an object (sensed or heard of); True if it was new."""
        known = self.objects.get(obj.id)
        if known is None:
            self.objects[obj.id] = obj
            self.found_at[obj.id] = t
            self.unscheduled.add(obj.id)
            return True
        if known != obj:
            self.warnings.append(f"object {obj.id} reported as {obj} but known as {known}; kept")
        return False

    def receive(self, t: int, messages: list) -> None:
        """Comm module, step ``t``: take in every message of the step, then coordinate if due."""
        for msg in messages:
            if isinstance(msg, ObjectFound):
                self.note_found(msg.object, msg.t)
            elif isinstance(msg, SearchDone):
                if msg.sender in self.team.agent_ids:
                    self.searched.add(msg.sender)
            elif isinstance(msg, Selection):
                self._check_selection(msg)
        if self.state is CommState.CLOSED:
            return
        if len(self.searched) == self.team.size:
            self._coordinate(t)
            self.state = CommState.CLOSED
            self.predicted_makespan = self._predict_makespan(t)
        elif self.policy.due(t, len(self.unscheduled), self.team.searched_fraction(t - 1),
                             self.team.searched_fraction(t)):
            self._coordinate(t)

    def _check_selection(self, msg: Selection) -> None:
        if msg.sender == self.me or msg.sender not in self.team.agent_ids:
            return
        mine = self._selections.get(msg.coordination)
        if mine is None:
            self.warnings.append(f"agent {msg.sender}: selection for unknown coordination "
                                 f"{msg.coordination}; ignored")
            return
        expected = tuple(int(x) for x in mine[:, self.team.index(msg.sender)])
        if tuple(msg.objects) != expected:
            self.warnings.append(f"agent {msg.sender}: selection {list(msg.objects)} in coordination "
                                 f"{msg.coordination} contradicts the algorithm ({list(expected)}); "
                                 "ignored")

    # ------------------------------------------------------------------ coordination

    def costs(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """CA_j and loc_j for a coordination in step t: the schedule applies from step t+1."""
        return np.maximum(np.maximum(self.free_at, self._lengths), t + 1), self.free_loc.copy()

    def _coordinate(self, t: int) -> None:
        if not self.unscheduled:
            return
        self.state = CommState.COORDINATING
        cost, loc = self.costs(t)
        batch = [self.objects[i] for i in sorted(self.unscheduled)]
        result = coordinate(self.team.agent_ids, cost, loc, batch, self.team.speed_periods)
        for a in result.schedule:
            members = [self.team.index(j) for j in a.agents]
            self.free_at[members] = a.finish
            self.free_loc[members] = self.objects[a.object].destination
        self.schedule.extend(result.schedule)
        self.unscheduled.clear()
        self.coordinations += 1
        self._selections[self.coordinations] = result.selections
        self._selections.pop(self.coordinations - _SELECTION_MEMORY, None)
        mine = tuple(int(x) for x in result.selections[:, self.team.index(self.me)])
        self._outbox.append(Selection(self.me, t, self.coordinations, mine))
        self.state = CommState.LISTENING

    def _predict_makespan(self, t: int) -> int:
        cost, loc = self.costs(t)
        bases = np.array(self.team.bases, dtype=np.int64).reshape(-1, 2)
        return int(np.max(arrival_np(cost, np.abs(loc - bases).sum(axis=1), self.team.period_array())))

    @property
    def closed(self) -> bool:
        """All agents have searched and every object is scheduled: nothing more will come."""
        return self.state is CommState.CLOSED

    def drain(self) -> list:
        out, self._outbox = self._outbox, []
        return out
