"""What the realtime runtimes exchange beyond the protocols' own messages: the agreement layer's
envelope, watermark and request, the world's stamped failure notice, a survivor's status after a
failure, and the digest of a coordination. Plain dataclasses, ROS-free (the DDS layer maps them
to interfaces as it does the protocols' messages).

The protocol message classes are imported here and only here, so the realtime package names one
place for them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from ost_ros.messages import (  # the protocol schemas (one import site for the package)
    FINISH_STATE,
    SEARCHING_STATE,
    Action,
    ActionKind,
    AgentLost,
    AgentMessage,
    Cell,
    ObjectFound,
    ObjectInfo,
    Observation,
    SearchDone,
    Status,
)
from ost_ros.negotiation.messages import NegotiationOffer
from ost_ros.protocols.auction.messages import Award, Bid
from ost_ros.protocols.ccp.messages import ScheduleUpdate

__all__ = [
    "FINISH_STATE",
    "MONITOR",
    "SEARCHING_STATE",
    "Action",
    "ActionKind",
    "AgentLost",
    "AgentMessage",
    "Award",
    "Back",
    "Bid",
    "Digest",
    "Envelope",
    "Hello",
    "Lost",
    "Mark",
    "Need",
    "NegotiationOffer",
    "ObjectFound",
    "ObjectInfo",
    "Observation",
    "RtStatus",
    "ScheduleUpdate",
    "SearchDone",
    "Status",
]


MONITOR = -2  # the membership monitor's id in the agreement layer (and its signer's on the wire)


@dataclass(frozen=True)
class Envelope:
    """A protocol message as it travels without a barrier: its sender, the sender's count of its
    messages (from 1), its stamp (an integer step) and the sender's watermark as it sent it
    (everything it sends from then on is stamped above it: a message is a :class:`Mark` too).
    ``watermark`` None: ``stamp - 1``, what a sender whose commitments are never held back has
    (in process; an agent node commits only as far as its base's events are in, so its stamps
    may run ahead of its watermark)."""

    TYPE: ClassVar[str] = "envelope"
    sender: int
    seq: int
    stamp: int
    message: Any
    watermark: int | None = None

    @property
    def implied(self) -> int:
        """The watermark this message announces."""
        return self.stamp - 1 if self.watermark is None else self.watermark


@dataclass(frozen=True)
class Mark:
    """A watermark: ``sender`` has sent ``seq`` messages so far and every message it sends from now
    on is stamped above ``watermark`` — so all its messages stamped ≤ ``watermark`` are among
    1..``seq``. Every envelope implies one (``stamp - 1``, its ``seq``); a Mark says it explicitly,
    when a peer waits for it."""

    TYPE: ClassVar[str] = "mark"
    sender: int
    watermark: int
    seq: int


@dataclass(frozen=True)
class Need:
    """``sender`` waits for batch ``stamp`` and lacks some participant's watermark: whoever has
    passed ``stamp`` answers with a :class:`Mark` (once). It carries the sender's own watermark
    and count (``watermark``, ``seq``: as a :class:`Mark` would), so the one who asks is never
    the one waited for."""

    TYPE: ClassVar[str] = "need"
    sender: int
    stamp: int
    watermark: int = -1
    seq: int = 0


@dataclass(frozen=True)
class Lost(AgentLost):
    """The world's stamped failure notice: robot ``agent`` is gone; its messages with ``seq`` ≤
    ``seq`` and stamp < ``t`` count, nothing else of it does. ``t`` is never below the robot's last
    watermark + 1, so no survivor can have completed a batch the notice belongs to. What the world
    knows of the robot, as its last telemetry: ``at`` — the cell it occupied at step ``t`` (where
    its counted sensing ends), ``dropped`` — the object it held or carried, where it now lies,
    ``delivered`` — the objects whose delivery it took part in."""

    TYPE: ClassVar[str] = "lost"
    seq: int = 0
    at: Cell = (0, 0)
    delivered: tuple[int, ...] = ()
    incarnation: int = 0  # which of the robot's lives ends (0: the first; a rejoin is the next)
    serial: int = 0  # the monitor's count of its notices (0: a run without a monitor)


@dataclass(frozen=True)
class Hello:
    """Robot ``sender``, declared out, asks to come back as its incarnation ``incarnation``:
    it has sent ``seq`` messages (none more until it is back), its base stands at ``at``. Not
    in a batch: every member that hears it answers with a stamped :class:`Back`."""

    TYPE: ClassVar[str] = "hello"
    sender: int
    incarnation: int
    seq: int
    at: Cell


@dataclass(frozen=True)
class Back(AgentMessage):
    """A member's stamped answer to robot ``agent``'s :class:`Hello`: from the batch after this
    one's stamp ``t`` on, ``agent`` is a member again as its incarnation ``incarnation`` —
    free at ``t + 1`` at ``at``, its messages counting from ``after + 1``. Every member sends one;
    the first in batch order readmits, the rest are duplicates, dropped alike by all."""

    TYPE: ClassVar[str] = "back"
    sender: int
    t: int
    agent: int
    incarnation: int
    after: int
    at: Cell


@dataclass(frozen=True)
class RtStatus(Status):
    """A survivor's status after a failure, without a barrier: besides when and where it is free
    (``Status``), which failure it answers (the count of failures known: ``failure``) and how many
    of its own schedule entries, from the first, are done or under way (``keep``) — what
    everyone keeps of the schedule is computed from these, not from predicted times."""

    TYPE: ClassVar[str] = "rt_status"
    failure: int = 0
    keep: int = 0


@dataclass(frozen=True)
class Digest:
    """One coordination as an agent computed it: the batch (stamp), a hash of its input (the
    batch's messages in order) and of its output (the global schedule after it). Equal on every
    agent that processed the batch, or the run has a disagreement."""

    TYPE: ClassVar[str] = "digest"
    sender: int
    stamp: int
    coordination: int
    input: str
    output: str


@dataclass(frozen=True)
class BaseEvent:
    """One event of robot ``agent``'s base, as it travels to the robot (over DDS, on its own
    ``agent_<i>/base`` topic), numbered from 1 by ``seq``: the base's clock
    (:class:`BaseClock`) says how many it has sent up to a time, so the robot knows when it has
    every one of them. ``kind`` says which fields mean something (:mod:`ost_ros.realtime.base`):
    ``started`` (a goal took over: ``cell``, ``t``, ``offset``, ``first``, ``factor``),
    ``stalled`` (``t``, ``steps``), ``lifted`` (``object``, ``group``, ``t``, ``factor``),
    ``detected`` (``cell``, ``t``, ``objects``, ``sensed``), ``ended`` (a goal's result:
    ``outcome``, ``code``, ``reason``, ``cell``, ``t``, and what it senses there)."""

    TYPE: ClassVar[str] = "base_event"
    agent: int
    seq: int
    kind: str
    goal: int = 0
    t: float = 0.0
    cell: Cell = (0, 0)
    offset: int = 0
    first: float = 0.0
    factor: float = 1.0
    steps: float = 0.0
    object: int = -1
    group: tuple[int, ...] = ()
    objects: tuple[ObjectInfo, ...] = ()
    sensed: tuple[ObjectInfo, ...] = ()
    outcome: str = ""
    code: str = ""
    reason: str = ""


@dataclass(frozen=True)
class BaseClock:
    """The bases' clock (realtime runs): sim time ``t``, and for every robot (in the team's id
    order) how many base events its base has sent with a time ≤ ``t`` — a robot that has all of
    them has every base event up to ``t``, and may commit it."""

    TYPE: ClassVar[str] = "base_clock"
    t: float
    events: tuple[int, ...]


@dataclass(frozen=True)
class BaseGoal:
    """Robot ``agent``'s goal ``id`` for its own base (over DDS on ``base_goals``, as nav2 takes a
    goal on ``goal_pose`` beside its action): ``kind`` follow (``path``), stand or carry
    (``object`` with ``group``), taking over at the base's first cell boundary at or after ``at``;
    ``state`` labels what the robot does meanwhile. What became of it, its base's events say."""

    TYPE: ClassVar[str] = "base_goal"
    agent: int
    id: int
    kind: str
    at: float
    path: tuple[Cell, ...] = ()
    object: int = -1
    group: tuple[int, ...] = ()
    state: str = ""
    life: int = 0  # the robot's incarnation (a base stopped when it was declared out: a later one)


@dataclass(frozen=True)
class StopBase:
    """The membership monitor to robot ``agent``'s base: its robot is declared out (its life
    ``life`` ends); stop, and say what the notice needs — where the robot was at ``until`` (its
    counted sensing ends there), its load, its deliveries (:class:`BaseStopped`)."""

    TYPE: ClassVar[str] = "stop_base"
    agent: int
    life: int
    until: float


@dataclass(frozen=True)
class BaseStopped:
    """Robot ``agent``'s base, stopped at ``t`` for the end of life ``life``: ``at`` — the cell it
    occupied at the time asked for, ``dropped`` — the object it held or carried, where it now
    lies, ``delivered`` — the objects whose delivery it took part in (a notice's facts)."""

    TYPE: ClassVar[str] = "base_stopped"
    agent: int
    life: int
    t: float
    at: Cell = (0, 0)
    dropped: tuple[ObjectInfo, ...] = ()
    delivered: tuple[int, ...] = ()
