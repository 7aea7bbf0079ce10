"""The auction's own messages: every agent's bid for an announced object, the auctioneer's award."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ost_ros.messages import SCHEMA_VERSION, AgentMessage


@dataclass(frozen=True)
class Bid(AgentMessage):
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
class Award(AgentMessage):
    """Auction: the auctioneer's decision for ``object`` — its n_i lowest bidders (ties: lower
    id), ascending. Winners execute their objects in the order the awards arrive."""

    TYPE: ClassVar[str] = "award"
    sender: int
    t: int
    object: int
    agents: tuple[int, ...]
    version: int = SCHEMA_VERSION
