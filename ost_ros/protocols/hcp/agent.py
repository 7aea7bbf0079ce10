"""The help-based cooperation protocol (HCP), the paper's baseline (§2.3), as an agent class.

Each agent owns the objects lying in its subarea and sweeps that subarea. A found object with
n_i = 1 is carried alone, then the sweep resumes where it was left. For n_i > 1 the owner goes to
the object and broadcasts a :class:`HelpRequest`; available agents answer with a standing
:class:`HelpOffer` (their arrival time); once n_i − 1 offers stand, the cheapest are the partners
(announced by :class:`HelpAccept`), the others are free again. Helpers interrupt their own work,
come, hold, carry, and go back to their work.

Deadlock handling (priority by object id, lower = higher priority):
- an available agent offers only to the open request with the lowest object id, and only if that
  id is lower than its own next object (otherwise it handles its own object first);
- an agent with a standing offer starts no own object (it may keep sweeping) until the offer is
  answered;
- an unstaffed requester that hears of an open request with a lower id withdraws
  (:class:`HelpRelease`, its offers lapse) and becomes a possible helper; it asks again later.
So the lowest open request is never withdrawn and every other agent eventually offers to it
(committed groups always finish), and N ≥ n_max staffs it (tested on random scenarios).

Every agent sees every message of a step (synchronous rounds), so the staffing decision is taken
by every agent with the same rule from the same offers, in a fixed order independent of message
order; the requester's :class:`HelpAccept` is cross-checked, never obeyed blindly.

Termination: an agent broadcasts :class:`SearchDone` when its part is done (subarea swept and
every own object delivered); an agent returns to base once every part is done.

Failures (the world's :class:`AgentLost`, docs/interpretation.md "Robot failures"): every
survivor drops the dead agent's requests and offers; a group with it breaks — its requester, if
alive, fetches the object where it now lies and asks again, its helpers go back to their work;
unless the dead agent's part was done, it goes to its heir, the lowest-id survivor: its whole
subarea, swept again (its finds died with it), and the object it last reported holding, where
it stood (``AgentLost.dropped``: its own last telemetry, relayed by the world).

The agent is a :class:`~ost_ros.protocols.base.ProtocolAgent`; its knowledge of requests and
offers is :class:`~ost_ros.protocols.hcp.comm.HcpComm`.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from enum import Enum
from typing import ClassVar

from ost_ros.messages import (
    ALL_READ,
    FINISH_STATE,
    SEARCHING_STATE,
    Action,
    ActionKind,
    AgentLost,
    AgentMessage,
    ObjectInfo,
    Observation,
    SearchDone,
)
from ost_ros.model import Cell, manhattan, moves_between
from ost_ros.motion import step_toward
from ost_ros.protocols.base import AgentSummary
from ost_ros.protocols.hcp.comm import HcpComm, HelpGroup
from ost_ros.protocols.hcp.messages import HelpAccept, HelpOffer, HelpRelease, HelpRequest
from ost_ros.protocols.plans import NO_PLAN, Plan, Segment
from ost_ros.search import SearchModule, route, sweep_waypoints
from ost_ros.team import TeamInfo

Action3 = tuple[ActionKind, Cell, int]  # what a motion state returns: kind, direction, object
WAIT: Action3 = (ActionKind.WAIT, (0, 0), -1)


class HcpState(str, Enum):
    SEARCHING = SEARCHING_STATE  # sweeping its subarea (sensing own objects)
    FETCHING = "FETCHING"  # going to (or standing at) an own object
    REQUESTING = "REQUESTING"  # at an own object, help requested, not yet staffed
    HELPING = "HELPING"  # going to a partner's object
    WAITING = "WAITING"  # at the object, group chosen, holding until all have arrived
    MOVING = "MOVING"  # carrying
    RESUMING = "RESUMING"  # walking back to where the sweep was left
    DECISION = "DECISION"  # own work done or paused: available, waiting
    RETURNING = "RETURNING"  # every part is done: going back to base
    FINISH = FINISH_STATE


_AVAILABLE = frozenset(
    (HcpState.SEARCHING, HcpState.RESUMING, HcpState.DECISION, HcpState.FETCHING, HcpState.REQUESTING)
)


class HcpAgent:
    """One robot running the help-based cooperation protocol."""

    protocol = "hcp"

    def __init__(self, agent_id: int, team: TeamInfo):
        self.id = agent_id
        self.team = team
        k = team.index(agent_id)
        self.area = team.areas[k]
        self.base: Cell = team.bases[k]
        self.position: Cell = self.base
        self.t = 0
        self.state = HcpState.SEARCHING
        self.search = SearchModule.for_area(self.area, self.base)
        self.sweep_done = False
        self.comm = HcpComm(agent_id, team)
        self.own: list[int] = []  # heap of found, not yet handled own object ids
        self.current: ObjectInfo | None = None
        self.helping = False  # current object is a partner's
        self.offering: int | None = None  # object of my standing offer
        self.part_done_sent = False
        self._outbox: list[AgentMessage] = []
        self._obs: Observation | None = None
        self.areas = [self.area]  # subareas whose objects it owns (+ inherited)
        self.sweeps_left: list[list[Cell]] = []  # inherited subareas still to sweep
        self.claimed: set[int] = set()  # objects it has taken as its own
        self.unsure: set[int] = set()  # inherited objects that may be delivered already
        # the last batch (lockstep: step) its comm has read: its offers, withdrawals and part
        # done say so, and count only if still sound then
        self.view = ALL_READ

    # ------------------------------------------------------------------ step, part 1: act

    def act(self, obs: Observation) -> Action:
        self.t, self.position, self._obs = obs.t, obs.position, obs
        self._read_up_to(obs.t - 1)
        if self.state is HcpState.SEARCHING:
            self._sense(obs)
        self._offer_or_withdraw()
        kind, direction, obj = self._motion()
        return Action(self.id, self.t, kind, direction, obj, self.state.value)

    def _read_up_to(self, t: int) -> None:
        """In lockstep it has read every step's messages before step ``t + 1``: what it says
        now is decided on them (a part it inherits in this step's messages is not done yet)."""
        self.view = t

    def _sense(self, obs: Observation) -> None:
        for o in obs.sensed:
            if any(a.contains(o.location) for a in self.areas) and o.id not in self.claimed:
                self._claim(self.comm.fallen.get(o.id, o), obs.t)
        if self.search.at_end(self.position):
            if self.sweeps_left:  # on to an inherited subarea (walking there, sensing)
                self.search = SearchModule(route([self.position] + self.sweeps_left.pop(0)))
            else:
                self.sweep_done = True

    def _claim(self, o: ObjectInfo, t: int) -> None:
        self.comm.objects[o.id] = o
        self.comm.found_at.setdefault(o.id, t)
        self.claimed.add(o.id)
        heapq.heappush(self.own, o.id)

    def _own_next(self) -> int | None:
        """Id of the own object this agent would handle next (the one in hand first)."""
        if self.current is not None and not self.helping:
            return self.current.id
        return self.own[0] if self.own else None

    def _offer_target(self) -> int | None:
        """The request this agent would answer now (offer to, withdrawing its own first), if any."""
        if self.state not in _AVAILABLE:
            return None
        best = self.comm.lowest_open(self.id)
        if best is None:
            return None
        mine = self._own_next()
        if mine is not None and mine < best:
            return None
        if self.offering is not None and self.state is not HcpState.REQUESTING:
            return None
        return best

    def _offer_or_withdraw(self) -> None:
        best = self._offer_target()
        if best is None:
            return
        if self.state is HcpState.REQUESTING:
            # A higher-priority request is open: give up mine (its offers lapse) and help there.
            assert self.current is not None
            self._outbox.append(HelpRelease(self.id, self.t, self.current.id, self.view))
            self.state = HcpState.FETCHING
        if self.offering is None:
            where = self.comm.objects[best].location
            arrival = self.t + 1 + manhattan(self.position, where)
            self._outbox.append(HelpOffer(self.id, self.t, best, self.comm.open[best], arrival, self.view))
            self.offering = best

    def _motion(self) -> tuple[ActionKind, Cell, int]:
        # A state either acts (returns the action) or hands over to the next state within the
        # same step (returns None), so no step is lost to a bookkeeping transition.
        for _ in range(2 * len(HcpState) + 2):
            action = self._STEP[self.state](self)
            if action is not None:
                return action
        raise RuntimeError(f"agent {self.id}: motion FSA did not settle in state {self.state}")

    def _searching(self) -> Action3 | None:
        if (self.own and self.offering is None) or self.sweep_done:
            self.state = HcpState.DECISION
            return None
        return ActionKind.MOVE, step_toward(self.position, self.search.next_cell(self.position)), -1

    def _deciding(self) -> Action3 | None:
        if self.offering is not None:
            return WAIT
        while self.own and self.comm.objects[self.own[0]].required > len(self.comm.alive):
            heapq.heappop(self.own)  # too few robots survive to move it
        if self.own:
            self.current = self.comm.objects[heapq.heappop(self.own)]
            self.helping = False
            self.state = HcpState.FETCHING
            return None
        if not self.sweep_done:
            self.state = HcpState.RESUMING
            return None
        if not self.part_done_sent:
            self.part_done_sent = True
            self._outbox.append(SearchDone(self.id, self.t, self.view))
            self.comm.done_parts.add(self.id)  # my own part needs no round trip
        if self.comm.closed:
            self.state = HcpState.RETURNING
            return None
        return WAIT

    def _resuming(self) -> Action3 | None:
        if self.own and self.offering is None:
            self.state = HcpState.DECISION
            return None
        target = self.search.path[self.search.index]
        if self.position == target:
            self.state = HcpState.SEARCHING
            assert self._obs is not None
            self._sense(self._obs)  # back on the sweep: sensing (and its end) resume
            return None
        return ActionKind.MOVE, step_toward(self.position, target), -1

    def _fetching(self) -> Action3 | None:
        assert self.current is not None and self._obs is not None
        target = self.current.location
        if self.position != target:
            return ActionKind.MOVE, step_toward(self.position, target), -1
        if self.current.id in self.unsure:  # inherited: is it still here?
            self.unsure.discard(self.current.id)
            if all(o.id != self.current.id for o in self._obs.sensed):
                self.current = None  # delivered before its owner died
                self.state = HcpState.DECISION
                return None
        if self.offering is not None:
            return WAIT
        if self.current.required == 1:
            self.state = HcpState.MOVING
            return None
        self._outbox.append(HelpRequest(self.id, self.t, self.current))
        self.state = HcpState.REQUESTING
        return WAIT

    def _requesting(self) -> Action3 | None:
        return WAIT

    def _helping(self) -> Action3 | None:
        assert self.current is not None
        if self.position == self.current.location:
            self.state = HcpState.WAITING
            return None
        return ActionKind.MOVE, step_toward(self.position, self.current.location), -1

    def _carrying(self) -> Action3 | None:
        obj = self.current
        assert obj is not None
        if self.position == obj.destination:  # delivered on arrival
            self.current = None
            self.helping = False
            self.state = HcpState.DECISION
            return None
        if self.position != obj.location:
            self.state = HcpState.MOVING
        return ActionKind.CARRY, step_toward(self.position, obj.destination), obj.id

    def _returning(self) -> Action3 | None:
        if self.position == self.base:
            self.state = HcpState.FINISH
            return None
        return ActionKind.MOVE, step_toward(self.position, self.base), -1

    def _finished(self) -> Action3 | None:
        return WAIT

    _STEP: ClassVar[dict[HcpState, Callable[[HcpAgent], Action3 | None]]] = {
        HcpState.SEARCHING: _searching,
        HcpState.DECISION: _deciding,
        HcpState.RESUMING: _resuming,
        HcpState.FETCHING: _fetching,
        HcpState.REQUESTING: _requesting,
        HcpState.HELPING: _helping,
        HcpState.WAITING: _carrying,
        HcpState.MOVING: _carrying,
        HcpState.RETURNING: _returning,
        HcpState.FINISH: _finished,
    }

    # ------------------------------------------------------------------ step, part 2: talk

    def outbox(self) -> list[AgentMessage]:
        out, self._outbox = self._outbox, []
        return out

    def communicate(self, t: int, messages: Sequence[AgentMessage]) -> None:
        before = len(self.comm.broken)
        formed = self.comm.receive(t, messages)
        for dead, g in self.comm.broken[before:]:
            self._group_broken(t, dead, g)
        for m in messages:
            if isinstance(m, AgentLost):
                heir, parts = self.comm.inherited.get(m.agent, (None, ()))
                if heir == self.id:
                    self._inherit(m, parts, t)
        if self.state in (HcpState.RETURNING, HcpState.FINISH) and not self.comm.closed:
            self.state = HcpState.DECISION  # a failure left work: available again
        if (
            self.comm.lost
            and self.current is not None
            and not self.helping
            and self.state in (HcpState.FETCHING, HcpState.REQUESTING)
            and self.current.required > len(self.comm.alive)
        ):
            if self.state is HcpState.REQUESTING:  # nobody left to come: withdraw, give it up
                self._outbox.append(HelpRelease(self.id, t, self.current.id, self.view))
            self.current = None
            self.state = HcpState.DECISION
        for g in formed:
            if self.current is not None and not self.helping and g.object == self.current.id:
                # My request is staffed: hold the object until the partners have arrived.
                self.state = HcpState.WAITING
                self._outbox.append(
                    HelpAccept(self.id, t, g.object, tuple(a for a in g.agents if a != self.id))
                )
            elif self.id in g.agents:
                if self.current is not None and not self.helping:
                    heapq.heappush(self.own, self.current.id)  # back to it after helping
                self.current = self.comm.objects[g.object]
                self.helping = True
                self.state = HcpState.HELPING
        if self.offering is not None and self.comm.offered_to.get(self.id) != self.offering:
            self.offering = None  # answered (chosen or not), lapsed, or never registered

    # ------------------------------------------------------------------ failures

    def _group_broken(self, t: int, dead: int, g: HelpGroup) -> None:
        """A member of ``g`` failed: its requester, if alive, fetches the object where it lies
        and asks again; everyone else in it goes back to its own work."""
        if self.id not in g.agents or self.current is None or self.current.id != g.object:
            return
        if self.comm.requester.get(g.object) == self.id and not self.helping:
            if self.state is HcpState.MOVING:  # carried part of the way: it lies here now
                self.current = replace(self.current, location=(self.position[0], self.position[1]))
                self.comm.objects[g.object] = self.current
            self.state = HcpState.FETCHING
            return
        self.current = None
        self.helping = False
        self.state = HcpState.DECISION

    def _inherit(self, lost: AgentLost, parts: tuple[int, ...], t: int) -> None:
        """The dead agent's parts are mine: its subareas (its own and what it had inherited,
        swept again: its finds died with it) and what it was holding, where it fell."""
        for owner in parts:
            area = self.team.areas[self.team.index(owner)]
            self.areas.append(area)
            self.sweeps_left.append(sweep_waypoints(area))
        if self.sweep_done:
            self.search = SearchModule(route([self.position] + self.sweeps_left.pop(0)))
            self.sweep_done = False
        self.part_done_sent = False
        for o in lost.dropped:  # its own (requested by it, or carried alone), not a partner's
            if self.comm.requester.get(o.id, lost.agent) == lost.agent:
                self._claim(o, t)
        for oid, o in sorted(self.comm.fallen.items()):
            # a load a robot of these parts dropped earlier and its heir (dead now) had taken as
            # its own: maybe delivered already, so looked at on arrival — it may lie outside
            # every subarea swept again
            owner = self.comm.requester.get(oid, self.comm.dropped_by[oid])
            if owner in parts and owner != lost.agent and oid not in self.claimed:
                self._claim(o, t)
                self.unsure.add(oid)
        for oid, req in sorted(self.comm.requester.items()):
            # objects it (or a robot it inherited from) asked help for: maybe delivered already,
            # so looked at on arrival (``unsure``); where it lies: its last notice or request
            if req in parts and oid not in self.claimed:
                self._claim(self.comm.fallen.get(oid, self.comm.objects[oid]), t)
                self.unsure.add(oid)

    # ------------------------------------------------------------------ quiet steps

    def plan(self, t: int, position: Cell) -> Plan:
        """The silent steps ``act`` takes from ``t`` while no message arrives — mirrors
        ``_motion`` state by state, chaining the hand-overs that need no decision (arriving to
        hold, to carry alone, to sweep on, to finish). Sweeps run to their end: the caller stops
        them where an own object comes into sensor range (``news``)."""
        if self._outbox or self._offer_target() is not None:
            return NO_PLAN
        segments = tuple(self._segments(self.state, position))
        # every first segment continues the current state (hand-overs only come after it)
        return Plan(segments, settled=bool(segments))

    def _segments(self, s: HcpState, pos: Cell) -> list[Segment]:
        return self._PLAN[s](self, pos)

    def _plan_searching(self, pos: Cell) -> list[Segment]:
        if (self.own and self.offering is None) or self.sweep_done:
            return []
        return self._sweep(pos)

    def _plan_deciding(self, pos: Cell) -> list[Segment]:
        if self.offering is None and (
            self.own or not self.sweep_done or not self.part_done_sent or self.comm.closed
        ):
            return []
        return [Segment("wait", HcpState.DECISION.value)]

    def _plan_resuming(self, pos: Cell) -> list[Segment]:
        target = self.search.path[self.search.index]
        if (self.own and self.offering is None) or pos == target:
            return []
        return [self._walk(HcpState.RESUMING, pos, target)] + self._sweep(target, HcpState.SEARCHING)

    def _plan_fetching(self, pos: Cell) -> list[Segment]:
        assert self.current is not None
        target, here = self.current.location, HcpState.FETCHING
        if pos == target:
            return [Segment("wait", here.value)] if self.offering is not None else []
        out = [self._walk(here, pos, target)]
        if self.current.id in self.unsure:
            return out  # is it still there? looked at on arrival
        if self.offering is not None:
            return out + [Segment("wait", here.value)]
        if self.current.required == 1 and target != self.current.destination:
            return out + [self._carry(HcpState.MOVING, target)]  # alone: carried at once
        return out

    def _plan_waiting(self, pos: Cell) -> list[Segment]:
        assert self.current is not None
        return [self._hold()] if pos == self.current.location else []

    def _plan_helping(self, pos: Cell) -> list[Segment]:
        assert self.current is not None
        target = self.current.location
        return [] if pos == target else [self._walk(HcpState.HELPING, pos, target), self._hold()]

    def _plan_moving(self, pos: Cell) -> list[Segment]:
        assert self.current is not None
        return [self._carry(HcpState.MOVING, pos)] if pos != self.current.destination else []

    def _plan_returning(self, pos: Cell) -> list[Segment]:
        if pos == self.base:
            return []
        return [self._walk(HcpState.RETURNING, pos, self.base), Segment("wait", HcpState.FINISH.value)]

    def _plan_standing(self, pos: Cell) -> list[Segment]:  # REQUESTING, FINISH: wait for news
        return [Segment("wait", self.state.value)]

    _PLAN: ClassVar[dict[HcpState, Callable[[HcpAgent, Cell], list[Segment]]]] = {
        HcpState.SEARCHING: _plan_searching,
        HcpState.DECISION: _plan_deciding,
        HcpState.RESUMING: _plan_resuming,
        HcpState.FETCHING: _plan_fetching,
        HcpState.REQUESTING: _plan_standing,
        HcpState.HELPING: _plan_helping,
        HcpState.WAITING: _plan_waiting,
        HcpState.MOVING: _plan_moving,
        HcpState.RETURNING: _plan_returning,
        HcpState.FINISH: _plan_standing,
    }

    def _sweep(self, pos: Cell, state: HcpState = HcpState.SEARCHING) -> list[Segment]:
        """On along the sweep from ``pos`` (its current cell) to the last cell, where it decides."""
        path, i = self.search.path, self.search.index
        if pos != path[i] or i >= len(path) - 1:
            return []
        return [Segment("sweep", state.value, len(path) - 1 - i, path=path, index=i)]

    def _walk(self, state: HcpState, pos: Cell, target: Cell) -> Segment:
        return Segment("walk", state.value, manhattan(pos, target), target=target)

    def _hold(self) -> Segment:
        assert self.current is not None
        return Segment(
            "hold", HcpState.WAITING.value, target=self.current.destination, object=self.current.id
        )

    def _carry(self, state: HcpState, pos: Cell) -> Segment:
        assert self.current is not None
        dest = self.current.destination
        return Segment("carry", state.value, manhattan(pos, dest), target=dest, object=self.current.id)

    def next_event(self, t: int) -> int | None:
        return None  # its knowledge changes only with messages

    def skip(self, t: int, position: Cell, segment: Segment, steps: int) -> None:
        self.t, self.position = t, position
        if segment.kind == "sweep":
            self.search.index = segment.index + moves_between(t - steps, t, segment.period)

    def news(self, obj: ObjectInfo) -> bool:
        return obj.id not in self.claimed and any(a.contains(obj.location) for a in self.areas)

    def group(self) -> int | None:
        return self.current.id if self.current is not None and self.state in _GROUP else None

    def departures(self) -> Mapping[int, int]:
        return {}  # when a group will be complete is known only when it is

    # ------------------------------------------------------------------ introspection

    def summary(self) -> AgentSummary:
        return AgentSummary(
            "help", None, 0, (), dict(self.comm.found_at), tuple(self.comm.warnings), repr(self.comm.groups)
        )

    @property
    def done(self) -> bool:
        return self.state is HcpState.FINISH

    @property
    def warnings(self) -> list[str]:
        return self.comm.warnings


_GROUP = frozenset((HcpState.HELPING, HcpState.WAITING, HcpState.MOVING))
