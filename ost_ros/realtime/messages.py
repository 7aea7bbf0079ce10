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
    "SEARCHING_STATE",
    "Action",
    "ActionKind",
    "AgentLost",
    "AgentMessage",
    "Award",
    "Bid",
    "Digest",
    "Envelope",
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


@dataclass(frozen=True)
class Envelope:
    """A protocol message as it travels without a barrier: its sender, the sender's count of its
    messages (from 1) and its stamp (an integer step; non-decreasing in ``seq``)."""

    TYPE: ClassVar[str] = "envelope"
    sender: int
    seq: int
    stamp: int
    message: Any


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
    passed ``stamp`` answers with a :class:`Mark` (once)."""

    TYPE: ClassVar[str] = "need"
    sender: int
    stamp: int


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
