"""The comm module of an NCP agent: CCP's shared knowledge, but the found objects are allocated
by the slot negotiation of the negotiation library (:mod:`ost_ros.negotiation.slots`, Rossi et
al.'s target-points protocol with n_i slots per object) instead of Algorithm Coordination.

At a coordination point (the same triggers as CCP) every found, unscheduled object is
negotiated; each round is one step: every active agent sends one :class:`NegotiationOffer` in step
t, and everyone reads all of them in step t+1. Once everyone has left, the agreed groups are
ordered by :func:`~ost_ros.coordination.order_groups` (one global order, CA/loc updated as in CCP)
and executed exactly like a CCP schedule. Objects found during a negotiation wait for the next
one (opened at once if a trigger is due).

Comm FSA: LISTENING —(coordination point)→ NEGOTIATING —(everyone left)→ LISTENING;
LISTENING —(every agent searched, nothing unscheduled, no negotiation under way)→ CLOSED.
Any state —(the world's AgentLost)→ RECOVERING —(every survivor's Status)→ LISTENING: a
negotiation under way is called off, what the dead robot held or had claimed and everything not
under way goes back into the pool and is negotiated again among the survivors
(:mod:`ost_ros.protocols.shared.failures`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ost_ros.coordination import CoordinationPolicy, order_groups
from ost_ros.messages import AgentLost, AgentMessage, ObjectFound, SearchDone, Status
from ost_ros.model import arrival_np
from ost_ros.negotiation.messages import NegotiationOffer
from ost_ros.negotiation.slots import NegotiationSettings, SlotNegotiation
from ost_ros.protocols.ccp.messages import Selection
from ost_ros.protocols.shared.failures import Recovery
from ost_ros.protocols.shared.knowledge import Knowledge, QueuedMessages
from ost_ros.team import TeamInfo


class NcpState(str, Enum):
    LISTENING = "LISTENING"
    NEGOTIATING = "NEGOTIATING"  # a negotiation is under way
    RECOVERING = "RECOVERING"  # a robot failed: waiting for every survivor's Status
    CLOSED = "CLOSED"


@dataclass
class NcpComm(Recovery, QueuedMessages):
    """Shared knowledge plus the slot negotiation. ``voices``: the agents whose moves this module
    sends — itself, or everyone when one module computes the whole run (every module holds the
    same public state, so the moves are the same)."""

    me: int
    team: TeamInfo
    policy: CoordinationPolicy
    settings: NegotiationSettings = field(default_factory=NegotiationSettings)
    mute_from: int | None = None  # fault injection: send no negotiation moves from this step
    voices: tuple[int, ...] = ()
    state: NcpState = NcpState.LISTENING
    negotiation: SlotNegotiation | None = None
    negotiations: int = 0
    moves_sent: int = 0
    _outbox: list[AgentMessage] = field(default_factory=list)
    replanned: bool = False  # (CCP's improved planner only)

    def __post_init__(self) -> None:
        self.knowledge = Knowledge(self.me, self.team)
        self.voices = self.voices or (self.me,)
        self._init_recovery()

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None:
        k = self.knowledge
        moves: dict[int, NegotiationOffer] = {}
        for msg in messages:
            if isinstance(msg, ObjectFound):
                k.note_found(msg.object, msg.t)
            elif isinstance(msg, SearchDone):
                self._search_done(msg)
            elif isinstance(msg, NegotiationOffer):
                self._take_move(msg, moves)
            elif isinstance(msg, Selection):
                k.warnings.append(f"agent {msg.sender}: a CCP selection in an NCP run; ignored")
            elif isinstance(msg, Status):
                self._status(msg)
            elif isinstance(msg, AgentLost):
                self._lose(msg.agent, msg.t)
        if self.recovering is not None:
            if self.recovering == t:
                return  # statuses come next step
            self._recover(t)
        if self.state is NcpState.CLOSED:
            return
        if self.negotiation is not None:
            self._negotiate(t, moves)
        if self.negotiation is None:
            all_searched = self.all_searched
            if k.unscheduled and (all_searched or self.policy.due_in(t, len(k.unscheduled), self.team)):
                self._open(t)
            elif all_searched and not k.unscheduled:
                self.state = NcpState.CLOSED
                k.predicted_makespan = k.predict_makespan(t, self.alive)

    def next_event(self, t: int) -> int | None:
        """The first step s >= t in which :meth:`receive` acts with no message (None: never)."""
        k = self.knowledge
        if self.negotiation is not None or self.recovering is not None:
            return t  # a round every step; a recovery
        if self.state is NcpState.CLOSED:
            return None
        if self.all_searched:
            return t
        return self.policy.next_due(t, len(k.unscheduled), self.team)

    def _take_move(self, msg: NegotiationOffer, moves: dict[int, NegotiationOffer]) -> None:
        neg, warn = self.negotiation, self.knowledge.warnings
        if msg.sender not in self.team.agent_ids:
            warn.append(f"negotiation move from agent {msg.sender}, not in the team; ignored")
            return
        if neg is None or msg.negotiation != neg.number or msg.round != neg.round:
            warn.append(
                f"agent {msg.sender}: move for negotiation {msg.negotiation} "
                f"round {msg.round} out of turn; ignored"
            )
            return
        k = self.team.index(msg.sender)
        if k in moves and moves[k] != msg:
            warn.append(f"agent {msg.sender}: two different moves in one round; kept the first")
            return
        moves[k] = msg

    def _open(self, t: int) -> None:
        """A coordination point: negotiate every found, unscheduled object."""
        k = self.knowledge
        survivors = self.alive
        for i in [i for i in k.unscheduled if k.objects[i].required > len(survivors)]:
            k.unscheduled.discard(i)  # fewer robots survive than it needs
            self.impossible.add(i)
        if not k.unscheduled:
            return
        self.state = NcpState.NEGOTIATING
        cost, loc = k.costs(t)
        batch = [k.objects[i] for i in sorted(k.unscheduled)]
        k.unscheduled.clear()
        where = np.array([o.location for o in batch], dtype=np.int64).reshape(-1, 2)
        reach = arrival_np(
            cost[None, :],
            np.abs(where[:, None, :] - loc[None, :, :]).sum(axis=2),
            self.team.period_array()[None, :],
        )
        self.negotiations += 1
        alive = np.array([j not in self.lost for j in self.team.agent_ids], dtype=bool)
        self.negotiation = SlotNegotiation.open(self.negotiations, batch, reach, alive)
        self._send_move(t)

    def _negotiate(self, t: int, moves: dict[int, NegotiationOffer]) -> None:
        neg, k = self.negotiation, self.knowledge
        assert neg is not None
        neg.apply(moves, self.team.agent_ids, self.settings)
        k.warnings.extend(neg.notes)
        neg.notes.clear()
        if not neg.done:
            self._send_move(t)
            return
        # Agreed: every agent orders the same groups the same way (a CCP schedule).
        cost, loc = k.costs(t)
        batch = [k.objects[i] for i in neg.objects]
        result = order_groups(
            self.team.agent_ids, cost, loc, batch, neg.groups(self.team.agent_ids), self.team.speed_periods
        )
        k.assign(result.schedule)
        k.coordinations += 1
        self.negotiation = None
        self.state = NcpState.LISTENING

    def _send_move(self, t: int) -> None:
        neg = self.negotiation
        assert neg is not None
        if self.mute_from is not None and t >= self.mute_from:
            return
        for agent in self.voices:
            i = self.team.index(agent)
            if not neg.active[i]:
                continue
            kind, row = neg.move(i, self.settings)
            ids = tuple(neg.objects[c] for c in np.flatnonzero(row))
            self._outbox.append(NegotiationOffer(agent, t, neg.number, neg.round, kind, ids))
            self.moves_sent += 1

    @property
    def closed(self) -> bool:
        return self.state is NcpState.CLOSED

    # ------------------------------------------------------------------ failures

    def _cancel_pending(self, t: int) -> None:
        """A negotiation under way when a robot failed is called off: its objects go back into
        the pool and are negotiated again among the survivors once their statuses are in."""
        if self.negotiation is not None:
            self.knowledge.unscheduled.update(self.negotiation.objects)
            self.negotiation = None
        self.state = NcpState.RECOVERING

    def _after_recovery(self, t: int) -> None:
        self.state = NcpState.LISTENING
