"""HCP without a barrier: the help-based protocol's agent as a realtime body, its knowledge of
requests and offers fed batch by batch (docs/realtime.md, "HCP without a barrier").

HCP's decisions are each robot's own — an owner asks for help, an available robot offers, a
requester withdraws for a request of higher priority — taken on what it has read so far. In
lockstep everyone has read the same; without a barrier a robot may decide on a stale view. So the
shared part — which requests are open, which offers stand, which groups are formed — is a
function of the stamped batches alone, taken in stamp order by every robot, and a decision
counts only if it is still sound where its stamp puts it:

- a withdrawal (:class:`HelpRelease`) closes the request only if it is still open then: a
  request staffed in a batch its requester had not read is carried all the same (the requester
  reads it, holds, and its partners come);
- an offer counts only if its sender was not put in a group after the last batch it had read
  (:attr:`HelpOffer.view`): it is busy there, and the offer lapses for everyone alike;
- a robot with an offer out starts none of its own objects until a batch at or past the offer's
  stamp says whether it stands (the lockstep agent's rule, with "answered" read by stamp).

Everything else is the lockstep agent's (:mod:`ost_ros.protocols.hcp.agent`), driven by the
runtime of :mod:`ost_ros.realtime.agent` as the schedule agents are: goals to its base, a
decision at each goal's end, each detection and each batch.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar

from ost_ros.messages import AgentLost, AgentMessage
from ost_ros.model import Cell
from ost_ros.protocols.hcp.agent import WAIT, Action3, HcpAgent, HcpState
from ost_ros.protocols.hcp.comm import HcpComm, HelpGroup
from ost_ros.protocols.hcp.messages import HelpOffer, HelpRelease, HelpRequest
from ost_ros.realtime.agent import EPS, RealtimeAgent
from ost_ros.realtime.messages import ObjectInfo
from ost_ros.realtime.world import ABORTED, REFUSED, Carry, Detection, Feedback, GoalResult
from ost_ros.search import SearchModule, route


class RtHcpComm(HcpComm):
    """HCP's knowledge without a barrier: a batch at a time (the world's stamped notice is a
    failure as the lockstep's); it has nothing of its own to say and no comm event."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.incarnation: dict[int, int] = {}  # (no robot comes back under HCP: always 0)
        self.dropped: dict[int, ObjectInfo] = {}  # the batch's notices: where their loads lie

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> list[HelpGroup]:
        # the realtime notice is a subclass: taken in as the lockstep's (by kind)
        msgs = [_as_lost(m) if isinstance(m, AgentLost) else m for m in _withdrawn(messages)]
        self.dropped = {o.id: o for m in msgs if isinstance(m, AgentLost) for o in m.dropped}
        return super().receive(t, msgs)

    def next_event(self, t: int) -> int | None:
        return None

    def drain(self) -> list[AgentMessage]:
        return []

    def cross_check(self, msg: AgentMessage) -> None:
        """Nothing of HCP's is a cross-check (its accept joins a batch)."""


def _withdrawn(messages: Sequence[AgentMessage]) -> list[AgentMessage]:
    """The batch without each request its sender withdrew in the same batch (a batch holds a
    sender's messages in the order it sent them; the lockstep comm takes withdrawals before
    requests, which in lockstep never share a step)."""
    asked: dict[tuple[int, int], int] = {}  # (sender, object) -> index of its request
    gone: set[int] = set()
    for k, m in enumerate(messages):
        if isinstance(m, HelpRequest):
            asked[(m.sender, m.object.id)] = k
        elif isinstance(m, HelpRelease) and (m.sender, m.object) in asked:
            gone.update((asked.pop((m.sender, m.object)), k))
    return [m for k, m in enumerate(messages) if k not in gone] if gone else list(messages)


def _as_lost(m: AgentLost) -> AgentLost:
    return m if type(m) is AgentLost else AgentLost(m.agent, m.t, m.dropped)


class RtHcpAgent(HcpAgent):
    """The HCP agent as a realtime body: its offers are answered by stamp, its finds are its own
    (never broadcast), a group broken by a failure is fetched where the notice says it lies."""

    protocol = "hcp"
    comm: RtHcpComm

    def __init__(self, agent_id: int, team: Any) -> None:
        super().__init__(agent_id, team)
        self.comm = RtHcpComm(agent_id, team)
        self.offer_stamp = -1  # the stamp of its last offer (its runtime says, as it sends it)
        self.period = 1  # (HCP's teams are of unit speed)
        self.reroute = False  # an inherited sweep to route from where it is at its next decision
        self._read_at: Cell = self.position
        self.moved_on = 0  # inherited sweeps routed from a cell other than where it read the notice
        self.walked_back = 0  # holds that came after its base had moved past the object
        self.view = -1  # no batch read yet
        # Its base's events are in up to here (its runtime says, when they cross a network): it
        # says its part is done only once they are, each find on the way claimed first
        self.sensed_until = math.inf
        self.part_wait: int | None = None  # the step its "part done" waits for them
        # The object its base last lifted, as its runtime knows (its base across a network: a
        # hold may come too late, and where the base went says nothing of a carry); None: unused
        self.lifted: int | None = None
        self.holding = -1  # the object its base holds or carries now (its runtime says)

    def _read_up_to(self, t: int) -> None:
        """(Its runtime says what it has read: the batches taken, not the step.)"""

    def report_late(self, t: int, sensed: Sequence[ObjectInfo]) -> list[AgentMessage]:
        """Its own objects its base sensed at step ``t`` (heard of late: it may be doing
        something else by now): claimed now — HCP's finds are private, nothing to say."""
        for o in sensed:
            if self.news(o):
                self._claim(self.comm.fallen.get(o.id, o), t)
        return []

    def body_messages(self) -> list[AgentMessage]:
        return self.outbox()

    def communicate(self, t: int, messages: Sequence[AgentMessage]) -> None:
        self.view = t  # (what it says while reading this batch is decided on it)
        offering = self.offering
        super().communicate(t, messages)
        if offering is not None and self.offering is None and t < self.offer_stamp:
            self.offering = offering  # not answered: the batch of its offer is still to come

    def let_go(self, obj: int, why: str) -> None:
        """Its base could not lift ``obj`` (``why``): it is not its to carry any more. A carry
        of its own that is over (its result came after the feedback it decided on) says nothing;
        anything else is a warning."""
        if self.current is None or self.current.id != obj:
            return
        if not (self.state is HcpState.MOVING and why.startswith("delivered")):
            self.comm.warnings.append(f"agent {self.id}: object {obj} let go, {why}")
        self.current, self.helping = None, False
        self.state = HcpState.DECISION

    def _deciding(self) -> Action3 | None:
        if (
            self.sweep_done
            and not self.part_done_sent
            and self.offering is None
            and not self.own
            and (self.t if self.part_wait is None else self.part_wait) > self.sensed_until
        ):
            if self.part_wait is None:  # a find on the way may still come: not done yet
                self.part_wait = self.t
            return WAIT
        self.part_wait = None
        return super()._deciding()

    def _carrying(self) -> Action3 | None:
        obj = self.current
        if (
            self.lifted is not None
            and obj is not None
            and self.lifted != obj.id
            and self.position != obj.location
        ):
            # its base moved on without it (a hold came after its base had left, as over a
            # network): nothing is carried — back to it (not "delivered on arrival")
            self.walk_back(obj.id)
            return None
        return super()._carrying()

    def _fetching(self) -> Action3 | None:
        cur = self.current
        if cur is not None and cur.id in self.unsure and self.holding == cur.id:
            # its base holds it (it held it for the dead requester): it lies here — what a
            # picture of a hold says it senses is nothing (its base says that with a result)
            self.unsure.discard(cur.id)
        return super()._fetching()

    _STEP: ClassVar[dict[HcpState, Callable[[HcpAgent], Action3 | None]]] = {
        **HcpAgent._STEP,
        HcpState.FETCHING: _fetching,  # type: ignore[dict-item]
        HcpState.DECISION: _deciding,  # type: ignore[dict-item]
        HcpState.WAITING: _carrying,  # type: ignore[dict-item]
        HcpState.MOVING: _carrying,  # type: ignore[dict-item]
    }

    def walk_back(self, obj: int) -> None:
        """Its hold of ``obj`` came after its base had moved on past the object (as its goal
        crosses a network): back to the object, then hold it (the walk of a helper arriving)."""
        if self.current is not None and self.current.id == obj and self.state in _GROUP_HOLD:
            self.state = HcpState.HELPING
            self.walked_back += 1

    def _inherit(self, lost: AgentLost, parts: tuple[int, ...], t: int) -> None:
        """As the lockstep agent's, but a robot whose sweep was done routes the inherited one
        from where it is at its next decision (:meth:`resume_at`), not from where it last
        decided (the lockstep agent reads a batch where it stands)."""
        done, self.sweep_done = self.sweep_done, False
        super()._inherit(lost, parts, t)
        self.sweep_done, self.reroute = done, done
        self._read_at = self.position

    def resume_at(self, cell: Cell) -> None:
        """A decision where ``cell`` is: the inherited sweep is routed from here."""
        if self.reroute:
            self.reroute = False
            self.search = SearchModule(route([cell] + self.sweeps_left.pop(0)))
            self.sweep_done = False
            # (the lockstep agent routes from where it stood when it read the notice, walking
            # back if it has moved since: counted, as the one way the two runs part at latency 0)
            self.moved_on += cell != self._read_at

    def _group_broken(self, t: int, dead: int, g: HelpGroup) -> None:
        """As the lockstep agent's, but the object lies where the notice says (a load the dead
        robot held or carried is dropped with it) — its own picture of where it is may be old."""
        fallen = self.comm.dropped.get(g.object)
        if (
            fallen is not None
            and self.current is not None
            and self.current.id == g.object
            and not self.helping
            and self.comm.requester.get(g.object) == self.id
        ):
            self.current = replace(self.current, location=fallen.location)
            self.comm.objects[g.object] = self.current
            self.state = HcpState.FETCHING
            return
        if self.state is HcpState.MOVING:
            self.state = HcpState.WAITING  # (no load moved without the dead robot's notice)
        super()._group_broken(t, dead, g)


_NOT_THERE = ("DELIVERED", "IN_TRANSIT", "NOT_AT_OBJECT")
_GROUP_HOLD = frozenset((HcpState.WAITING, HcpState.MOVING))  # what a hold or carry is sent in


@dataclass(frozen=True)
class _Task:
    """What an HCP robot holds or carries: the object and its group (as a schedule entry)."""

    object: int
    agents: tuple[int, ...]


@dataclass
class RtHcpRuntime(RealtimeAgent):
    """The realtime runtime of an HCP robot (the module docstring)."""

    agent: RtHcpAgent  # type: ignore[assignment]

    def destination(self, obj: int) -> Cell:
        return self.comm.objects[obj].destination

    def _task(self) -> _Task | None:  # type: ignore[override]
        a = self.agent
        if a.current is None:
            return None
        oid = a.current.id
        group = next((g.agents for g in reversed(a.comm.groups) if g.object == oid), (self.id,))
        return _Task(oid, group if self.id in group else (self.id,))

    def on_result(self, res: GoalResult, now: float) -> list:
        """As every robot's, but a hold or carry refused because the object is not there to lift
        (delivered, carried by others, lying elsewhere) lets the object go: nobody's schedule will
        tell an HCP robot otherwise, and deciding again would ask for the same lift. (Refused
        because its base was not where the object lies — its goal came after the base had moved
        on, as over a network — it decides again, and walks back.)"""
        g = self.goals.goal
        cur = self.agent.current
        gone = (
            res.goal == self.goals.id
            and isinstance(g, Carry)
            and res.outcome in (ABORTED, REFUSED)
            and res.code in _NOT_THERE
            and not (res.code == "NOT_AT_OBJECT" and cur is not None and res.cell != cur.location)
        )
        if gone and isinstance(g, Carry):
            self.agent.let_go(g.object, f"{res.code.lower()} at {res.time:g}: {res.reason}")
        elif res.goal == self.goals.id and isinstance(g, Carry) and res.code == "NOT_AT_OBJECT":
            self.agent.walk_back(g.object)  # (not a fault: counted, no warning)
            self.goals.goal, self.goals.sweep, self.goals.lifted = None, None, -1
            self._decide_again(now)
            return self._flush(now)
        out = super().on_result(res, now)
        if not gone or self.out:
            return out
        self._decide_again(now)  # (what it does instead)
        return out + self._flush(now)

    def on_detection(self, det: Detection, now: float) -> list:
        """What its base sensed in its own area is its own to claim. Heard of at once (in
        process), it senses as the lockstep agent does: only while its body sweeps (a body that
        has just become a helper resumes its sweep from here, and senses it again). Heard of late
        (a network between them), it is claimed whatever the body does now: the body may have
        moved its sweep past it, and would never sense it again."""
        a = self.agent
        if self.out or not any(a.news(o) for o in det.objects):
            return self._flush(now)
        if not self.remote_base and det.time >= now - EPS:
            if a.state is HcpState.SEARCHING:
                self._decide_at(det.time, now)
        else:
            a.report_late(math.ceil(det.time - EPS), det.sensed)
            self._decide_at(math.floor(now + EPS) + 1, now)  # (as after a batch that changed it)
        return self._flush(now)

    def base_known(self, t: float) -> None:
        super().base_known(t)
        if not self.remote_base:
            return
        a = self.agent
        a.sensed_until = t
        if a.part_wait is not None and t >= a.part_wait:
            self.rule.due.add(t)  # its part may be done now: decide (its caller's clock comes)

    def held(self, now: float) -> bool:
        return super().held(now) or self.agent.part_wait is not None

    def _sync(self, fb: Feedback, s: int) -> None:
        super()._sync(fb, s)
        g = self.goals.goal
        self.agent.holding = g.object if isinstance(g, Carry) and fb.goal == self.goals.id else -1
        self.agent.resume_at(fb.cell)
        self.agent.view = self.batches.done  # what its decisions are taken on

    def _send(self, message, time: float) -> None:
        super()._send(message, time)
        if isinstance(message, HelpOffer) and self.record.last is not None:
            self.agent.offer_stamp = self.record.last[0]

    def _sponsor(self, now: float) -> None:
        """No robot comes back under HCP: a robot declared out stays out (its parts inherited)."""
        self.life.hellos.clear()

    def _take(self, t: int, now: float) -> None:
        msgs = self.batches.take(t)
        self.record.took(t, now)
        a = self.agent
        a.communicate(t, msgs)
        if any(isinstance(m, AgentLost) for m in msgs):
            self.goals.blocked = -1  # the comm knows of the failure: its groups are settled again
        for m in a.body_messages():
            self._send(m, now)
        self._digest(t, msgs, len(a.comm.groups))
        self._decide_at(math.floor(now + EPS) + 1, now)

    def _schedule_view(self) -> str | None:
        """The shared view: requests open, offers standing, groups formed, robots lost."""
        c = self.agent.comm
        view = repr((sorted(c.open.items()), sorted(c.offered_to.items()), c.groups, sorted(c.lost)))
        return None if view == self._view else view
