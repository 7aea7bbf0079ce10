"""What a realtime run's nodes call their topics (relative names) and which message kinds go
robot to robot — ROS-free, so the supervisor can name them before it forks the robots (the
Fast DDS profile of a run, :mod:`ost_ros.commands.dds_profile`). The nodes import them from
:mod:`ost_ros.node.realtime`."""

from __future__ import annotations

from ost_ros import protocols
from ost_ros.realtime.messages import Back, Hello, Mark, Need, RtStatus, ScheduleUpdate, Status

MARKS = "marks"  # agents → agents (and the world): watermarks
NEEDS = "needs"  # agents → agents: a batch waits for watermarks
LOST = "lost"  # membership → agents: stamped notices of robots declared out (latched)
HELLOS = "hellos"  # a robot declared out → the team: it asks to come back
STOP_BASES = "stop_bases"  # membership → world: stop a robot's base (declared out)
STOPPED_BASES = "stopped_bases"  # world → membership: stopped, and the facts of its notice
DIGESTS = "digests"  # agents → world (and anyone): coordination digests
BASE_CLOCK = "base_clock"  # world → agents: sim time, and how many events each base has sent
BASE_GOALS = "base_goals"  # agents → world: each robot's goals for its own base
BUNDLES = "bundles"  # membership → agents (fanout:=monitor): the robots' messages, passed on

FANOUTS = ("monitor", "direct")  # how a robot's messages reach its peers (the fanout parameter)


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


def relayed(protocol: str, organisation: str = "distributed") -> tuple[tuple[str, type], ...]:
    """(topic, kind) of what the monitor passes on with ``fanout:=monitor``, in the order a
    bundle's ``kinds`` number them: the robot-to-robot messages, the watermarks, the needs, the
    hellos of robots out."""
    kinds = tuple((str(getattr(k, "TYPE")), k) for k in message_kinds(protocol, organisation))  # noqa: B009
    return (*kinds, (MARKS, Mark), (NEEDS, Need), (HELLOS, Hello))


def everyone_reads(protocol: str, organisation: str, fanout: str) -> tuple[str, ...]:
    """The topics every robot of a realtime run reads (and the membership monitor): each robot's
    messages, watermarks and hellos — or, with ``fanout:=monitor``, the monitor's bundles of them
    (each robot's own topics then have one reader, the monitor) — the membership's notices, the
    bases' clock."""
    if fanout == "monitor":
        return tuple(sorted({BUNDLES, LOST, BASE_CLOCK}))
    kinds = {str(getattr(k, "TYPE")) for k in message_kinds(protocol, organisation)}  # noqa: B009
    return tuple(sorted(kinds | {MARKS, NEEDS, HELLOS, LOST, BASE_CLOCK}))
