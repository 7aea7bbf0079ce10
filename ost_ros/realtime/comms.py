"""The shared-schedule comm modules (CCP, NCP, the auction) without a barrier: each waits for
what it needs by stamp instead of assuming "sent in step t, read in t+1", so that what it
computes is a function of the stamped batches alone. In lockstep every awaited reply is in the
next batch, and these modules compute what the lockstep ones do (tested: at latency 0 a run
equals ``ost sim``).

- Recovery (:class:`RtRecovery`, every protocol): the world's stamped notice starts it; every
  survivor's body stops what is not under way and reports a :class:`RtStatus` (where and when it
  is free, how many of its schedule entries are done or under way); recovery completes in the
  first batch that holds every survivor's status for this failure. What is kept of the schedule
  is computed from those statuses and the notice's facts (what the dead robot delivered, where it
  dropped its load, where its counted sensing ends) — never from predicted times, which a late
  robot does not keep.
- CCP's coordinator organisation: no coordination starts while the coordinator's update is
  awaited (it comes when it comes, not the next step).
- NCP: a round completes in the first batch holding every active negotiator's move (or, for a
  silent one, once ``round_deadline`` steps have passed since the round opened: a deterministic
  time-out counted in stamps).
- The auction already waits for every bid and for the award; only its recovery changes.
- CCP keeps every coordination's selections for cross-checking (a peer's may come many
  coordinations later).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ost_ros.model import Cell, moves_between
from ost_ros.protocols.auction.comm import Auction, AuctionComm
from ost_ros.protocols.ccp.comm import CcpComm, CommState
from ost_ros.protocols.greedy.comm import GreedyComm
from ost_ros.protocols.ncp.comm import NcpComm
from ost_ros.protocols.shared.knowledge import Knowledge
from ost_ros.protocols.shared.recovery import Sweep
from ost_ros.realtime.messages import (
    AgentMessage,
    Award,
    Back,
    Bid,
    Lost,
    NegotiationOffer,
    RtStatus,
    ScheduleUpdate,
    Status,
)
from ost_ros.team import TeamInfo

_MOOT = (NegotiationOffer, Bid, Award, ScheduleUpdate)  # what a failure cancels in flight


class RtRecovery:
    """Recovery from a failed robot without a barrier (mixed in before the protocol's comm class,
    whose :class:`~ost_ros.protocols.shared.failures.Recovery` it replaces)."""

    me: int
    team: TeamInfo
    knowledge: Knowledge
    lost: dict[int, int]
    statuses: dict[int, Status]
    orphans: list[tuple[Cell, ...]]
    impossible: set[int]
    owed: dict[int, int]
    reset: bool
    _alive: tuple[int, ...] | None

    def _init_recovery(self) -> None:
        self._recovering: int | None = None
        self._batch = -1
        self._notice: dict[int, Lost] = {}
        self._dead_delivered: set[int] = set()
        self._dead_drops: dict[int, Cell] = {}
        self.kept_len: int | None = None  # schedule length after the last recovery's pruning
        self.moot = 0  # messages a failure made moot before they arrived
        # The failures taken in since the last completed recovery, and the sweeps they orphaned,
        # keyed so that they are handed out in the order the lockstep module would have them
        self._episode: list[tuple[int, int]] = []  # (stamp, agent), in the order taken in
        self._keyed: list[tuple[tuple[int, int, int], tuple[Cell, ...]]] = []
        self.recovered = False  # a recovery completed (the body resyncs its task list)
        self.losses = 0  # notices taken in (a status answers the count; never decreases)
        self._last_loss = -1  # the stamp of the last notice taken in
        self.incarnation: dict[int, int] = {}  # agent -> its life now (0 unless it came back)
        self.rejoined: dict[int, int] = {}  # agent -> the stamp of its last Back
        # agent -> the schedule's entries when it came back (what is left of them later is what
        # it found planned: a re-plan or a recovery in the same batch drops and appends entries)
        self.rejoin_old: dict[int, list] = {}
        self.joins = 0  # rejoins taken in
        super()._init_recovery()  # type: ignore[misc]

    # The lockstep modules read ``recovering == t`` as "statuses come in a later batch": so it
    # reads the current batch until every survivor's status for the failure is in.
    @property
    def recovering(self) -> int | None:
        if self._recovering is None:
            return None
        return self._recovering if self._statuses_in() else self._batch

    @recovering.setter
    def recovering(self, value: int | None) -> None:
        self._recovering = value

    def _statuses_in(self) -> bool:
        return all(j in self.statuses for j in self.alive if not self._exempt(j))

    def rejoin_len(self, j: int) -> int:
        """How many entries at the head of the schedule were planned before robot j came back
        (kept entries keep their order and everything planned since comes after them)."""
        old = {id(e) for e in self.rejoin_old.get(j, ())}  # (alive: the list holds them)
        return sum(1 for e in self.knowledge.schedule if id(e) in old)

    def _exempt(self, j: int) -> bool:
        """A robot back since the recovery under way began: it has nothing of the schedule to
        keep (what is left of its old life there is pruned or kept by the others' statuses), so
        no status of it is due or counted."""
        return bool(self._episode) and self.rejoined.get(j, -1) >= self._episode[0][0]

    def cross_check(self, msg: AgentMessage) -> None:
        """A message that joins no batch (a cross-check, :attr:`AgentMessage.SHARED`): the
        protocols that send one say what to do with it."""

    @property
    def alive(self) -> tuple[int, ...]:  # (Recovery's; declared for the type checker)
        return super().alive  # type: ignore[misc]

    def _enter(self, t: int, messages: Sequence[AgentMessage]) -> list[AgentMessage]:
        """A batch begins: its stamp, the failure notices it holds (for ``_lose``), and its
        messages without those a failure already taken in has made moot: a move, bid, award or
        coordinator's update made before the sender could know of it (in lockstep it would have
        been read before the failure; here it may arrive after, and is dropped alike by all)."""
        self._batch = t
        for m in messages:
            if isinstance(m, Lost):
                self._notice[m.agent] = m
            elif isinstance(m, Back):
                self._rejoin(t, m)
        cut = self._last_loss
        keep = [m for m in messages if not (isinstance(m, _MOOT) and m.t < cut)]
        self.moot += len(messages) - len(keep)
        return keep

    def _rejoin(self, t: int, msg: Back) -> None:
        """Robot ``msg.agent``, out, is a member again from batch t + 1 (the first Back of its
        next life; the others are duplicates): free at t + 1 where its base stands, its search
        over (its cells went to others when it was declared), objects that had too few robots
        for them back in the pool if it makes enough."""
        j = msg.agent
        if j not in self.lost or msg.incarnation != self.incarnation.get(j, 0) + 1:
            return
        del self.lost[j]
        self._alive = None
        self.incarnation[j] = msg.incarnation
        self.rejoined[j] = t
        self.rejoin_old[j] = list(self.knowledge.schedule)  # what it finds planned (not its own)
        self.joins += 1
        k, i = self.knowledge, self.team.index(j)
        self.owed[j] = 0
        k.searched.add(j)
        k.free_at[i] = k.base_at[i] = t + 1
        k.free_loc[i] = k.base_loc[i] = msg.at
        k.lengths[i] = min(k.lengths[i], t + 1)
        n = len(self.alive)
        back = {o for o in self.impossible if k.objects[o].required <= n}
        if back:
            self.impossible -= back
            k.unscheduled |= back
            self._reopened(t)

    def _reopened(self, t: int) -> None:
        """Objects that were impossible are back in the pool: a comm that had closed listens
        again (it plans them at its next coordination point)."""
        state = getattr(self, "state", None)
        if state is not None and state.value == "CLOSED":
            self.state = type(state)("LISTENING")

    def _status(self, msg: Status) -> None:
        if (
            isinstance(msg, RtStatus)
            and msg.sender in self.team.agent_ids
            and msg.sender not in self.lost
            and msg.failure == self.losses
            and not self._exempt(msg.sender)
        ):
            self.statuses[msg.sender] = msg

    def sweeps_of(self, agent: int) -> list[Sweep]:
        return super().sweeps_of(agent)  # type: ignore[misc]

    def _lose(self, agent: int, t: int) -> None:
        """The notice of ``agent``'s failure, stamped t: its unsensed cells become orphaned sweeps
        (from where its counted sensing ends), and everyone waits for the survivors' statuses;
        the schedule is pruned only then, from facts."""
        if agent not in self.team.agent_ids or agent in self.lost:
            return
        k = self.knowledge
        notice = self._notice.get(agent)
        before, rank = list(self._episode), sum(1 for f, _ in self._episode if f == t)
        self._episode.append((t, agent))
        self.losses += 1
        self._last_loss = max(self._last_loss, t)
        self.lost[agent] = t
        self._alive = None
        k.searched.discard(agent)
        if self.owed[agent] > 0:
            sweeps = self.sweeps_of(agent)
            first = len(sweeps) - self.owed[agent]  # its sweeps are done in order
            period = self.team.periods[self.team.index(agent)] if self.team.periods else 1
            for i, sw in enumerate(sweeps[first:]):
                rest = (
                    _remainder(sw, t, period, notice.at if notice else None) if i == 0 else sw.path[sw.walk :]
                )
                if not rest:
                    continue
                # a take-over not begun by an earlier failure of this recovery was, in lockstep
                # terms, put back into the pool then (as a survivor's): keyed so
                early = [f for f, _ in before if sw.start > f] if sw is not sweeps[0] else []
                key = (min(early), 1, self._position(sw)) if early else (t, 2 * rank, i)
                self._keyed.append((key, tuple(rest)))
        self.owed[agent] = 0
        if notice is not None:
            self._dead_delivered.update(notice.delivered)
            for o in notice.dropped:
                self._dead_drops[o.id] = o.location
        k.predicted_makespan = None
        self.recovering = t
        self.statuses.clear()
        self.reset = True
        self._cancel_pending(t)  # type: ignore[attr-defined]

    def _position(self, sw: Sweep) -> int:
        sched = self.knowledge.schedule
        return next((p for p, e in enumerate(sched) if e is sw), len(sched))

    def _pruned(self, objects: list[int]) -> None:
        """Objects a recovery took out of the schedule (for protocols that care)."""

    def _recover(self, t: int) -> None:
        """Every survivor's status is in: keep what is done or under way (by the statuses and
        the notices), put the rest back into the pool (dropped loads from where they lie), then
        hand out the orphaned sweeps and let the protocol plan the pool."""
        k = self.knowledge
        survivors = self.alive
        own: dict[int, list[int]] = {}
        for pos, e in enumerate(k.schedule):
            for j in e.agents:
                own.setdefault(j, []).append(pos)
        kept: set[int] = set()
        for j in survivors:
            st = self.statuses.get(j)
            kept.update(own.get(j, [])[: st.keep if isinstance(st, RtStatus) else 0])
        removed: list[int] = []
        for pos, e in enumerate(k.schedule):
            if pos in kept:
                continue
            if isinstance(e, Sweep):
                if e.agent not in self.lost:  # a survivor's take-over not begun: back to the pool
                    early = [f for f, _ in self._episode if e.start > f]
                    key = (min(early) if early else self._episode[-1][0], 1, pos)
                    self._keyed.append((key, tuple(e.path[e.walk :])))
                    self.sweeps_of(e.agent).remove(e)
                    self.owed[e.agent] -= 1
                    if self.owed[e.agent] == 0:
                        k.searched.add(e.agent)
                continue
            if e.object in self._dead_delivered:
                kept.add(pos)  # delivered (a notice says so): done, whoever is left of its group
                continue
            cell = self._dead_drops.get(e.object)
            o = k.objects[e.object]
            if cell is not None and cell != o.location:
                k.drops[e.object] = cell
                k.objects[e.object] = replace(o, location=cell)
            k.unscheduled.add(e.object)
            removed.append(e.object)
        k.schedule[:] = [e for pos, e in enumerate(k.schedule) if pos in kept]
        self.kept_len = len(k.schedule)
        self.recovered = True
        self._pruned(removed)
        for j, st in self.statuses.items():
            i = self.team.index(j)
            k.free_at[i] = st.free_at
            k.free_loc[i] = st.location
            k.lengths[i] = min(k.lengths[i], st.free_at)
        k.rebase()
        self.orphans.extend(cells for _, cells in sorted(self._keyed, key=lambda kc: kc[0]))
        self._keyed.clear()
        self._episode.clear()
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
        self._after_recovery(t)  # type: ignore[attr-defined]


def _remainder(sw: Sweep, t: int, period: int, at: Cell | None) -> tuple[Cell, ...]:
    """The cells of ``sw`` its robot, failed with its counted sensing ending at cell ``at``
    (at step t), may not have reported: from ``at`` on. Of several visits of ``at`` the first:
    a robot is never ahead of its sweep's prediction, but it may be far behind it (it came back
    from out with the sweep given to it at its readmission, taken up much later than planned),
    so only the first visit is sure not to skip cells it never sensed."""
    path = sw.path
    guess = moves_between(sw.start, t, period) if t > sw.start else 0
    if at is None:
        i = guess
    else:
        i = next((i for i, c in enumerate(path) if c == at), -1)
        if i < 0:
            return tuple(path[sw.walk :])
    return tuple(path[max(min(i, len(path) - 1), sw.walk) :])


@dataclass
class RtCcpComm(RtRecovery, CcpComm):
    """CCP's comm module without a barrier."""

    _all_selections: dict[int, tuple[tuple[int, ...], dict[int, tuple[int, ...]]]] = field(
        default_factory=dict
    )
    _early: dict[int, list[AgentMessage]] = field(default_factory=dict)  # coordination -> selections

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None:
        messages = self._enter(t, messages)
        k = self.knowledge
        for msg in messages:
            self._take(t, msg)
        if self.recovering is not None:
            if self.recovering == t:
                return  # statuses still to come
            self._recover(t)
        if self.state is CommState.CLOSED or self.closing:
            return
        if self.policy.centralised and self.awaiting:
            return  # the coordinator's update is under way: nothing starts before it is in
        if self.all_searched:
            self._coordinate(t, final=True)
            if self.awaiting:
                self.closing = True
            elif not self.closing:
                self.state = CommState.CLOSED
                k.predicted_makespan = k.predict_makespan(t, self.alive)
        elif self.policy.due_in(t, len(k.unscheduled), self.team):
            self._coordinate(t)

    def next_event(self, t: int) -> int | None:
        if self._recovering is not None or (self.policy.centralised and self.awaiting):
            return None  # statuses, an update: it waits for messages
        return super().next_event(t)

    def _adopt(self, t: int, msg: ScheduleUpdate) -> None:
        super()._adopt(t, msg)
        if self.state is CommState.CLOSED and self.knowledge.unscheduled:
            # a robot came back while the final update was on its way, and with it objects that
            # had been impossible: the comm is not closed, it plans them next
            self.state, self.closing = CommState.LISTENING, False

    @property
    def coordinator(self) -> int:
        """The lowest-id survivor that never came back: a robot readmitted does not take the role
        over (an update under way would then be another's), only a failure moves it."""
        stayed = [j for j in self.alive if j not in self.rejoined]
        return stayed[0] if stayed else self.alive[0]

    def _coordinate(self, t: int, final: bool = False) -> None:
        before = self.knowledge.coordinations
        super()._coordinate(t, final)
        c = self.knowledge.coordinations
        if c != before and c in self._selections:
            self._all_selections[c] = self._selections[c]
            for msg in self._early.pop(c, []):
                self._check_selection(msg)

    def cross_check(self, msg: AgentMessage) -> None:
        """A peer's Selection, as it comes (it is in no batch): checked against this robot's own
        coordination of that number — now, or once this robot has computed it."""
        c = getattr(msg, "coordination", 0)
        if c > self.knowledge.coordinations:
            self._early.setdefault(c, []).append(msg)
        else:
            self._check_selection(msg)

    def _check_selection(self, msg) -> None:
        c = msg.coordination
        if c not in self._selections and c in self._all_selections:
            self._selections[c] = self._all_selections[c]  # an old one: looked up again
        super()._check_selection(msg)


@dataclass
class RtGreedyComm(RtRecovery, GreedyComm):
    """Greedy dispatch without a barrier. The dispatch is a function of public knowledge (the
    finds, the search ends, the schedule it has dispatched, the statuses after a failure), so
    taken batch by batch it is the same on every robot; a quiet step it acts in (a robot's
    predicted delivery frees it for the queue's head) is a comm event (:meth:`next_event`),
    stamped like a batch. "Free" is the schedule's prediction, as in lockstep: a robot late on
    it is dispatched all the same and its group waits for it — every robot executes its
    entries in the one global order, so nobody holds forever."""

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None:
        super().receive(t, self._enter(t, messages))

    def next_event(self, t: int) -> int | None:
        if self._recovering is not None:
            return None  # statuses: it waits for messages
        return super().next_event(t)


@dataclass
class RtNcpComm(RtRecovery, NcpComm):
    """NCP's comm module without a barrier: rounds complete on moves, not on steps."""

    round_deadline: int = 1000  # steps a round waits for a silent negotiator (the time-out)
    _moves: dict[int, NegotiationOffer] = field(default_factory=dict)
    _opened: int = 0  # the stamp the current round opened at

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None:
        super().receive(t, self._enter(t, messages))

    def _open(self, t: int) -> None:
        self._moves = {}
        self._opened = t
        super()._open(t)

    def _negotiate(self, t: int, moves: dict[int, NegotiationOffer]) -> None:
        neg = self.negotiation
        assert neg is not None
        for key, m in moves.items():
            self._moves.setdefault(key, m)
        waiting = [int(i) for i in np.flatnonzero(neg.active) if self.team.agent_ids[int(i)] not in self.lost]
        if any(i not in self._moves for i in waiting) and t < self._opened + self.round_deadline:
            return  # the round is not complete
        moves, self._moves = self._moves, {}
        self._opened = t
        super()._negotiate(t, moves)

    def next_event(self, t: int) -> int | None:
        if self._recovering is not None:
            return None
        if self.negotiation is not None:
            return max(t, self._opened + self.round_deadline)  # the time-out, if nobody moves
        return super().next_event(t)


@dataclass
class RtAuctionComm(RtRecovery, AuctionComm):
    """The auction's comm module without a barrier: bids and awards already wait by content; an
    auctioneer awards once (in lockstep its award is read the next step, before it could decide
    again; here more batches may pass before its award comes back)."""

    _awarding: set[int] = field(default_factory=set)  # auctions it has sent the award of

    def _decide(self, t: int) -> None:
        sent = {o: self.auctions.pop(o) for o in list(self.auctions) if o in self._awarding}
        before = len(self._outbox)
        super()._decide(t)
        self.auctions.update(sent)
        self._awarding.update(m.object for m in self._outbox[before:] if isinstance(m, Award))
        self._awarding &= set(self.auctions)

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None:
        super().receive(t, self._enter(t, messages))

    def _lose(self, agent: int, t: int) -> None:
        if agent not in self.team.agent_ids or agent in self.lost:
            return
        k = self.knowledge
        super()._lose(agent, t)
        for obj in list(self.auctions):  # auctions under way: back into the pool, re-auctioned
            k.unscheduled.add(obj)
            self._reauction.add(obj)
        self.auctions.clear()
        self._awarding.clear()

    def _pruned(self, objects: list[int]) -> None:
        self._reauction.update(objects)

    def _bidders(self, auction: Auction) -> tuple[int, ...]:
        """Survivors that were members when it opened (a robot back since bid on nothing)."""
        return tuple(j for j in self.alive if self.rejoined.get(j, -1) <= auction.opened)

    def next_event(self, t: int) -> int | None:
        if self._recovering is not None:
            return None
        return super().next_event(t)
