"""The messages every protocol speaks, ROS-free: sensing and acting, finds, the end of a search.

Frozen dataclasses with a ``TYPE`` tag (over DDS: the topic, ``<ns>/<TYPE>``). Each has an
``ost_msgs`` interface of the same name, field for field, and :mod:`ost_msgs_py.wire` converts
between the two; ``version`` is the schema's version inside the process (on the wire the
interface's type hash plays that part).

- agent ↔ agent (the comm module): every message derives from :class:`AgentMessage`. The ones
  here are shared by several protocols — :class:`ObjectFound`, :class:`SearchDone`, and for
  recovery from a failed robot :class:`Status` (and the world's notice :class:`AgentLost`); each
  protocol's own messages live in its package (``ost_ros/protocols/<name>/messages.py``) and the
  registry's specs list what each protocol broadcasts, so the table of every agent message kind
  is :func:`ost_ros.protocols.messages`, never a list kept by hand;
- agent ↔ world (sensing and acting): :class:`Observation`, :class:`Action`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any, ClassVar

Cell = tuple[int, int]  # a grid cell (x, y): the one definition every module uses

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


class AgentMessage:
    """The base of every message an agent's comm module takes in: a frozen dataclass with a
    ``TYPE`` (its topic), the ``sender`` and the step ``t`` it is about. The kinds are the
    registry's (each protocol's ``SPEC.messages``) plus the world's :class:`AgentLost`."""

    TYPE: ClassVar[str]
    # False for a message that only cross-checks (CCP's Selection): it changes no agent's shared
    # view, so without a barrier it is taken in as it comes, not in a batch (docs/realtime.md).
    SHARED: ClassVar[bool] = True
    sender: int
    t: int


@dataclass(frozen=True)
class ObjectFound(AgentMessage):
    """Broadcast when an agent senses an object for the first time (CCP: every found object)."""

    TYPE: ClassVar[str] = "object_found"
    sender: int
    t: int
    object: ObjectInfo
    version: int = SCHEMA_VERSION


# The view of a decision taken having read every message before it (lockstep): a decision
# without a barrier says the last batch it was taken on, and counts only if still sound then.
ALL_READ = 2**31 - 1


@dataclass(frozen=True)
class SearchDone(AgentMessage):
    """Broadcast once when an agent has swept its whole subarea (HCP: and delivered its own
    objects)."""

    TYPE: ClassVar[str] = "search_done"
    sender: int
    t: int
    # HCP without a barrier: the last batch the sender had read (a part it inherited later is
    # not done); ALL_READ: lockstep, or a protocol whose parts never change hands
    view: int = ALL_READ
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class Status(AgentMessage):
    """Recovery after a failure (CCP, NCP, the auction): when the sender is free of what it keeps
    doing (a carry under way, its sweep) and where it then stands. Every survivor broadcasts one
    the step after it learnt of the failure; all re-plan on them."""

    TYPE: ClassVar[str] = "status"
    sender: int
    t: int
    free_at: int
    location: Cell
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class ScheduledObject:
    """One entry of a schedule: the object, its group, carry start and finish (what a
    coordinator's ScheduleUpdate carries and what an agent reports at the end of a run)."""

    object: int
    agents: tuple[int, ...]
    start: int
    finish: int


WORLD = -1  # sender of the world's notices


@dataclass(frozen=True)
class AgentLost(AgentMessage):
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

    def does(self, kind: ActionKind, direction: Cell, obj: int, state: str) -> bool:
        """Whether this is that action (whoever takes it, whenever): how a planned step is
        compared with the action taken."""
        return (
            self.kind is kind
            and tuple(self.direction) == tuple(direction)
            and self.object == obj
            and self.state == state
        )


WORLD_MESSAGES: tuple[type[Any], ...] = (Observation, Action)
