"""What an HCP agent knows of the team's requests and offers (the same at every agent): the
requests open, the standing offers, the staffing decisions, whose parts are done, and after a
failure who inherits what (:mod:`ost_ros.protocols.hcp.agent` for the protocol)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ost_ros.messages import AgentLost, AgentMessage, ObjectInfo, SearchDone
from ost_ros.protocols.hcp.messages import HelpAccept, HelpOffer, HelpRelease, HelpRequest
from ost_ros.team import TeamInfo


@dataclass(frozen=True)
class HelpGroup:
    """A staffing decision: who carries ``object`` (requester included), taken in step ``t``."""

    object: int
    agents: tuple[int, ...]
    t: int


def _ordered(msgs: list[Any], key: Callable[[Any], Any]) -> list[Any]:
    """Messages in a fixed order (not the order they arrived in)."""
    return sorted(msgs, key=key) if len(msgs) > 1 else msgs


@dataclass
class HcpComm:
    """What an HCP agent knows of the team's requests and offers (the same at every agent)."""

    me: int
    team: TeamInfo
    objects: dict[int, ObjectInfo] = field(default_factory=dict)
    found_at: dict[int, int] = field(default_factory=dict)  # own objects: step found
    open: dict[int, int] = field(default_factory=dict)  # object -> requester
    offers: dict[int, dict[int, int]] = field(default_factory=dict)  # object -> {agent: arrival}
    offered_to: dict[int, int] = field(default_factory=dict)  # agent -> object (standing)
    groups: list[HelpGroup] = field(default_factory=list)
    done_parts: set[int] = field(default_factory=set)
    warnings: list[str] = field(default_factory=list)
    # Failures: dead agent -> step; who requested each object; groups broken by a death;
    # dead agent -> its heir (when it left a part to do).
    lost: dict[int, int] = field(default_factory=dict)
    requester: dict[int, int] = field(default_factory=dict)
    broken: list[tuple[int, HelpGroup]] = field(default_factory=list)  # (dead agent, group)
    inherited: dict[int, tuple[int, tuple[int, ...]]] = field(default_factory=dict)  # -> (heir, parts)
    fallen: dict[int, ObjectInfo] = field(default_factory=dict)  # object -> where it was dropped
    heir_since: dict[int, int] = field(default_factory=dict)  # heir -> the step it last inherited
    dropped_by: dict[int, int] = field(default_factory=dict)  # fallen object -> the robot that fell

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
            self._close(obj)  # its request: nobody asks for it any more
        offered = self.offered_to.pop(agent, None)  # its standing offer lapses
        if offered is not None:
            self.offers.get(offered, {}).pop(agent, None)
        latest: dict[int, HelpGroup] = {}
        for g in self.groups:
            latest[g.object] = g
        # (a group broken by an earlier failure is not broken again: its object may be fetched
        # by someone else by now)
        gone = {id(g) for _, g in self.broken}
        self.broken.extend((agent, g) for g in latest.values() if agent in g.agents and id(g) not in gone)
        parts = tuple(self.parts.pop(agent, [agent]))
        if agent not in self.done_parts and self.alive:
            heir = self.alive[0]  # the lowest-id survivor takes its parts
            self.inherited[agent] = (heir, parts)
            self.heir_since[heir] = t
            self.parts[heir].extend(parts)
            self.done_parts.discard(heir)
        self.done_parts.discard(agent)

    def _close(self, obj: int) -> None:
        self.open.pop(obj, None)
        for agent in self.offers.pop(obj, {}):
            if self.offered_to.get(agent) == obj:
                del self.offered_to[agent]

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> list[HelpGroup]:
        """Take in the step's messages (by kind, so their order does not matter) and staff every
        request that has enough standing offers. Returns the groups formed in this step."""
        by_kind: dict[type, list[Any]] = {}
        for msg in messages:
            by_kind.setdefault(type(msg), []).append(msg)
        self._take_requests(by_kind)
        for msg in _ordered(by_kind.get(AgentLost, []), lambda m: m.agent):
            for o in msg.dropped:  # where a dead robot's load lies (sensing gives its origin)
                self.fallen[o.id] = o
                self.dropped_by[o.id] = msg.agent
            self._lose(msg.agent, msg.t)
        for msg in by_kind.get(HelpAccept, ()):
            self._check_accept(msg)
        for msg in by_kind.get(SearchDone, ()):
            # (a part inherited after the last batch the sender had read is not done)
            if msg.sender in self._ids and self.heir_since.get(msg.sender, -1) <= msg.view:
                self.done_parts.add(msg.sender)
        formed: list[HelpGroup] = []
        if HelpOffer not in by_kind:  # staffing changes only with new offers
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

    def _take_requests(self, by_kind: dict[type, list[Any]]) -> None:
        """Withdrawn requests, new requests, new standing offers — in a fixed order."""
        ids = self._ids
        for msg in by_kind.get(HelpRelease, ()):
            if self.open.get(msg.object) == msg.sender:
                self._close(msg.object)
        for msg in _ordered(by_kind.get(HelpRequest, []), lambda m: m.object.id):
            if msg.sender in ids and msg.object.id not in self.open and msg.object.required > 1:
                self.open[msg.object.id] = msg.sender
                self.requester[msg.object.id] = msg.sender
                self.objects[msg.object.id] = msg.object
                self.offers[msg.object.id] = {}
        for msg in _ordered(by_kind.get(HelpOffer, []), lambda m: (m.object, m.sender)):
            if (
                msg.object in self.open
                and msg.sender in ids
                and msg.sender not in self.offered_to
                and self.open[msg.object] != msg.sender
                and not self._staffed_since(msg.sender, msg.view)
            ):
                self.offers[msg.object][msg.sender] = msg.arrival
                self.offered_to[msg.sender] = msg.object

    def _staffed_since(self, agent: int, view: int) -> bool:
        """Whether ``agent`` was put in a group after the last batch it had read (``view``;
        lockstep: every one): its offer was decided on a stale view — it is busy there — and
        counts for nobody (without a barrier, docs/realtime.md "HCP without a barrier")."""
        for g in reversed(self.groups):
            if g.t <= view:
                return False
            if agent in g.agents:
                return True
        return False

    def _check_accept(self, msg: HelpAccept) -> None:
        for g in reversed(self.groups):
            if g.object == msg.object:
                expected = tuple(a for a in g.agents if a != msg.sender)
                if tuple(sorted(msg.partners)) != expected:
                    self.warnings.append(
                        f"agent {msg.sender}: partners {list(msg.partners)} for "
                        f"object {msg.object} contradict the offers "
                        f"({list(expected)}); ignored"
                    )
                return
        self.warnings.append(
            f"agent {msg.sender}: accept for object {msg.object} that was never staffed; ignored"
        )

    def lowest_open(self, exclude: int) -> int | None:
        """The highest-priority open request not made by ``exclude``."""
        for o in sorted(self.open) if len(self.open) > 1 else self.open:
            if self.open[o] != exclude:
                return o
        return None

    @property
    def closed(self) -> bool:
        return all(j in self.done_parts for j in self.alive)
