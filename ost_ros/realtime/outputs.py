"""What a robot's realtime runtime asks its caller to do (the in-process runner or the agent
node): each callback of :class:`~ost_ros.realtime.agent.RealtimeAgent` returns a list of these."""

from __future__ import annotations

from dataclasses import dataclass

from ost_ros.realtime.messages import Digest, Envelope, Hello, Mark, Need
from ost_ros.realtime.world import Goal


@dataclass(frozen=True)
class Publish:
    """Broadcast to every peer (an Envelope, a Mark, a Need or a Hello)."""

    payload: Envelope | Mark | Need | Hello


@dataclass(frozen=True)
class SendGoal:
    """A goal for the agent's own base (client id ``id``), taking over at its first boundary at or
    after ``at``."""

    id: int
    goal: Goal
    at: float


@dataclass(frozen=True)
class AskFeedback:
    """Where will the base be at its first boundary at or after ``at`` (answer: ``on_feedback``)."""

    at: float


@dataclass(frozen=True)
class WakeAt:
    """Call ``on_clock`` at sim time ``time``."""

    time: float


Output = Publish | SendGoal | AskFeedback | WakeAt | Digest

# A robot whose base is across a network decides as of the time its decision was due if that is
# less than this much ago (steps): its goal then has the rest of the step to reach the base, which
# takes it over at that time (RealtimeWorld.takeover) — as a base on board would.
DECIDE_WINDOW = 0.5


def decision_time(at: float, now: float) -> float:
    """The moment a decision asked for ``at`` is taken as of, answered at ``now`` (a robot whose
    base is across a network: its picture of the base answers): ``at`` if due less than
    DECIDE_WINDOW ago, else now."""
    return at if now - DECIDE_WINDOW < at else max(at, now)
