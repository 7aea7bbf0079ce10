"""A robot's own picture of its base (ROS-free): where the base will be, from what the base says
anyway and the robot's own goals — no question to anyone on a decision's path.

Over DDS a robot's base is across a network: the robot cannot ask the world where it is at each
decision without a round trip. Instead the base says how it moves whenever that changes — a goal
has taken over (:class:`~ost_ros.realtime.world.GoalStarted`: from which cell and time, when the
first move leaves, how long a move takes), it stalled (:class:`~ost_ros.realtime.world.Stalled`),
its group lifted an object (:class:`~ost_ros.realtime.world.CarryStarted`), a goal ended
(:class:`~ost_ros.realtime.world.GoalResult`) — and the robot computes its base's motion from those
facts with the world's own formulas (:class:`~ost_ros.realtime.world.Route`,
:func:`~ost_ros.realtime.world.follow_departures`, :func:`~ost_ros.realtime.world.carry_departures`).
So :meth:`BaseMirror.feedback` answers what ``RealtimeWorld.feedback`` would (tested on random
runs: the same cell, time, goal, index and carry at every decision), as long as the robot has
heard every event its base sent: :attr:`BaseMirror.fresh` is False while a goal it sent has
neither started nor ended, and :meth:`BaseMirror.settled` also while a route finished by the
decision's time has no result yet.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from ost_ros.model import Cell, group_period
from ost_ros.realtime.messages import BaseEvent, ObjectInfo
from ost_ros.realtime.world import (
    ABORTED,
    REACHED,
    REFUSED,
    Carry,
    CarryStarted,
    Detection,
    Feedback,
    Follow,
    Goal,
    GoalResult,
    GoalStarted,
    Route,
    Stalled,
    carry_departures,
    follow_departures,
)
from ost_ros.search import route as xy_route
from ost_ros.team import TeamInfo

Motion = GoalStarted | Stalled | CarryStarted | GoalResult  # what moves the picture


@dataclass
class BaseMirror:
    """What a robot knows of its own base's motion (see the module docstring). ``destination``:
    an object's destination (a carry's route ends there); ``group_period``: the period of a group
    carrying together."""

    agent: int
    cell: Cell  # where it stands (route None), or stood when its route began
    period: int
    destination: Callable[[int], Cell]
    group_period: Callable[[Sequence[int]], int]
    time: float = 0.0  # since when it stands at ``cell``
    goal: int = 0  # the goal running on the base (the last one that took over)
    kind: str = ""  # follow, stand, hold, carry, or "" (nothing running)
    route: Route | None = None
    offset: int = 0  # a FOLLOW path's index of route.cells[i] is i - offset
    holding: int = -1  # the object it holds or carries
    sensed: tuple[ObjectInfo, ...] = ()  # what it senses standing at ``cell`` (from a result)
    _sent: dict[int, Goal] = field(default_factory=dict)  # goals sent, neither started nor ended

    def sent(self, gid: int, goal: Goal) -> None:
        """The robot sent goal ``gid`` to its base."""
        self._sent[gid] = goal

    @property
    def fresh(self) -> bool:
        """Every goal sent has started or ended: the picture is the base's."""
        return not self._sent

    def settled(self, at: float) -> bool:
        """Whether the picture holds at ``at``: every goal sent has started or ended, and the goal
        running is not over by then by its own route — a route its base has finished by ``at``
        waits for its result, which comes after every detection on the way (decided on the
        prediction, a sweep ended before its last finds were in, and they were dropped: the
        objects were never carried)."""
        if self._sent:
            return False
        r = self.route
        return r is None or r.arrive(len(r.cells) - 1) > at + 1e-9

    def take(self, ev: Motion, sensed: tuple[ObjectInfo, ...] = ()) -> None:
        """One of its base's events (``sensed``: with a result, what it senses where it stands)."""
        if isinstance(ev, GoalStarted):
            self._start(ev)
        elif isinstance(ev, Stalled):
            if self.route is not None:
                self.route.shift(ev.time, ev.steps)
        elif isinstance(ev, CarryStarted):
            if self.agent in ev.group and self.kind == "hold" and self.holding == ev.object:
                cells = xy_route([self.cell, self.destination(ev.object)])
                k = self.group_period(ev.group)
                self.route = Route(
                    cells, ev.time, carry_departures(ev.time, len(cells) - 1, k, ev.factor), ev.factor
                )
                self.kind = "carry"
        elif isinstance(ev, GoalResult):
            self._end(ev, sensed)

    def _start(self, ev: GoalStarted) -> None:
        goal = self._sent.pop(ev.goal, None)
        self.goal, self.cell, self.time = ev.goal, ev.cell, ev.time
        self.route, self.holding, self.offset, self.sensed = None, -1, 0, ()
        if isinstance(goal, Follow):
            self.kind = "follow" if math.isfinite(ev.first) else "done"
            if self.kind == "follow":
                cells = list(goal.path) if ev.offset == 0 else [ev.cell, *goal.path]
                departs = follow_departures(ev.first, len(cells) - 1, self.period, ev.factor)
                self.route, self.offset = Route(cells, ev.time, departs, ev.factor), ev.offset
        elif isinstance(goal, Carry):
            self.kind, self.holding = "hold", goal.object
        else:
            self.kind = "stand"

    def _end(self, ev: GoalResult, sensed: tuple[ObjectInfo, ...]) -> None:
        if ev.outcome == REFUSED:
            self._sent.pop(ev.goal, None)  # it never took over: what ran runs on
        elif ev.outcome in (REACHED, ABORTED) and ev.goal == self.goal:
            self.cell, self.time, self.route, self.kind, self.holding = ev.cell, ev.time, None, "done", -1
            self.sensed = sensed

    def feedback(self, at: float) -> Feedback:
        """Where the base will be at its first cell boundary at or after ``at`` (a move under way
        is completed): as ``RealtimeWorld.feedback`` answers, what it senses only where it stands
        since a result (a robot on the move hears of its finds by its detections)."""
        r = self.route
        if r is None:
            sensed = self.sensed if self.kind == "done" else ()
            return Feedback(self.agent, max(at, self.time), self.cell, self.goal, -1, -1, sensed)
        m, time = r.boundary(at)
        index = m - self.offset if self.kind == "follow" else -1
        carrying = self.holding if self.kind == "carry" else -1
        return Feedback(self.agent, time, r.cells[m], self.goal, index, carrying, ())


def mirror_of(team: TeamInfo, agent: int, destination: Callable[[int], Cell]) -> BaseMirror:
    """The picture of robot ``agent``'s base at the start: at its base, nothing running."""
    periods = dict(zip(team.agent_ids, team.periods or (1,) * team.size))
    return BaseMirror(
        agent,
        team.bases[team.index(agent)],
        periods[agent],
        destination,
        lambda group: group_period([periods[j] for j in group]),
    )


# ----------------------------------------------------------------------------- on the wire

Event = GoalStarted | Stalled | CarryStarted | GoalResult | Detection


def pack(agent: int, seq: int, ev: Event, sensed: tuple[ObjectInfo, ...] = ()) -> BaseEvent:
    """Event number ``seq`` of ``agent``'s base as it travels to the robot (``sensed``: with a
    result, what the robot senses where it stands)."""
    if isinstance(ev, GoalStarted):
        return BaseEvent(agent, seq, "started", ev.goal, ev.time, ev.cell, ev.offset, ev.first, ev.factor)
    if isinstance(ev, Stalled):
        return BaseEvent(agent, seq, "stalled", t=ev.time, steps=ev.steps)
    if isinstance(ev, CarryStarted):
        return BaseEvent(agent, seq, "lifted", t=ev.time, factor=ev.factor, object=ev.object, group=ev.group)
    if isinstance(ev, Detection):
        return BaseEvent(
            agent, seq, "detected", t=ev.time, cell=ev.cell, objects=ev.objects, sensed=ev.sensed
        )
    return BaseEvent(
        agent,
        seq,
        "ended",
        ev.goal,
        ev.time,
        ev.cell,
        sensed=sensed,
        outcome=ev.outcome,
        code=ev.code,
        reason=ev.reason,
    )


KINDS = ("started", "stalled", "lifted", "detected", "ended")


def unpack(m: BaseEvent) -> Event:
    """The event a :class:`BaseEvent` carries (its ``sensed`` for a result is the caller's to
    read); ValueError for a kind it does not know."""
    if m.kind == "started":
        return GoalStarted(m.agent, m.goal, m.t, m.cell, m.offset, m.first, m.factor)
    if m.kind == "stalled":
        return Stalled(m.agent, m.t, m.steps)
    if m.kind == "lifted":
        return CarryStarted(m.object, m.group, m.t, m.factor)
    if m.kind == "detected":
        return Detection(m.agent, m.t, m.cell, m.objects, m.sensed)
    if m.kind == "ended":
        return GoalResult(m.agent, m.goal, m.outcome, m.t, m.cell, m.code, m.reason)
    raise ValueError(f"kind {m.kind!r} is not one of {', '.join(KINDS)}")
