"""The membership role (``world_node.membership``) in process, on a stand-in for its node (no DDS):
what it hears goes to the monitor through the monitor's API, its ledger of each robot is the
agents' own (``stamps.Ledger``), and every Mark the monitor returns is said — on ``marks``, or in
the bundles with ``fanout:=monitor``."""

import pytest

from ost_msgs_py import cdr, wire
from ost_ros.lockstep.messages import Sample
from ost_ros.node.bundles import BUNDLE
from ost_ros.realtime.membership import MONITOR
from ost_ros.realtime.messages import Hello, Mark, ObjectFound, ObjectInfo
from ost_ros.realtime.topics import BUNDLES, MARKS
from world_node.membership import Membership


class Log:
    def __init__(self):
        self.lines: list[str] = []

    def info(self, text: str) -> None:
        self.lines.append(text)

    warning = error = info


class Pub:
    """A publisher: what it published, raw."""

    def __init__(self, topic: str):
        self.topic_name, self.sent = f"/ost/{topic}", []

    def publish(self, data: bytes) -> None:
        self.sent.append(data)

    def get_subscription_count(self) -> int:
        return 0


class Sub:
    def __init__(self, topic: str, callback):
        self.topic_name, self.callback = f"/ost/{topic}", callback

    def get_publisher_count(self) -> int:
        return 0


class Timer:
    def reset(self) -> None:
        pass

    def cancel(self) -> None:
        pass


class FakeNode:
    """What the membership role needs of its node: endpoints by topic, a timer, a logger."""

    def __init__(self):
        self.pubs: dict[str, Pub] = {}
        self.log = Log()

    def create_publisher(self, _type, topic, _qos, event_callbacks=None) -> Pub:
        return self.pubs.setdefault(topic, Pub(topic))

    def create_subscription(self, _type, topic, callback, _qos, raw=False, event_callbacks=None) -> Sub:
        return Sub(topic, callback)

    def create_timer(self, _period, _callback, clock=None, autostart=True) -> Timer:
        return Timer()

    def get_logger(self) -> Log:
        return self.log


def role(fanout: str, ids=(0, 1, 2, 3)) -> tuple[Membership, FakeNode]:
    """A membership role as ``membership_node`` runs it: a base stopped answers later (None)."""
    p = {
        "keys": "",
        "insecure": True,
        "failure_timeout": 0.0,
        "fanout": fanout,
        "protocol": "ccp",
        "coordination": "distributed",
    }
    node = FakeNode()
    return Membership(node, ids, p, stop=lambda *_: None, now=lambda: 0.0), node  # type: ignore[arg-type]


def said(node: FakeNode, r: Membership) -> list[Mark]:
    """The Marks the monitor said: on ``marks``, or in the bundles (flushed now)."""
    if r.bundler is None:
        data = node.pubs[MARKS].sent
    else:
        r.bundler.flush()
        data = []
        for raw in node.pubs[BUNDLES].sent:
            b, _ = cdr.decode(BUNDLE, raw)
            view, at = memoryview(b.data), 0
            for kind, size in zip(b.kinds, b.sizes):
                if kind == r.kind_of[MARKS]:
                    data.append(bytes(view[at : at + size]))
                at += size
    decode = wire.decoder(Mark)
    marks = [wire.from_ros(decode(d)[0]) for d in data]
    return [m for m in marks if m.sender == MONITOR]  # (the robots' own are passed on too)


def mark(r: Membership, agent: int, watermark: int, seq: int = 0) -> None:
    m = Mark(agent, watermark, seq)
    r.on_mark(r.kind_of[MARKS], m, bytes(wire.to_cdr(m, run="")))


@pytest.mark.parametrize("fanout", ["direct", "monitor"])
def test_a_mark_the_monitor_may_give_on_a_hello_is_said(fanout):
    """Robots 3 and then 2 are declared out, their bases' facts still to come (so nothing was
    ticked since): batch 11 is wanted, and without robot 2 the monitor could commit 50. Robot
    3's Hello (it runs again) ticks the monitor — which commits 50 and returns its Mark: said at
    once (it was dropped before, and no later tick says it again: batch 11 is no longer
    wanted once returned)."""
    r, node = role(fanout)
    for agent, w in ((0, 50), (1, 50), (2, 10), (3, 60)):
        mark(r, agent, w)
    assert r.monitor.committed == 10 and said(node, r) == []
    r.declare(3)
    r.declare(2)
    assert set(r.waiting) == {2, 3} and said(node, r) == []  # (their notices wait for the facts)
    r.on_hello(Hello(3, 1, 0, (0, 0)))
    assert said(node, r) == [Mark(MONITOR, 50, 2)]
    assert r.monitor.committed == 50 and r.monitor.members() == [0, 1, 3]


def test_the_monitor_counts_a_robots_watermark_only_once_it_holds_all_its_messages_before():
    """The role's ledger of a robot is a robot's of a peer: message 2 before message 1 counts
    nothing yet (the monitor relays what it counts); with both, the highest watermark heard; a
    copy again (the monitor's own relay) is nothing new."""
    r, node = role("direct", ids=(0, 1))
    found = ObjectFound(0, 1, ObjectInfo(0, (1, 1), (2, 2), 1))
    kind, pub = r.kind_of["object_found"], node.pubs["object_found"]
    r.on_sample(kind, pub, Sample(found, 5, 2, "", 4), b"two")
    assert r.monitor.heard[0] == (-1, 0)
    r.on_sample(kind, pub, Sample(found, 3, 1, "", 2), b"one")
    assert r.monitor.heard[0] == (4, 2)
    r.on_sample(kind, pub, Sample(found, 3, 1, "", 2), b"one")
    assert [data for _k, _p, data in r.originals[0]] == [b"two", b"one"]
    assert r.monitor.wanted == {3, 5}  # every member will need those batches
