"""What the world, agent and watch nodes share on the wire: topic names, types, QoS, and the way
in of a message (:func:`subscribe`: raw bytes, checked, decoded, or dropped with a warning).

Every topic name is relative, so it lives under the node's namespace (default ``/ost``; ``-r
__ns:=/team_a`` moves a whole team). Each protocol message kind has a topic of its own, named by
its kind (``object_found``, ``selection``, ``help_request``, ...; a run has the topics of its
protocol only) and typed by its ``ost_msgs`` interface; the lockstep has ``agent_<i>/tick``,
``acted``, ``ready``, ``run_end``, ``reports``, ``resend``. QoS per topic (docs/ros.md):
everything the lockstep needs is reliable + keep-all, so no sample of a step is ever dropped
(loss would break agreement); discovery hand-shakes and the result are transient-local, so a
late joiner still gets them. Every message of the run travels as the CDR bytes of its interface,
sealed (:class:`ost_ros.node.signing.NodeAuth`) and taken raw; display and tool topics (clock,
markers, result, alive, poses, the base's action) are ordinary typed traffic.
"""

from __future__ import annotations

import hashlib
import json
import re
import time
from collections.abc import Callable
from typing import Any

from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription

from ost_msgs_py import auth, wire
from ost_msgs_py.wire import MessageError
from ost_ros.lockstep.messages import Acted, AgentReport, Ready, Resend, RunEnd, RunInfo, Sample
from ost_ros.model import Scenario
from ost_ros.node.signing import NodeAuth
from ost_ros.scenario import scenario_to_dict

NAMESPACE = "/ost"  # the nodes' default namespace
WORLD_NODE = "world"

# Relative names (resolved in the node's namespace).
CLOCK = "clock"  # sim time; remap to /clock for tools that use sim time
MARKERS = "markers"
ACTED = "acted"  # agent → world
RESEND = "resend"  # agent → agents: publish lost messages again
READY = "ready"  # agent → world
RUN_END = "run_end"  # world → all agents
REPORTS = "reports"  # agent → world
RESULT = "result"  # world → anyone (JSON of `ost sim --json`)
RUN_INFO = "run_info"  # world → anyone: run id, scenario, stepping (recorders, live views)


def message_topic(kind: type) -> str:
    """Agent → all agents: the topic of one protocol message kind (its ``TYPE``)."""
    return str(getattr(kind, "TYPE"))  # noqa: B009 - every message class has one (mypy: type)


def agent_node_name(agent_id: int) -> str:
    return f"agent_{agent_id}"


def tick_topic(agent_id: int) -> str:
    """World → one agent: its observation of the step (one topic per robot, like a sensor)."""
    return f"{agent_node_name(agent_id)}/tick"


def alive_topic(agent_id: int) -> str:
    """Agent → world: one sample at the start; then its liveliness (QoS, asserted by DDS itself)
    is how the world learns that the robot's process is gone."""
    return f"{agent_node_name(agent_id)}/alive"


# Discovery taking longer than this is reported (what a node still lacks): 50 agents on two
# cores take 20-40 s to match; a node still unmatched after a minute is stuck.
DISCOVERY_NOTE_S = 60.0


def alive_qos(lease_s: float, writer: bool = False) -> QoSProfile:
    """A finite liveliness lease (``lease_s`` <= 0: none). The robot's writer offers
    MANUAL_BY_TOPIC: :class:`~ost_ros.node.plumbing.Alive` asserts it from a thread of its own, so
    the assertion goes to that topic's readers only (the world's or the monitor's) as a heartbeat
    — AUTOMATIC would have the participant assert it to every participant of the domain, each
    robot receiving every other's: at N=50 most of an idle robot's CPU (docs/realtime.md). A
    killed or stopped process stops asserting and the reader reports it within the lease. The
    readers request AUTOMATIC, which any writer's liveliness satisfies."""
    return QoSProfile(
        depth=1,
        history=HistoryPolicy.KEEP_LAST,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
        liveliness=LivelinessPolicy.MANUAL_BY_TOPIC if writer else LivelinessPolicy.AUTOMATIC,
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

# Topic → (QoS, type): the run's graph, documented in docs/ros.md and checked by the tests.
TOPICS: dict[str, tuple[QoSProfile, str]] = {
    CLOCK: (LATEST_QOS, "rosgraph_msgs/msg/Clock"),
    MARKERS: (LATEST_QOS, "visualization_msgs/msg/MarkerArray"),
    ACTED: (LOCKSTEP_QOS, wire.type_name(Acted)),
    RESEND: (LOCKSTEP_QOS, wire.type_name(Resend)),
    READY: (LATCHED_ALL_QOS, wire.type_name(Ready)),
    RUN_END: (LATCHED_ALL_QOS, wire.type_name(RunEnd)),
    REPORTS: (LATCHED_ALL_QOS, wire.type_name(AgentReport)),
    RESULT: (RESULT_QOS, "std_msgs/msg/String"),
    RUN_INFO: (LATCHED_ALL_QOS, wire.type_name(RunInfo)),
}

# Fast DDS now and then never pairs one writer with one reader while the rest of discovery
# completes: twice in about ten 51-process runs here an agent's writer stayed at 48/50 readers
# for over ten minutes (the readers' side had matched it; the graph seen from outside was whole).
# Matching that has not moved for REDISCOVER_S (the run configuration's default) gets the
# lacking endpoints created anew: a new endpoint is announced and paired afresh (docs/ros.md,
# "discovery that stops moving").


class Unchanged:
    """How long a value (what discovery lacks) has stayed the same."""

    def __init__(self) -> None:
        self.value: object = None
        self.since = 0.0

    def for_s(self, value: object, now: float) -> float:
        if value != self.value:
            self.value, self.since = value, now
        return now - self.since

    def restart(self, now: float) -> None:
        self.since = now


def renew(node: Node, endpoint: Any) -> Any:
    """A new endpoint like ``endpoint`` — publisher or subscription, same type, topic, QoS,
    callback and raw or not, no default event handlers — the old one destroyed (see
    REDISCOVER_S)."""
    if isinstance(endpoint, Publisher):
        pub = node.create_publisher(
            endpoint.msg_type, endpoint.topic, endpoint.qos_profile, event_callbacks=no_events_pub()
        )
        node.destroy_publisher(endpoint)
        return pub
    sub = node.create_subscription(
        endpoint.msg_type,
        endpoint.topic,
        endpoint.callback,
        endpoint.qos_profile,
        event_callbacks=no_events_sub(),
        raw=endpoint.raw,
    )
    node.destroy_subscription(endpoint)
    return sub


def no_events_pub() -> PublisherEventCallbacks:
    """For the many per-kind and per-agent endpoints: no default event handlers. Each handler is
    a waitable that every wait of the executor adds to its wait set — one wait per sample, so on
    the busiest endpoints the handlers cost more than the samples (an incompatible-QoS reader is
    still refused by DDS; the ros2 tool that brings it warns)."""
    return PublisherEventCallbacks(use_default_callbacks=False)


def no_events_sub() -> SubscriptionEventCallbacks:
    """See :func:`no_events_pub`."""
    return SubscriptionEventCallbacks(use_default_callbacks=False)


def sender_of(value: Any) -> str:
    """Who a message dataclass (or Sample) is from, for warnings: ``agent 3``, ``the world``."""
    return wire.sender_of(value.message if isinstance(value, Sample) else value)


def scenario_fingerprint(scenario: Scenario) -> str:
    """Short hash of the scenario: the world refuses agents that loaded a different one. (Of its
    canonical JSON: the YAML text took every robot 0.15 CPU-s at N=50 M=200, a tenth of its start.)"""
    text = json.dumps(scenario_to_dict(scenario), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


_DIGITS = re.compile(r"\d+")


class Throttle:
    """At most one warning per key (topic, sender, reason) every ``period`` seconds; counts the rest."""

    def __init__(self, logger, period: float = 5.0):
        self.logger = logger
        self.period = period
        self._last: dict[tuple[str, str], float] = {}
        self._muted: dict[tuple[str, str], int] = {}

    def warn(self, topic: str, sender: str, text: str) -> None:
        """A dropped message: names the topic and the sender; throttled per topic, sender and
        kind of reason (its text, numbers aside: unsigned, forged how, replayed, which field)."""
        key = (topic, f"{sender}: {_DIGITS.sub('#', text)}")
        self.note(key, f"dropped message on {topic} from {sender}: {text}")

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


Skip = Callable[[Any], bool]


def other_run(run: str) -> Skip:
    """A ``skip`` for :func:`subscribe`: a message of another run than ``run`` (a stray node's)."""
    return lambda m: m.run != run


class Receiver:
    """A raw subscription's callback: the bytes of a sample in, its dataclass out to ``callback``
    (a :class:`~ost_ros.lockstep.messages.Sample` for a protocol message; with the bytes as
    received too, ``keep_bytes``) — or dropped, counted, with a throttled warning naming the topic,
    the sender it claims and why.

    In this order: the receiver's own tag (a secure run: :meth:`ost_msgs_py.auth.Checker.check`;
    nothing that fails it is decoded), the bytes decoded into the interface's light message
    (:func:`ost_msgs_py.wire.decode`), ``skip`` (a message the node already has, by its content:
    ignored, neither counted nor warned about), the signer is the sender the message claims
    (forged), the signer's counter (replayed), the dataclass (its own checks). The replay window
    comes last of the checks, unlike the tag: a dead robot's messages relayed to those that hold
    them carry their original counters (``skip`` must see them first), and a message refused for
    its claim must mark no counter as seen (messages sealed with a stolen robot key but claiming
    others, counted from the thief's clock, would push the robot's window past its own next
    counters). Warnings are built only for a dropped message."""

    __slots__ = ("callback", "decode", "guard", "keep_bytes", "kind", "skip", "throttle", "topic")

    def __init__(
        self,
        kind: type,
        callback: Callable[..., Any],
        guard: NodeAuth,
        throttle: Throttle,
        keep_bytes: bool = False,
        skip: Skip | None = None,
    ):
        self.kind, self.callback, self.guard, self.throttle = kind, callback, guard, throttle
        self.keep_bytes, self.skip = keep_bytes, skip
        self.decode = wire.decoder(kind)
        self.topic = ""  # fully qualified: set by subscribe() once the subscription exists

    def __call__(self, data: bytes) -> None:
        value = self.receive(data)
        if value is not None:
            if self.keep_bytes:
                self.callback(value, data)
            else:
                self.callback(value)

    def receive(self, data: bytes) -> Any:
        """The dataclass of ``data``, or None (skipped, or dropped and counted)."""
        checker = self.guard.checker
        if checker is not None:
            why = checker.check(data, self.topic)
            if why is not None:
                return self.drop(data, why)
        try:
            msg, end = self.decode(data)
        except MessageError as exc:
            return self.drop(data, f"{auth.MALFORMED}: {exc}")
        if self.skip is not None and self.skip(msg):
            return None
        if checker is not None:
            a = msg.auth
            if end != len(data) or len(a.tags) != checker.size:  # (the tags checked were not its own)
                return self.drop(data, f"{auth.MALFORMED}: its bytes do not end with its tag vector", msg)
            claimed = auth.claimed_signer(msg)
            if claimed != a.signer:
                who = "nobody" if claimed is None else auth.signer_name(claimed)
                return self.drop(
                    data, f"{auth.FORGED}: sealed by {auth.signer_name(a.signer)}, sent as {who}", msg
                )
            why = checker.fresh(a.signer, a.counter)
            if why is not None:
                return self.drop(data, why, msg)
        try:
            return wire.from_ros(msg)
        except MessageError as exc:
            return self.drop(data, f"{auth.MALFORMED}: {exc}", msg)

    def drop(self, data: bytes, why: str, msg: Any = None) -> None:
        self.guard.drop(why)
        if msg is None:  # who it claims to be from: decoded now, for the warning only
            try:
                msg = self.decode(data)[0]
            except MessageError:
                msg = None
        self.throttle.warn(self.topic, wire.sender_of(msg), why)


def subscribe(
    node: Node,
    kind: type,
    topic: str,
    callback: Callable[..., Any],
    qos: QoSProfile,
    guard: NodeAuth,
    throttle: Throttle,
    keep_bytes: bool = False,
    skip: Skip | None = None,
    events: bool = False,
) -> Subscription:
    """A raw subscription to ``topic`` (relative) for the interface of the message dataclass
    ``kind``: ``callback(value)`` — ``callback(value, data)`` with ``keep_bytes`` — for each
    sample that passes the checks (:class:`Receiver`). ``events``: rclpy's default event
    handlers (off: see :func:`no_events_sub`)."""
    receiver = Receiver(kind, callback, guard, throttle, keep_bytes, skip)
    sub = node.create_subscription(
        wire.ros_type(kind),
        topic,
        receiver,
        qos,
        raw=True,
        event_callbacks=None if events else no_events_sub(),
    )
    receiver.topic = sub.topic_name
    return sub
