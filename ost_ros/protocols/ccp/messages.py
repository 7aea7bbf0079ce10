"""CCP's own messages: each agent's picks of a coordination (cross-checked by every peer) and,
in the coordinator organisation, the coordinator's schedule."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ost_ros.messages import SCHEMA_VERSION, AgentMessage, ScheduledObject


@dataclass(frozen=True)
class Selection(AgentMessage):
    """An agent's own picks in one coordination process (Algorithm Coordination, step 1).

    ``objects[r]`` is the object the sender selected in round r (-1 once it selects nothing).
    Every peer recomputes these from shared knowledge and flags any disagreement.
    """

    TYPE: ClassVar[str] = "selection"
    SHARED: ClassVar[bool] = False  # a cross-check: no peer's schedule depends on it
    sender: int
    t: int
    coordination: int
    objects: tuple[int, ...]
    version: int = SCHEMA_VERSION


@dataclass(frozen=True)
class ScheduleUpdate(AgentMessage):
    """Coordinator organisation (paper §3): the coordinator's result of coordination
    ``coordination``, in scheduling order; ``final``: the one after the whole search."""

    TYPE: ClassVar[str] = "schedule_update"
    sender: int
    t: int
    coordination: int
    assignments: tuple[ScheduledObject, ...]
    final: bool = False
    version: int = SCHEMA_VERSION
