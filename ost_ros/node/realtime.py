"""What the world and agent nodes of a realtime run share on the wire (docs/realtime.md): topic,
action and service names, and the message kinds. Names are relative (under the node's namespace),
as the lockstep's (:mod:`ost_ros.node.transport`)."""

from __future__ import annotations

from ost_ros import protocols
from ost_ros.node.params import ParameterError
from ost_ros.realtime.messages import Back, Lost, RtStatus, ScheduleUpdate, Status

MARKS = "marks"  # agents → agents (and the world): watermarks
NEEDS = "needs"  # agents → agents: a batch waits for watermarks
LOST = "lost"  # membership → agents: stamped notices of robots declared out (latched)
HELLOS = "hellos"  # a robot declared out → the team: it asks to come back
STOP_BASES = "stop_bases"  # membership → world: stop a robot's base (declared out)
STOPPED_BASES = "stopped_bases"  # world → membership: stopped, and the facts of its notice
DIGESTS = "digests"  # agents → world (and anyone): coordination digests
BASE_CLOCK = "base_clock"  # world → agents: sim time, and how many events each base has sent
BASE_GOALS = "base_goals"  # agents → world: each robot's goals for its own base

__all__ = [
    "BASE_CLOCK",
    "BASE_GOALS",
    "DIGESTS",
    "HELLOS",
    "LOST",
    "MARKS",
    "NEEDS",
    "STOPPED_BASES",
    "STOP_BASES",
    "Lost",
    "message_kinds",
]


def message_kinds(protocol: str, organisation: str = "distributed") -> tuple[type, ...]:
    """The robot-to-robot message kinds of a realtime run: the protocol's — a survivor's status
    after a failure said as ``RtStatus`` (the lockstep's ``Status`` never goes out), a
    coordinator's update only in the coordinator organisation, a member's ``Back`` readmitting a
    robot — each a topic, so each a reader and a writer per robot to discover (a team of 50
    brings up ~2 200 endpoints)."""
    kinds = [k for k in protocols.get(protocol).messages if k is not Status]
    if organisation != "coordinator":
        kinds = [k for k in kinds if k is not ScheduleUpdate]
    return (*kinds, RtStatus, Back)


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
