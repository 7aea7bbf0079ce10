"""Message schemas shared by the protocol core and the ROS layer.

Plain dataclasses, ROS-free. Every message has a ``TYPE`` tag (over DDS: its topic,
``/ost/<TYPE>``) and an ``ost_msgs`` interface of the same name, field for field
(``ost_msgs_py/ost_msgs/msg/``); :mod:`ost_msgs_py.wire` converts between the two with strict
validation. ``version`` is the schema's version inside the process; on the wire the interface's
type hash plays that part.

Two families:
- agent ↔ agent (the comm module): :class:`ObjectFound`, :class:`SearchDone`, :class:`Selection`,
  and the help-based protocol's :class:`HelpRequest`, :class:`HelpOffer`, :class:`HelpAccept`,
  :class:`HelpRelease`, the negotiation protocol's :class:`NegotiationOffer`, and for recovery
  from a failed robot :class:`Status` (and the world's notice :class:`AgentLost`), and the
  coordinator organisation's :class:`ScheduleUpdate`, and the auction's :class:`Bid` and
  :class:`Award`;
- agent ↔ world (sensing and acting): :class:`Observation`, :class:`Action`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any, ClassVar

Cell = tuple[int, int]

SCHEMA_VERSION = 1


class ActionKind(str, Enum):
    WAIT = "wait"
    MOVE = "move"
    CARRY = "carry"


@dataclass(frozen=True)
class ObjectInfo:
    """What sensing an object reveals: its identity, where it is, where it goes, how many carry it."""

    id: int
    location: Cell
    destination: Cell
    required: int


# ----------------------------------------------------------------------------- agent ↔ agent


@dataclass(frozen=True)
class ObjectFound:
    """Broadcast when an agent senses an object for the first time (CCP: every found object)."""

    TYPE: ClassVar[str] = "object_found"
    sender: int
    t: int
    object: ObjectInfo
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class SearchDone:
    """Broadcast once when an agent has swept its whole subarea."""

    TYPE: ClassVar[str] = "search_done"
    sender: int
    t: int
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class Selection:
    """An agent's own picks in one coordination process (Algorithm Coordination, step 1).

    ``objects[r]`` is the object the sender selected in round r (-1 once it selects nothing).
    Every peer recomputes these from shared knowledge and flags any disagreement.
    """

    TYPE: ClassVar[str] = "selection"
    sender: int
    t: int
    coordination: int
    objects: tuple[int, ...]
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class HelpRequest:
    """HCP: the owner of an object asks for ``required - 1`` helpers."""

    TYPE: ClassVar[str] = "help_request"
    sender: int
    t: int
    object: ObjectInfo
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class HelpOffer:
    """HCP: an available agent offers help, with the time it would arrive at the object."""

    TYPE: ClassVar[str] = "help_offer"
    sender: int
    t: int
    object: int
    requester: int
    arrival: int
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class HelpAccept:
    """HCP: the requester's chosen partners for an object (everyone else is released)."""

    TYPE: ClassVar[str] = "help_accept"
    sender: int
    t: int
    object: int
    partners: tuple[int, ...]
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class HelpRelease:
    """HCP: a requester gives up its partners (deadlock handling) or declines all offers."""

    TYPE: ClassVar[str] = "help_release"
    sender: int
    t: int
    object: int
    version: int = SCHEMA_VERSION


NEGOTIATION_KINDS = ("offer", "exit")
BROADCAST = -1  # receiver of a message meant for every team mate


@dataclass(frozen=True)
class NegotiationOffer:
    """NCP: one negotiator's move in round ``round`` of negotiation ``negotiation``.

    ``offer`` is the offer vector: the ids of the objects in which the sender claims one carrying
    slot. ``kind`` is ``offer`` (a claim, possibly unchanged) or ``exit`` (the sender leaves with
    ``offer``, which nobody contests any more). ``receiver`` is -1: every move goes to everyone.
    Carried on ``/ost/negotiation_offer`` by the ROS runtime.
    """

    TYPE: ClassVar[str] = "negotiation_offer"
    sender: int
    t: int
    negotiation: int
    round: int
    kind: str
    offer: tuple[int, ...] = ()
    receiver: int = BROADCAST
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class ScheduledObject:
    """One entry of a coordinator's schedule: the object, its group, carry start and finish."""

    object: int
    agents: tuple[int, ...]
    start: int
    finish: int


@dataclass(frozen=True)
class ScheduleUpdate:
    """Coordinator organisation (paper §3): the coordinator's result of coordination
    ``coordination``, in scheduling order; ``final``: the one after the whole search."""

    TYPE: ClassVar[str] = "schedule_update"
    sender: int
    t: int
    coordination: int
    assignments: tuple[ScheduledObject, ...]
    final: bool = False
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class Bid:
    """Auction: the sender's bid for ``object`` — the step it could be there (when it is free of
    its search and of the objects it has won, plus the walk). Every agent bids on every object
    announced; the object's auctioneer awards it."""

    TYPE: ClassVar[str] = "bid"
    sender: int
    t: int
    object: int
    cost: int
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class Award:
    """Auction: the auctioneer's decision for ``object`` — its n_i lowest bidders (ties: lower
    id), ascending. Winners execute their objects in the order the awards arrive."""

    TYPE: ClassVar[str] = "award"
    sender: int
    t: int
    object: int
    agents: tuple[int, ...]
    version: int = SCHEMA_VERSION


WORLD = -1  # sender of the world's notices


@dataclass(frozen=True)
class AgentLost:
    """The world's notice that agent ``agent`` failed in step ``t``: it acted for the last time in
    step t-1 and sent nothing from step t on. Every survivor gets it in the same step (the ROS
    runtime carries it in ``Tick.failed``), so all agree on the survivor set. ``dropped``: what
    the robot itself last reported holding — the object its last action carried (or held for its
    group), at the cell it stood on: its own telemetry, relayed by the world, nothing else
    (docs/interpretation.md, "What a failure notice carries"). CCP computes the same itself;
    HCP's heir needs it."""

    TYPE: ClassVar[str] = "agent_lost"
    agent: int
    t: int
    dropped: tuple[ObjectInfo, ...] = ()  # its last reported load, where it stood
    sender: int = WORLD
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class Status:
    """CCP recovery after a failure: when the sender is free of what it keeps doing (a carry
    under way, its sweep) and where it then stands. Every survivor broadcasts one the step after
    it learnt of the failure; all re-coordinate on them."""

    TYPE: ClassVar[str] = "status"
    sender: int
    t: int
    free_at: int
    location: Cell
    version: int = SCHEMA_VERSION


# ----------------------------------------------------------------------------- agent ↔ world


@dataclass(frozen=True)
class Observation:
    """What the world tells an agent at the start of step ``t``: its pose and its sensor reading.

    ``sensed`` are the undelivered objects in the 3×3 block around the agent.
    """

    TYPE: ClassVar[str] = "observation"
    agent: int
    t: int
    position: Cell
    sensed: tuple[ObjectInfo, ...] = ()
    version: int = SCHEMA_VERSION


# The two global states the world reads from ``Action.state`` (every protocol's agents use these
# names): a move made while SEARCHING counts as search (else as travel), and an agent reporting
# FINISH at its base is done. Every other state name is the protocol's own, for display only.
SEARCHING_STATE = "SEARCHING"
FINISH_STATE = "FINISH"


@dataclass(frozen=True)
class Action:
    """An agent's action for step ``t``: wait, move one cell, or carry ``object`` one cell.

    A carry moves the object (and its carriers) only when enough agents carry it together in the
    same step; until the group is complete the carriers hold the object where it is.

    ``state`` is the agent's global FSA state when it acted: the world reads only
    :data:`SEARCHING_STATE` and :data:`FINISH_STATE` from it; the rest is for display.
    """

    TYPE: ClassVar[str] = "action"
    agent: int
    t: int
    kind: ActionKind
    direction: Cell = (0, 0)
    object: int = -1
    state: str = ""
    version: int = SCHEMA_VERSION


AGENT_MESSAGES: tuple[type[Any], ...] = (
    ObjectFound,
    SearchDone,
    Selection,
    HelpRequest,
    HelpOffer,
    HelpAccept,
    HelpRelease,
    NegotiationOffer,
    Status,
    AgentLost,
    ScheduleUpdate,
    Bid,
    Award,
)
WORLD_MESSAGES: tuple[type[Any], ...] = (Observation, Action)
ALL_MESSAGES: dict[str, type[Any]] = {cls.TYPE: cls for cls in AGENT_MESSAGES + WORLD_MESSAGES}

# Any message an agent's comm module takes in (the world's AgentLost notice included).
AgentMessage = (
    ObjectFound
    | SearchDone
    | Selection
    | HelpRequest
    | HelpOffer
    | HelpAccept
    | HelpRelease
    | NegotiationOffer
    | Status
    | AgentLost
    | ScheduleUpdate
    | Bid
    | Award
)
