"""The communication module of a greedy agent: nearest-robot dispatch, the usual baseline of
multi-robot task allocation (docs/interpretation.md, "Greedy dispatch").

Every found object is broadcast (:class:`ObjectFound`) and queued, in the order it was found
(ties: lower id). The queue's head goes, at once, to the n_i *free* robots nearest to it — free:
its search is done and everything it was given is delivered, so it could set off in the next
step (CA_j ≤ t+1 in the shared :class:`Knowledge`); nearest: the earliest to be there from where
it stands, ties to the lower id. An object that finds too few free robots waits, and so does
everything queued behind it (first come, first served); it goes the step its n_i-th robot is
free — a step with no message, so :meth:`GreedyComm.next_event` names it. No coordination
point, no schedule ahead: a robot holds at most one object.

Every input is public (the finds, the search ends, the schedule), so every agent computes the
same dispatch and no message of its own is needed. Execution, the searched-all bookkeeping and
recovery from a failed robot are CCP's comm module, which this one extends (after a failure,
what is not under way goes back into the queue, in its found order).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ost_ros.coordination import Assignment, carry_times
from ost_ros.messages import AgentMessage
from ost_ros.model import Cell, arrival, manhattan
from ost_ros.protocols.ccp.comm import CcpComm, CommState


@dataclass
class GreedyComm(CcpComm):
    """The comm module of one greedy agent (``voices``: as CCP's)."""

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None:
        """Comm module, step ``t``: take in the step's messages, then dispatch what can go."""
        k = self.knowledge
        for msg in messages:
            self._take(t, msg)
        if self.recovering is not None:
            if self.recovering == t:
                return  # statuses come next step
            self._recover(t)  # dispatches (via _after_recovery)
        self._coordinate(t)
        if self.state is not CommState.CLOSED and self.all_searched and not k.unscheduled:
            self.state = CommState.CLOSED
            k.predicted_makespan = k.predict_makespan(t, self.alive)

    @property
    def trigger(self) -> str:
        return "greedy"

    def queue(self) -> list[int]:
        """The objects waiting for robots, first found first (ties: lower id)."""
        k = self.knowledge
        return sorted(k.unscheduled, key=lambda i: (k.found_at[i], i))

    def next_event(self, t: int) -> int | None:
        """The first step s >= t in which :meth:`receive` acts with no message: a recovery, the
        close, or the step the queue's head has its n_i-th free robot (robots become free at
        the end of their search and at a delivery, which no message announces)."""
        if self.recovering is not None:
            return t
        if self.closed:
            return None
        queue = self.queue()
        if not queue:
            return t if self.all_searched else None  # the close; else a find must come first
        k = self.knowledge
        need = k.objects[queue[0]].required
        survivors = self.alive
        if need > len(survivors):
            return t  # it cannot be moved any more: dropped at once
        idx = [self.team.index(j) for j in survivors]
        ready = sorted(max(int(k.free_at[i]), int(k.lengths[i])) for i in idx)
        return max(t, ready[need - 1] - 1)  # free in step s: ready by s + 1

    def _coordinate(self, t: int, final: bool = False) -> None:
        """Dispatch from the head of the queue while its n_i nearest free robots exist."""
        k = self.knowledge
        survivors = self.alive
        cost, _ = k.costs(t)
        free = [j for j in survivors if int(cost[self.team.index(j)]) == t + 1]
        for i in self.queue():
            o = k.objects[i]
            if o.required > len(survivors):
                k.unscheduled.discard(i)
                self.impossible.add(i)  # fewer robots survive than it needs
                continue
            if o.required > len(free):
                return  # first come, first served: the rest waits behind it
            there = {j: self._there(j, o.location, t) for j in free}
            group = sorted(free, key=lambda j: (there[j], j))[: o.required]
            start, finish = carry_times(
                max(there[j] for j in group), manhattan(o.location, o.destination), self._periods(group)
            )
            k.assign([Assignment(o.id, tuple(sorted(group)), start, finish)])
            k.unscheduled.discard(i)
            k.coordinations += 1
            free = [j for j in free if j not in group]

    def _there(self, agent: int, target: Cell, t: int) -> int:
        """When ``agent``, free from step t+1 where its last task left it, can be at ``target``."""
        m = self.team.index(agent)
        at = self.knowledge.free_loc[m]
        return arrival(t + 1, manhattan((int(at[0]), int(at[1])), target), self._periods([agent])[0])

    def _periods(self, agents: Sequence[int]) -> list[int]:
        periods = self.team.periods
        return [periods[self.team.index(j)] if periods else 1 for j in agents]
