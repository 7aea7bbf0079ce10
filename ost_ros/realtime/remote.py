"""A robot whose base is across a network (ROS-free): the one path by which its base's events
reach its runtime and its decisions are answered — the agent node's and the in-process runner's
(``ost sim --latency … --base-delay``) alike.

Nothing on a decision's path asks the base: the robot keeps its own picture of it
(:class:`~ost_ros.realtime.base.BaseMirror`) from the events its base sends — numbered, in order
— and from its own goals, and answers its runtime's :class:`~ost_ros.realtime.outputs.AskFeedback`
from that picture as of when the decision was due (:func:`~ost_ros.realtime.outputs.decision_time`).
While a goal it sent has neither started nor ended, or the route running is over by then with no
result yet, the picture is not whole: the decision waits for the events that make it so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ost_ros.realtime.base import BaseMirror, Motion
from ost_ros.realtime.messages import ObjectInfo
from ost_ros.realtime.outputs import Output, SendGoal, decision_time
from ost_ros.realtime.world import CarryStarted, Detection, GoalResult

if TYPE_CHECKING:
    from ost_ros.realtime.agent import RealtimeAgent


@dataclass
class BaseLink:
    """A robot's runtime and its picture of its base (see the module docstring)."""

    rt: RealtimeAgent
    mirror: BaseMirror
    waiting: float | None = None  # a decision (asked for this time) waiting for its picture

    def event(self, ev: Motion | Detection, sensed: Sequence[ObjectInfo], now: float) -> list[Output]:
        """One of its base's events, in their order (``sensed``: with a result, what the base
        senses where it stands): its picture first, then the runtime's callback."""
        if not isinstance(ev, Detection):
            self.mirror.take(ev, tuple(sensed))
        if isinstance(ev, Detection):
            return self.rt.on_detection(ev, now)
        if isinstance(ev, CarryStarted):
            return self.rt.on_carry(ev, now)
        if isinstance(ev, GoalResult):
            return self.rt.on_result(ev, now)
        return []  # (a goal took over, a stall: its picture's alone)

    def goal(self, o: SendGoal) -> None:
        """A goal it sends its base: its picture waits for the base to start or end it."""
        self.mirror.sent(o.id, o.goal)

    def decide(self, at: float, now: float) -> list[Output]:
        """Answer a decision asked for ``at`` from its picture — unless the picture is not whole
        by then (a robot declared out decides on what it has: its base is stopped)."""
        t = decision_time(at, now)
        # (a route over by now waits for its result, even if the decision is taken as of before)
        if not self.mirror.settled(max(t, now)) and not self.rt.out:
            self.waiting = at
            return []
        return self.rt.on_feedback(self.mirror.feedback(t), now)

    def retry(self, now: float) -> list[Output]:
        """More of its base's events are in: the decision waiting for its picture, again (it
        waits on if the picture is still not whole)."""
        if self.waiting is None:
            return []
        at, self.waiting = self.waiting, None
        return self.decide(at, now)
