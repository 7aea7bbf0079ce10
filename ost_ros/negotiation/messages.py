"""Offers as plain data: what one negotiator sends another.

:class:`Offer` (the library's negotiations): everything is ints, floats, strings and lists of
floats, so a message survives JSON or a DDS sequence<double> unchanged. The task type decodes
``params`` (polygon vertices x1,y1,x2,y2,... or claimed target coordinates) — partners never see
each other's private rewards.

:class:`NegotiationOffer` (the slot negotiation, :mod:`.slots`): one move as an OST agent
broadcasts it — NCP's message (``ost_ros.protocols.ncp`` lists it; its interface,
``ost_msgs/msg/NegotiationOffer``, is ``ost_ros/protocols/ncp/msg/NegotiationOffer.msg``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

from ost_ros.messages import SCHEMA_VERSION, AgentMessage

from .errors import NegotiationError

KINDS = ("offer", "accept", "exit", "abort")
BROADCAST = -1  # receiver id meaning "every team mate"


@dataclass(frozen=True)
class Offer:
    """One negotiation message.

    round: negotiation round; period: global offer counter (Rubinstein's time t);
    sender/receiver: agent ids (receiver -1 = all); kind: offer|accept|exit|abort;
    params: the claimed sub-task as a flat list of numbers — for "accept" and "exit", the
    share the sender takes and leaves with (an accept accepts the receiver's last offer).
    """

    round: int
    period: int
    sender: int
    receiver: int
    kind: str
    params: tuple[float, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise NegotiationError(f"unknown message kind {self.kind!r} (expected one of {', '.join(KINDS)})")
        if any(not math.isfinite(v) for v in self.params):
            raise NegotiationError("offer params must be finite numbers")

    def to_dict(self) -> dict[str, Any]:
        return {
            "round": self.round,
            "period": self.period,
            "sender": self.sender,
            "receiver": self.receiver,
            "kind": self.kind,
            "params": [float(v) for v in self.params],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Offer:
        try:
            return cls(
                round=int(data["round"]),
                period=int(data["period"]),
                sender=int(data["sender"]),
                receiver=int(data.get("receiver", BROADCAST)),
                kind=str(data["kind"]),
                params=tuple(float(v) for v in data.get("params", ())),
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, NegotiationError):
                raise
            raise NegotiationError(f"malformed offer message: {exc}") from None


@dataclass(frozen=True)
class NegotiationOffer(AgentMessage):
    """NCP: one negotiator's move in round ``round`` of negotiation ``negotiation``.

    ``offer`` is the offer vector: the ids of the objects in which the sender claims one carrying
    slot. ``kind`` is ``offer`` (a claim, possibly unchanged) or ``exit`` (the sender leaves with
    ``offer``, which nobody contests any more). ``receiver`` is -1: every move goes to everyone.
    Carried on ``<ns>/negotiation_offer`` by the ROS runtime.
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
