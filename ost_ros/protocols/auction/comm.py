"""The communication module of an auction agent: market-based allocation, as fleet dispatchers do.

Each found object is auctioned by its finder (the lowest id among the agents that report it in
the step it is first reported):

1. step t: the finder's :class:`ObjectFound` opens the auction (one auction at a time: objects
   found meanwhile wait, lowest id first); every agent takes it in and queues its
   :class:`Bid` — the step it could be at the object (free of its search and of everything it
   has won, then the walk);
2. step t+1: every bid arrives; the auctioneer picks the object's n_i lowest bids (ties: lower
   id) and queues the :class:`Award`;
3. step t+2: the award arrives; every agent appends the object with that group to the schedule,
   timed like any group (it starts when its last member arrives).

Awards are read in one order by everyone (the step, then the auctioneers' id order), and every
agent executes its won objects in that order, so no two groups can wait on each other: no
deadlock. The schedule is the shared :class:`Knowledge` of CCP; what is not the auction —
execution, recovery from a failed robot (every survivor's Status, orphaned sweeps), searched-all
bookkeeping — is CCP's comm module, which this one extends. After a failure, what is not under
way is auctioned again by the lowest surviving id.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from ost_ros.coordination import Assignment, carry_times
from ost_ros.messages import AgentMessage, ObjectFound
from ost_ros.model import arrival, manhattan
from ost_ros.protocols.auction.messages import Award, Bid
from ost_ros.protocols.ccp.comm import CcpComm, CommState


@dataclass
class Auction:
    """One object's auction: who runs it, and the bids in so far (agent -> cost)."""

    auctioneer: int
    opened: int
    bids: dict[int, int] = field(default_factory=dict)


@dataclass
class AuctionComm(CcpComm):
    """The comm module of one auction agent (``voices``: as CCP's)."""

    auctions: dict[int, Auction] = field(default_factory=dict)
    finders: dict[int, int] = field(default_factory=dict)  # object -> its auctioneer (finder)
    awarded: int = 0

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None:
        """Comm module, step ``t``: messages (reports, bids, awards, failures), then the
        auctions this agent runs that have every bid, then new auctions and bids."""
        k = self.knowledge
        for msg in messages:
            if isinstance(msg, ObjectFound):
                # the first report, in the team's id order: the lowest id of the first step
                self.finders.setdefault(msg.object.id, msg.sender)
            if isinstance(msg, Bid):
                self._bid(msg)
            elif isinstance(msg, Award):
                self._award(t, msg)
            else:
                self._take(t, msg)
        if self.recovering is not None:
            if self.recovering == t:
                return  # statuses come next step
            self._recover(t)  # re-auctions what is in the pool (via _coordinate)
        self._decide(t)
        if k.unscheduled:
            self._coordinate(t)
        if (
            self.state is not CommState.CLOSED
            and self.all_searched
            and not self.auctions
            and not k.unscheduled
        ):
            self.state = CommState.CLOSED
            k.predicted_makespan = k.predict_makespan(t, self.alive)

    @property
    def trigger(self) -> str:
        return "auction"

    def next_event(self, t: int) -> int | None:
        """Auctions move only on messages; a recovery or the close happen on their own."""
        if self.recovering is not None:
            return t
        if self.closed:
            return None
        if self.all_searched and not self.auctions and not self.knowledge.unscheduled:
            return t
        return None

    # ------------------------------------------------------------------ the auction

    def _coordinate(self, t: int, final: bool = False) -> None:
        """Open the auction of the first object in the pool (lowest id) and bid on it — one
        auction at a time, so every bid counts what its bidder has won before."""
        k = self.knowledge
        survivors = self.alive
        for i in sorted(k.unscheduled):
            if self.auctions:
                return
            k.unscheduled.discard(i)
            if k.objects[i].required > len(survivors):
                self.impossible.add(i)  # fewer robots survive than it needs
                continue
            finder = self.finders.get(i, -1)
            # the finder runs it; a re-auction (or a finder that died) the lowest survivor
            auctioneer = finder if finder in survivors and i not in self.lost_objects else survivors[0]
            self.auctions[i] = Auction(auctioneer, t)
            k.coordinations += 1
            for voice in self.voices:
                if voice in survivors:
                    self._outbox.append(Bid(voice, t, i, self.bid(voice, i, t)))

    def bid(self, agent: int, obj: int, t: int) -> int:
        """The step ``agent`` could be at ``obj``: free (search done, won objects delivered, from
        step t+1 on) at where its last delivery leaves it, then the walk."""
        k = self.knowledge
        cost, loc = k.costs(t)
        i = self.team.index(agent)
        period = self.team.periods[i] if self.team.periods else 1
        target = k.objects[obj].location
        return arrival(int(cost[i]), manhattan((int(loc[i][0]), int(loc[i][1])), target), period)

    def _bid(self, msg: Bid) -> None:
        auction = self.auctions.get(msg.object)
        if auction is None or msg.sender not in self.team.agent_ids or msg.sender in self.lost:
            self.knowledge.warnings.append(
                f"agent {msg.sender}: bid for object {msg.object}, which is not being auctioned; ignored"
            )
            return
        auction.bids[msg.sender] = msg.cost

    def _decide(self, t: int) -> None:
        """Every auction this agent runs whose bids are all in: award it."""
        for obj, auction in sorted(self.auctions.items()):
            if auction.auctioneer not in self.voices or auction.opened == t:
                continue
            bidders = self._bidders(auction)
            if any(j not in auction.bids for j in bidders):
                continue
            need = self.knowledge.objects[obj].required
            ranked = sorted(bidders, key=lambda j: (auction.bids[j], j))
            self._outbox.append(Award(auction.auctioneer, t, obj, tuple(sorted(ranked[:need]))))

    def _bidders(self, auction: Auction) -> tuple[int, ...]:
        """Whose bids an auction waits for: every survivor."""
        return self.alive

    def _award(self, t: int, msg: Award) -> None:
        """The award of an auction: the group joins the schedule after everything awarded before
        (it starts when its last member can be there)."""
        k = self.knowledge
        auction = self.auctions.get(msg.object)
        o = k.objects.get(msg.object)
        if auction is None or o is None or msg.sender != auction.auctioneer:
            k.warnings.append(
                f"agent {msg.sender}: award of object {msg.object} it does not auction; ignored"
            )
            return
        if len(set(msg.agents)) != o.required or any(j not in self.alive for j in msg.agents):
            k.warnings.append(
                f"agent {msg.sender}: award of object {msg.object} to {list(msg.agents)} "
                f"is not {o.required} live agents; ignored"
            )
            return
        del self.auctions[msg.object]
        # when the last member can be there (order_groups' timing, for one object)
        cost, loc = k.costs(t)
        members = [self.team.index(j) for j in msg.agents]
        periods = [self.team.periods[i] if self.team.periods else 1 for i in members]
        m_p = max(
            arrival(int(cost[i]), manhattan((int(loc[i][0]), int(loc[i][1])), o.location), p)
            for i, p in zip(members, periods)
        )
        start, finish = carry_times(m_p, manhattan(o.location, o.destination), periods)
        k.assign([Assignment(o.id, tuple(sorted(msg.agents)), start, finish)])
        self.awarded += 1

    # ------------------------------------------------------------------ failures

    @property
    def lost_objects(self) -> set[int]:
        """Objects whose auction or award a failure cancelled: the lowest survivor re-auctions."""
        return self._reauction

    def _lose(self, agent: int, t: int) -> None:
        """CCP's recovery, plus: auctions under way are cancelled and their objects go back into
        the pool, to be auctioned again once every survivor's Status is in."""
        k = self.knowledge
        before = {a.object for a in k.assignments}
        super()._lose(agent, t)
        self._reauction |= before - {a.object for a in k.assignments}
        for obj in list(self.auctions):
            k.unscheduled.add(obj)
            self._reauction.add(obj)
        self.auctions.clear()

    def __post_init__(self) -> None:
        super().__post_init__()
        self._reauction: set[int] = set()
