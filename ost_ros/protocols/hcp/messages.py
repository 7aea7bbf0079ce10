"""HCP's own messages: an owner's request for help, the offers, the owner's choice, a release."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ost_ros.messages import ALL_READ, SCHEMA_VERSION, AgentMessage, ObjectInfo


@dataclass(frozen=True)
class HelpRequest(AgentMessage):
    """HCP: the owner of an object asks for ``required - 1`` helpers."""

    TYPE: ClassVar[str] = "help_request"
    sender: int
    t: int
    object: ObjectInfo
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class HelpOffer(AgentMessage):
    """HCP: an available agent offers help, with the time it would arrive at the object."""

    TYPE: ClassVar[str] = "help_offer"
    sender: int
    t: int
    object: int
    requester: int
    arrival: int
    # the last batch the sender had read when it offered (without a barrier; lockstep: ALL_READ)
    view: int = ALL_READ
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class HelpAccept(AgentMessage):
    """HCP: the requester's chosen partners for an object (everyone else is released)."""

    TYPE: ClassVar[str] = "help_accept"
    sender: int
    t: int
    object: int
    partners: tuple[int, ...]
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class HelpRelease(AgentMessage):
    """HCP: a requester gives up its partners (deadlock handling) or declines all offers."""

    TYPE: ClassVar[str] = "help_release"
    sender: int
    t: int
    object: int
    view: int = ALL_READ  # as HelpOffer's
    version: int = SCHEMA_VERSION
