"""What the world and agent nodes of a realtime run share on the wire (docs/realtime.md): topic,
action and service names, and the message kinds. Names are relative (under the node's namespace),
as the lockstep's (:mod:`ost_ros.node.transport`)."""

from __future__ import annotations

from ost_ros import protocols
from ost_ros.realtime.messages import Lost, RtStatus

MARKS = "marks"  # agents → agents (and the world): watermarks
NEEDS = "needs"  # agents → agents: a batch waits for watermarks
LOST = "lost"  # world → agents: stamped failure notices (latched)
DIGESTS = "digests"  # agents → world (and anyone): coordination digests

__all__ = ["DIGESTS", "LOST", "MARKS", "NEEDS", "Lost", "message_kinds"]


def message_kinds(protocol: str) -> tuple[type, ...]:
    """The robot-to-robot message kinds of a realtime run: the protocol's, and a survivor's status
    after a failure (the realtime comm modules say it as ``RtStatus``)."""
    return (*protocols.get(protocol).messages, RtStatus)


def follow_action(agent: int) -> str:
    """The robot's base: ``ost_msgs/action/FollowCells``."""
    return f"agent_{agent}/follow_cells"


def where_service(agent: int) -> str:
    """Where the robot's base will be next: ``ost_msgs/srv/Where``."""
    return f"agent_{agent}/where"


def detections_topic(agent: int) -> str:
    """World → the robot: objects coming into its sensor (``ost_msgs/msg/Detection``)."""
    return f"agent_{agent}/detections"


def pose_topic(agent: int) -> str:
    """World → anyone: the robot's pose (``geometry_msgs/msg/PoseStamped``, frame ``map``)."""
    return f"agent_{agent}/pose"
