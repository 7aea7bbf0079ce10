"""What the world, membership and agent nodes of a realtime run share on the wire
(docs/realtime.md): the topic names and message kinds of :mod:`ost_ros.realtime.topics`
(re-exported here: ROS-free, so the supervisor names them too), each robot's own names (its base's
events, its pose, its base's action) and the ``joins`` parameter read. Names are relative (under
the node's namespace), as the lockstep's (:mod:`ost_ros.node.transport`)."""

from __future__ import annotations

from ost_ros.node.params import ParameterError
from ost_ros.realtime.topics import (
    BASE_CLOCK,
    BASE_GOALS,
    BUNDLES,
    DIGESTS,
    HELLOS,
    LOST,
    MARKS,
    NEEDS,
    STOP_BASES,
    STOPPED_BASES,
    message_kinds,
    relayed,
)

__all__ = [
    "BASE_CLOCK",
    "BASE_GOALS",
    "BUNDLES",
    "DIGESTS",
    "HELLOS",
    "LOST",
    "MARKS",
    "NEEDS",
    "STOPPED_BASES",
    "STOP_BASES",
    "message_kinds",
    "relayed",
]


def joining(text: str) -> frozenset[int]:
    """The robots that join mid-run, from the ``joins`` parameter (``AGENT:T,...``): not in the
    team at the start, so nobody waits for them before it (they come in as a robot declared out
    comes back). A malformed list is a :class:`ParameterError`."""
    out = set()
    for item in (x.strip() for x in text.split(",")):
        if not item:
            continue
        a, sep, t = item.partition(":")
        if not (sep and a.isdigit() and t.isdigit()):
            raise ParameterError(f"joins: expected AGENT:T[,AGENT:T...], got {item!r}")
        out.add(int(a))
    return frozenset(out)


def follow_action(agent: int) -> str:
    """The robot's base: ``ost_msgs/action/FollowCells``."""
    return f"agent_{agent}/follow_cells"


def base_topic(agent: int) -> str:
    """World → the robot: its base's events, numbered, in order (``ost_msgs/msg/BaseEvent``)."""
    return f"agent_{agent}/base"


def pose_topic(agent: int) -> str:
    """World → anyone: the robot's pose (``geometry_msgs/msg/PoseStamped``, frame ``map``)."""
    return f"agent_{agent}/pose"
