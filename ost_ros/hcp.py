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
subarea, swept again (its finds died with it), and the objects it was holding, where the world
says they fell (``AgentLost.dropped``).

Same per-step interface as :class:`~ost_ros.agent.CcpAgent`: ``act(obs)``, ``outbox()``,
``communicate(t, messages)``.
"""
from __future__ import annotations

import heapq
from dataclasses import dataclass, field, replace
from enum import Enum

from ost_msgs_py.messages import (Action, ActionKind, AgentLost, HelpAccept, HelpOffer, HelpRelease,
                                  HelpRequest, Observation, ObjectInfo, SearchDone)
from ost_ros.model import Cell, manhattan
from ost_ros.motion import step_toward
from ost_ros.search import SearchModule, route, sweep_waypoints
from ost_ros.team import TeamInfo


class HcpState(str, Enum):
    SEARCHING = "SEARCHING"    # sweeping its subarea (sensing own objects)
    FETCHING = "FETCHING"      # going to (or standing at) an own object
    REQUESTING = "REQUESTING"  # at an own object, help requested, not yet staffed
    HELPING = "HELPING"        # going to a partner's object
    WAITING = "WAITING"        # at the object, group chosen, holding until all have arrived
    MOVING = "MOVING"          # carrying
    RESUMING = "RESUMING"      # walking back to where the sweep was left
    DECISION = "DECISION"      # own work done or paused: available, waiting
    RETURNING = "RETURNING"    # every part is done: going back to base
    FINISH = "FINISH"


@dataclass(frozen=True)
class HelpGroup:
    """A staffing decision: who carries ``object`` (requester included), taken in step ``t``."""

    object: int
    agents: tuple[int, ...]
    t: int


def _ordered(msgs, key):
    """Messages in a fixed order (not the order they arrived in)."""
    return sorted(msgs, key=key) if len(msgs) > 1 else msgs


@dataclass
class HcpComm:
    """What an HCP agent knows of the team's requests and offers (the same at every agent)."""

    me: int
    team: TeamInfo
    objects: dict[int, ObjectInfo] = field(default_factory=dict)
    found_at: dict[int, int] = field(default_factory=dict)     # own objects: step found
    open: dict[int, int] = field(default_factory=dict)          # object -> requester
    offers: dict[int, dict[int, int]] = field(default_factory=dict)  # object -> {agent: arrival}
    offered_to: dict[int, int] = field(default_factory=dict)    # agent -> object (standing)
    groups: list[HelpGroup] = field(default_factory=list)
    done_parts: set[int] = field(default_factory=set)
    warnings: list[str] = field(default_factory=list)
    # CCP-compatible views used by the simulator's result.
    schedule: list = field(default_factory=list)
    predicted_makespan: int | None = None
    coordinations: int = 0
    # Failures: dead agent -> step; who requested each object; groups broken by a death;
    # dead agent -> its heir (when it left a part to do).
    lost: dict[int, int] = field(default_factory=dict)
    requester: dict[int, int] = field(default_factory=dict)
    broken: list[tuple[int, HelpGroup]] = field(default_factory=list)   # (dead agent, group)
    inherited: dict[int, tuple[int, tuple[int, ...]]] = field(default_factory=dict)   # -> (heir, parts)
    fallen: dict[int, ObjectInfo] = field(default_factory=dict)   # object -> where it was dropped

    def __post_init__(self) -> None:
        self._ids = frozenset(self.team.agent_ids)
        # whose subareas each agent owns: its own, then those it inherited
        self.parts: dict[int, list[int]] = {j: [j] for j in self.team.agent_ids}

    @property
    def alive(self) -> tuple[int, ...]:
        return tuple(j for j in self.team.agent_ids if j not in self.lost)

    def _lose(self, agent: int, t: int) -> None:
        if agent not in self._ids:
            return
        self.lost[agent] = t
        self._ids = self._ids - {agent}
        for obj in [o for o, r in self.open.items() if r == agent]:
            self._close(obj)                       # its request: nobody asks for it any more
        obj = self.offered_to.pop(agent, None)      # its standing offer lapses
        if obj is not None:
            self.offers.get(obj, {}).pop(agent, None)
        latest: dict[int, HelpGroup] = {}
        for g in self.groups:
            latest[g.object] = g
        self.broken.extend((agent, g) for g in latest.values() if agent in g.agents)
        parts = tuple(self.parts.pop(agent, [agent]))
        if agent not in self.done_parts and self.alive:
            heir = self.alive[0]                   # the lowest-id survivor takes its parts
            self.inherited[agent] = (heir, parts)
            self.parts[heir].extend(parts)
            self.done_parts.discard(heir)
        self.done_parts.discard(agent)

    def _close(self, obj: int) -> None:
        self.open.pop(obj, None)
        for agent in self.offers.pop(obj, {}):
            if self.offered_to.get(agent) == obj:
                del self.offered_to[agent]

    def receive(self, t: int, messages: list) -> list[HelpGroup]:
        """Take in the step's messages (by kind, so their order does not matter) and staff every
        request that has enough standing offers. Returns the groups formed in this step."""
        by_kind: dict[type, list] = {}
        for msg in messages:
            by_kind.setdefault(type(msg), []).append(msg)
        ids = self._ids
        for msg in by_kind.get(HelpRelease, ()):
            if self.open.get(msg.object) == msg.sender:
                self._close(msg.object)
        for msg in _ordered(by_kind.get(HelpRequest, ()), lambda m: m.object.id):
            if msg.sender in ids and msg.object.id not in self.open and msg.object.required > 1:
                self.open[msg.object.id] = msg.sender
                self.requester[msg.object.id] = msg.sender
                self.objects[msg.object.id] = msg.object
                self.offers[msg.object.id] = {}
        for msg in _ordered(by_kind.get(HelpOffer, ()), lambda m: (m.object, m.sender)):
            if (msg.object in self.open and msg.sender in ids and msg.sender not in self.offered_to
                    and self.open[msg.object] != msg.sender):
                self.offers[msg.object][msg.sender] = msg.arrival
                self.offered_to[msg.sender] = msg.object
        for msg in _ordered(by_kind.get(AgentLost, ()), lambda m: m.agent):
            for o in msg.dropped:   # where a dead robot's load lies (sensing gives its origin)
                self.fallen[o.id] = o
            self._lose(msg.agent, msg.t)
        for msg in by_kind.get(HelpAccept, ()):
            self._check_accept(msg)
        for msg in by_kind.get(SearchDone, ()):
            if msg.sender in ids:
                self.done_parts.add(msg.sender)
        formed = []
        if HelpOffer not in by_kind:   # staffing changes only with new offers
            return formed
        for obj in sorted(self.open):
            need = self.objects[obj].required - 1
            offers = self.offers[obj]
            if len(offers) >= need:
                partners = sorted(offers, key=lambda a: (offers[a], a))[:need]
                group = HelpGroup(obj, tuple(sorted(partners + [self.open[obj]])), t)
                self.groups.append(group)
                formed.append(group)
                self._close(obj)
        return formed

    def _check_accept(self, msg: HelpAccept) -> None:
        for g in reversed(self.groups):
            if g.object == msg.object:
                expected = tuple(a for a in g.agents if a != msg.sender)
                if tuple(sorted(msg.partners)) != expected:
                    self.warnings.append(f"agent {msg.sender}: partners {list(msg.partners)} for "
                                         f"object {msg.object} contradict the offers "
                                         f"({list(expected)}); ignored")
                return
        self.warnings.append(f"agent {msg.sender}: accept for object {msg.object} that was never "
                             "staffed; ignored")

    def lowest_open(self, exclude: int) -> int | None:
        """The highest-priority open request not made by ``exclude``."""
        for o in sorted(self.open) if len(self.open) > 1 else self.open:
            if self.open[o] != exclude:
                return o
        return None

    @property
    def closed(self) -> bool:
        return all(j in self.done_parts for j in self.alive)


_AVAILABLE = frozenset((HcpState.SEARCHING, HcpState.RESUMING, HcpState.DECISION,
                        HcpState.FETCHING, HcpState.REQUESTING))


@dataclass(frozen=True)
class Quiet:
    """What an agent will do, unchanged and silent, until something happens (for the event
    engine): ``kind`` is sweep | walk | wait | hold | carry; ``target`` the cell it walks or
    carries to (None otherwise); ``steps`` how many steps that lasts (None: until a message)."""

    kind: str
    target: Cell | None = None
    steps: int | None = None


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
        self.own: list[int] = []              # heap of found, not yet handled own object ids
        self.current: ObjectInfo | None = None
        self.helping = False                  # current object is a partner's
        self.offering: int | None = None      # object of my standing offer
        self.part_done_sent = False
        self._outbox: list = []
        self._obs: Observation | None = None
        self.areas = [self.area]              # subareas whose objects it owns (+ inherited)
        self.sweeps_left: list = []           # inherited subareas still to sweep
        self.claimed: set[int] = set()        # objects it has taken as its own
        self.unsure: set[int] = set()         # inherited objects that may be delivered already

    # ------------------------------------------------------------------ step, part 1: act

    def act(self, obs: Observation) -> Action:
        self.t, self.position, self._obs = obs.t, obs.position, obs
        if self.state is HcpState.SEARCHING:
            self._sense(obs)
        self._offer_or_withdraw()
        kind, direction, obj = self._motion()
        return Action(self.id, self.t, kind, direction, obj, self.state.value)

    def _sense(self, obs: Observation) -> None:
        for o in obs.sensed:
            if any(a.contains(o.location) for a in self.areas) and o.id not in self.claimed:
                self._claim(self.comm.fallen.get(o.id, o), obs.t)
        if self.search.at_end(self.position):
            if self.sweeps_left:   # on to an inherited subarea (walking there, sensing)
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
            self._outbox.append(HelpRelease(self.id, self.t, self.current.id))
            self.state = HcpState.FETCHING
        if self.offering is None:
            where = self.comm.objects[best].location
            arrival = self.t + 1 + manhattan(self.position, where)
            self._outbox.append(HelpOffer(self.id, self.t, best, self.comm.open[best], arrival))
            self.offering = best

    def _motion(self) -> tuple[ActionKind, Cell, int]:
        for _ in range(2 * len(HcpState) + 2):
            s = self.state
            if s is HcpState.SEARCHING:
                if (self.own and self.offering is None) or self.sweep_done:
                    self.state = HcpState.DECISION
                    continue
                return ActionKind.MOVE, step_toward(self.position, self.search.next_cell(self.position)), -1
            if s is HcpState.DECISION:
                if self.offering is not None:
                    return ActionKind.WAIT, (0, 0), -1
                while self.own and self.comm.objects[self.own[0]].required > len(self.comm.alive):
                    heapq.heappop(self.own)           # too few robots survive to move it
                if self.own:
                    self.current = self.comm.objects[heapq.heappop(self.own)]
                    self.helping = False
                    self.state = HcpState.FETCHING
                    continue
                if not self.sweep_done:
                    self.state = HcpState.RESUMING
                    continue
                if not self.part_done_sent:
                    self.part_done_sent = True
                    self._outbox.append(SearchDone(self.id, self.t))
                    self.comm.done_parts.add(self.id)   # my own part needs no round trip
                if self.comm.closed:
                    self.state = HcpState.RETURNING
                    continue
                return ActionKind.WAIT, (0, 0), -1
            if s is HcpState.RESUMING:
                if self.own and self.offering is None:
                    self.state = HcpState.DECISION
                    continue
                target = self.search.path[self.search.index]
                if self.position == target:
                    self.state = HcpState.SEARCHING
                    self._sense(self._obs)   # back on the sweep: sensing (and its end) resume
                    continue
                return ActionKind.MOVE, step_toward(self.position, target), -1
            if s is HcpState.FETCHING:
                target = self.current.location
                if self.position != target:
                    return ActionKind.MOVE, step_toward(self.position, target), -1
                if self.current.id in self.unsure:   # inherited: is it still here?
                    self.unsure.discard(self.current.id)
                    if all(o.id != self.current.id for o in self._obs.sensed):
                        self.current = None          # delivered before its owner died
                        self.state = HcpState.DECISION
                        continue
                if self.offering is not None:
                    return ActionKind.WAIT, (0, 0), -1
                if self.current.required == 1:
                    self.state = HcpState.MOVING
                    continue
                self._outbox.append(HelpRequest(self.id, self.t, self.current))
                self.state = HcpState.REQUESTING
                return ActionKind.WAIT, (0, 0), -1
            if s is HcpState.REQUESTING:
                return ActionKind.WAIT, (0, 0), -1
            if s is HcpState.HELPING:
                if self.position == self.current.location:
                    self.state = HcpState.WAITING
                    continue
                return ActionKind.MOVE, step_toward(self.position, self.current.location), -1
            if s is HcpState.WAITING or s is HcpState.MOVING:
                obj = self.current
                if self.position == obj.destination:   # delivered on arrival
                    self.current = None
                    self.helping = False
                    self.state = HcpState.DECISION
                    continue
                if self.position != obj.location:
                    self.state = HcpState.MOVING
                return ActionKind.CARRY, step_toward(self.position, obj.destination), obj.id
            if s is HcpState.RETURNING:
                if self.position == self.base:
                    self.state = HcpState.FINISH
                    continue
                return ActionKind.MOVE, step_toward(self.position, self.base), -1
            return ActionKind.WAIT, (0, 0), -1   # FINISH
        raise RuntimeError(f"agent {self.id}: motion FSA did not settle in state {self.state}")

    # ------------------------------------------------------------------ step, part 2: talk

    def outbox(self) -> list:
        out, self._outbox = self._outbox, []
        return out

    def communicate(self, t: int, messages: list) -> None:
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
            self.state = HcpState.DECISION   # a failure left work: available again
        if (self.comm.lost and self.current is not None and not self.helping
                and self.state in (HcpState.FETCHING, HcpState.REQUESTING)
                and self.current.required > len(self.comm.alive)):
            if self.state is HcpState.REQUESTING:   # nobody left to come: withdraw, give it up
                self._outbox.append(HelpRelease(self.id, t, self.current.id))
            self.current = None
            self.state = HcpState.DECISION
        for g in formed:
            if self.current is not None and not self.helping and g.object == self.current.id:
                # My request is staffed: hold the object until the partners have arrived.
                self.state = HcpState.WAITING
                self._outbox.append(HelpAccept(self.id, t, g.object,
                                               tuple(a for a in g.agents if a != self.id)))
            elif self.id in g.agents:
                if self.current is not None and not self.helping:
                    heapq.heappush(self.own, self.current.id)   # back to it after helping
                self.current = self.comm.objects[g.object]
                self.helping = True
                self.state = HcpState.HELPING
        if self.offering is not None and self.comm.offered_to.get(self.id) != self.offering:
            self.offering = None   # answered (chosen or not), lapsed, or never registered

    # ------------------------------------------------------------------ failures

    def _group_broken(self, t: int, dead: int, g: HelpGroup) -> None:
        """A member of ``g`` failed: its requester, if alive, fetches the object where it lies
        and asks again; everyone else in it goes back to its own work."""
        if self.id not in g.agents or self.current is None or self.current.id != g.object:
            return
        if self.comm.requester.get(g.object) == self.id and not self.helping:
            if self.state is HcpState.MOVING:   # carried part of the way: it lies here now
                self.current = replace(self.current, location=tuple(self.position))
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
        for o in lost.dropped:   # its own (requested by it, or carried alone), not a partner's
            if self.comm.requester.get(o.id, lost.agent) == lost.agent:
                self._claim(o, t)
        for oid, req in sorted(self.comm.requester.items()):
            # objects it (or a robot it inherited from) asked help for: maybe delivered already,
            # so looked at on arrival (``unsure``); where it lies: its last notice or request
            if req in parts and oid not in self.claimed:
                self._claim(self.comm.fallen.get(oid, self.comm.objects[oid]), t)
                self.unsure.add(oid)

    # ------------------------------------------------------------------ event engine

    def quiet(self) -> Quiet | None:
        """The silent, state-preserving behaviour ``act`` would repeat from the current step while
        no message arrives, or None if the next act decides something. Mirrors ``_motion`` (the
        event engine's equality test with the step engine keeps the two in step). A sweep's
        length is bounded by the engine, which knows where unfound objects lie."""
        if self._outbox or self._offer_target() is not None:
            return None
        s, pos = self.state, self.position
        if s is HcpState.SEARCHING:
            if (self.own and self.offering is None) or self.sweep_done:
                return None
            if pos != self.search.path[self.search.index]:
                return None
            return Quiet("sweep", None, len(self.search.path) - 1 - self.search.index)
        if s is HcpState.DECISION:
            if self.offering is not None:
                return Quiet("wait")
            if self.own or not self.sweep_done or not self.part_done_sent or self.comm.closed:
                return None
            return Quiet("wait")
        if s is HcpState.RESUMING:
            if self.own and self.offering is None:
                return None
            target = self.search.path[self.search.index]
            return Quiet("walk", target, manhattan(pos, target)) if pos != target else None
        if s is HcpState.FETCHING:
            target = self.current.location
            if pos != target:
                return Quiet("walk", target, manhattan(pos, target))
            return Quiet("wait") if self.offering is not None else None
        if s is HcpState.REQUESTING:
            return Quiet("wait")
        if s is HcpState.HELPING:
            target = self.current.location
            return Quiet("walk", target, manhattan(pos, target)) if pos != target else None
        if s is HcpState.WAITING:
            return Quiet("hold") if pos == self.current.location else None
        if s is HcpState.MOVING:
            dest = self.current.destination
            return Quiet("carry", dest, manhattan(pos, dest)) if pos != dest else None
        if s is HcpState.RETURNING:
            return Quiet("walk", self.base, manhattan(pos, self.base)) if pos != self.base else None
        return Quiet("wait")   # FINISH

    def skip(self, t: int, position: Cell, sweep_steps: int = 0) -> None:
        """Catch up after the engine advanced ``sweep_steps`` quiet sweep steps (or others)."""
        self.t, self.position = t, position
        self.search.index += sweep_steps

    # ------------------------------------------------------------------ introspection

    @property
    def done(self) -> bool:
        return self.state is HcpState.FINISH

    @property
    def warnings(self) -> list[str]:
        return self.comm.warnings
