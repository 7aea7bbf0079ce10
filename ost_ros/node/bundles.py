"""Fan-out through the membership monitor (``fanout:=monitor``; docs/realtime.md, "Fan-out
through the monitor"): a robot's messages, watermarks and needs go to the monitor alone, which
passes them on to the team in bundles (``<ns>/bundles``, ``ost_msgs/msg/Bundle``).

Why: with ``fanout:=direct`` each sample a robot publishes is delivered to every peer, N × N
deliveries when each of N robots says something (CCP's selections at every coordination: 2 550
at N = 50), and a delivery costs a process about what rclpy takes to hand it over, whatever its
size. Through the monitor it is N deliveries in and one bundle to each robot.

What a receiver trusts is unchanged: each message in a bundle is the bytes its robot sealed, so
a robot checks its own tag in it, the signer and the counter, exactly as if it had come on its
own topic (:class:`~ost_ros.node.transport.Receiver`, bound to that topic's name). The bundle
is not sealed: a stranger's bundle holds nothing a robot accepts. What the monitor can do is
what it could before — hold messages back (every batch already waits for the monitor's
watermark) — not forge or alter one.
"""

from __future__ import annotations

import array
import threading
from collections.abc import Sequence
from typing import Any

import ost_msgs.msg as ros
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node

from ost_msgs_py import auth, cdr
from ost_msgs_py.wire import MessageError
from ost_ros.node import transport as tp

BUNDLE_TYPE = ros.Bundle
BUNDLE = cdr.message_class(BUNDLE_TYPE)
# How long the monitor collects before it passes a bundle on (wall s, from the first message
# of the bundle): the robots' messages of one coordination come within a few milliseconds of
# each other; a step at rtf 100 is 10 ms.
WINDOW_S = 0.002
# A bundle this large goes out at once (bytes): the selections of 50 robots are ~40 kB.
MAX_BYTES = 256 * 1024


class Bundler:
    """The monitor's side: messages to pass on (``add``), published together once ``window_s``
    has passed since the first of them (a one-shot timer on the steady clock) or once they are
    ``MAX_BYTES``."""

    def __init__(self, node: Node, pub: Any, run: str, guard: Any, window_s: float = WINDOW_S):
        self.pub, self.run, self.guard = pub, run, guard
        self.kinds = array.array("B")
        self.sizes = array.array("I")
        self.data = bytearray()
        self.lock = threading.Lock()  # (the world's process: its bases' thread may declare a robot)
        self.bundles = self.messages = 0  # published so far
        wall = RosClock(clock_type=ClockType.STEADY_TIME)
        self.timer = node.create_timer(window_s, self.flush, clock=wall, autostart=False)

    def add(self, kind: int, data: bytes) -> None:
        """Pass ``data`` (a message as its robot sealed it, of kind number ``kind``) on."""
        with self.lock:
            first = not self.kinds
            self.kinds.append(kind)
            self.sizes.append(len(data))
            self.data += data
            full = len(self.data) >= MAX_BYTES
        if full:
            self.flush()
        elif first:
            self.timer.reset()

    def flush(self) -> None:
        """Publish what is collected (nothing: nothing is published)."""
        self.timer.cancel()
        with self.lock:
            if not self.kinds:
                return
            bundle = BUNDLE(run=self.run, kinds=self.kinds, sizes=self.sizes, data=self.data)
            self.messages += len(self.kinds)
            self.kinds, self.sizes, self.data = array.array("B"), array.array("I"), bytearray()
        self.bundles += 1
        self.guard.relay(self.pub, bytes(cdr.encode(bundle)))


class Unbundler:
    """A robot's side: a raw subscription's callback taking a bundle apart, each message to the
    :class:`~ost_ros.node.transport.Receiver` of its kind (its topic's checks, skip and callback).
    A bundle that does not fit — not a bundle, lengths that do not add up, a kind the run does not
    have — is dropped whole or in part with a throttled warning naming it; what fits is taken."""

    __slots__ = ("guard", "receivers", "run", "throttle", "topic")

    def __init__(self, receivers: Sequence[tp.Receiver], run: str, guard: Any, throttle: tp.Throttle):
        self.receivers, self.run, self.guard, self.throttle = tuple(receivers), run, guard, throttle
        self.topic = ""  # fully qualified: set once the subscription exists

    def __call__(self, data: bytes) -> None:
        try:
            b, _end = cdr.decode(BUNDLE, data)
        except MessageError as exc:
            return self.drop(f"{auth.MALFORMED}: {exc}")
        if b.run != self.run:
            return None  # (another run's: not for this robot)
        if len(b.kinds) != len(b.sizes) or sum(b.sizes) != len(b.data):
            return self.drop(
                f"{auth.MALFORMED}: {len(b.kinds)} kinds, {len(b.sizes)} sizes, "
                f"{sum(b.sizes)} of {len(b.data)} bytes"
            )
        view, at, n = memoryview(b.data), 0, len(self.receivers)
        for kind, size in zip(b.kinds, b.sizes, strict=True):
            data_k = bytes(view[at : at + size])
            at += size
            if kind >= n:
                self.drop(f"{auth.MALFORMED}: kind {kind} (this run has {n})")
                continue
            self.receivers[kind](data_k)
        return None

    def drop(self, why: str) -> None:
        self.guard.drop(why)
        self.throttle.warn(self.topic, "a bundle", why)


def receivers_for(
    node: Node,
    topics: Sequence[tuple[str, type]],
    callbacks: Sequence[Any],
    skips: Sequence[Any],
    guard: Any,
    throttle: tp.Throttle,
) -> list[tp.Receiver]:
    """A :class:`~ost_ros.node.transport.Receiver` per relayed topic, bound to the topic's fully
    qualified name (what each message's tags were computed over)."""
    out = []
    for (topic, kind), callback, skip in zip(topics, callbacks, skips, strict=True):
        r = tp.Receiver(kind, callback, guard, throttle, skip=skip)
        r.topic = node.resolve_topic_name(topic)
        out.append(r)
    return out
