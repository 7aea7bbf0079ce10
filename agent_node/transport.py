"""What the world node and the agent nodes share on the wire: topic names, QoS, decoding.

Every runtime message is JSON text (:mod:`ost_msgs_py.codec`) in ``std_msgs/msg/String``.
QoS per topic (see docs/ros.md): everything the lockstep needs is reliable + keep-all, so no
sample of a step is ever dropped (loss would break agreement); discovery hand-shakes and the
result are transient-local, so a late joiner still gets them.
"""

from __future__ import annotations

import faulthandler
import hashlib
import time

from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from ost_msgs_py import codec
from ost_msgs_py.codec import MessageError
from ost_ros import protocols
from ost_ros.model import Scenario
from ost_ros.scenario import dump_scenario

NAMESPACE = "/ost"
WORLD_NODE = "world"

CLOCK = "/clock"
MARKERS = "/ost/markers"
ACTED = "/ost/acted"  # agent → world
STEP_MESSAGES = "/ost/step_messages"  # agent → all agents
RESEND = "/ost/resend"  # agent → agents: publish a lost batch again
READY = "/ost/ready"  # agent → world
RUN_END = "/ost/run_end"  # world → all agents
REPORTS = "/ost/reports"  # agent → world
RESULT = "/ost/result"  # world → anyone


def channel_topic(channel: str) -> str:
    """Agent → all agents: a protocol's own channel (e.g. NCP's ``negotiation``), in its runs only."""
    return f"{NAMESPACE}/{channel}"


def agent_node_name(agent_id: int) -> str:
    return f"agent_{agent_id}"


def tick_topic(agent_id: int) -> str:
    """World → one agent: its observation of the step (one topic per robot, like a sensor)."""
    return f"{NAMESPACE}/{agent_node_name(agent_id)}/tick"


def alive_topic(agent_id: int) -> str:
    """Agent → world: nothing is published; its liveliness (QoS, asserted by DDS itself) is
    how the world learns that the robot's process is gone."""
    return f"{NAMESPACE}/{agent_node_name(agent_id)}/alive"


# Liveliness lease (s): an agent whose liveliness is lost for it and then for as long again (with
# nothing heard from it) is declared failed by the world: detection in about 2 leases.
FAILURE_TIMEOUT_S = 1.0


def alive_qos(lease_s: float) -> QoSProfile:
    """AUTOMATIC liveliness with a finite lease: the DDS participant asserts it from its own
    thread, so a busy Python agent is never mistaken for a dead one; a killed process stops
    asserting and the world's reader reports it within the lease. ``lease_s`` <= 0: no lease."""
    return QoSProfile(
        depth=1,
        history=HistoryPolicy.KEEP_LAST,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
        liveliness=LivelinessPolicy.AUTOMATIC,
        liveliness_lease_duration=Duration(seconds=max(lease_s, 0.0)),
    )  # 0: infinite


# If a step stalls this long, the missing samples are asked for again (world: ticks and run_end;
# agents: peers' step messages). Reliable QoS should make this unnecessary; it is the safety net
# for a sample lost while endpoints were still completing discovery.
RESEND_S = 1.0

# Lockstep traffic: nothing may be lost or overwritten.
LOCKSTEP_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
# Hand-shakes and reports: also delivered to a subscriber that appears later.
LATCHED_ALL_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# The result: the last one is what counts.
RESULT_QOS = QoSProfile(
    depth=1,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# Display and time: only the newest sample matters (reliable also matches best-effort readers).
LATEST_QOS = QoSProfile(
    depth=1,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

# Topic → (QoS, who publishes, who subscribes): the documented graph, checked by the tests.
TOPICS: dict[str, tuple[QoSProfile, str]] = {
    CLOCK: (LATEST_QOS, "rosgraph_msgs/msg/Clock"),
    MARKERS: (LATEST_QOS, "visualization_msgs/msg/MarkerArray"),
    ACTED: (LOCKSTEP_QOS, "std_msgs/msg/String"),
    STEP_MESSAGES: (LOCKSTEP_QOS, "std_msgs/msg/String"),
    RESEND: (LOCKSTEP_QOS, "std_msgs/msg/String"),
    READY: (LATCHED_ALL_QOS, "std_msgs/msg/String"),
    RUN_END: (LATCHED_ALL_QOS, "std_msgs/msg/String"),
    REPORTS: (LATCHED_ALL_QOS, "std_msgs/msg/String"),
    RESULT: (RESULT_QOS, "std_msgs/msg/String"),
}


def protocol_topics(protocol: str) -> dict[str, tuple[QoSProfile, str]]:
    """Topics only a run of the given protocol has (same QoS and type as the step messages)."""
    return {channel_topic(c): (LOCKSTEP_QOS, "std_msgs/msg/String") for c in protocols.get(protocol).channels}


def scenario_fingerprint(scenario: Scenario) -> str:
    """Short hash of the scenario: the world refuses agents that loaded a different one."""
    return hashlib.sha256(dump_scenario(scenario).encode()).hexdigest()[:16]


def to_string(msg) -> String:
    return String(data=codec.encode(msg))


class Throttle:
    """At most one warning per (topic, sender) every ``period`` seconds; counts the rest."""

    def __init__(self, logger, period: float = 5.0):
        self.logger = logger
        self.period = period
        self._last: dict[tuple[str, str], float] = {}
        self._muted: dict[tuple[str, str], int] = {}

    def warn(self, topic: str, sender: str, text: str) -> None:
        """A dropped message: names the topic and the sender."""
        self.note((topic, sender), f"dropped message on {topic} from {sender}: {text}")

    def note(self, key: tuple[str, str], text: str) -> None:
        """Any warning, throttled per ``key``."""
        now = time.monotonic()
        if now - self._last.get(key, -1e9) < self.period:
            self._muted[key] = self._muted.get(key, 0) + 1
            return
        muted = self._muted.pop(key, 0)
        self._last[key] = now
        more = f" ({muted} more suppressed)" if muted else ""
        self.logger.warning(f"{text}{more}")


def decode_or_warn(msg: String, topic: str, expected, throttle: Throttle):
    """The decoded message, or None after a throttled warning naming the sender."""
    try:
        return codec.decode(msg.data, expected)
    except MessageError as exc:
        throttle.warn(topic, codec.sender_of(msg.data), str(exc))
        return None


# rcl now and then spins forever inside destroy_node (busy, holding the GIL; seen twice in about
# 600 node processes here, once at exit and once destroying a node right after creating it), so
# a node process could hang after its work is done.
DESTROY_TIMEOUT_S = 5.0


def guard_exit(seconds: float = DESTROY_TIMEOUT_S) -> None:
    """Arm a C-level watchdog (faulthandler's own thread needs no GIL): if the process is still
    alive ``seconds`` from now it prints where it hangs and exits with code 1."""
    faulthandler.dump_traceback_later(seconds, exit=True)
