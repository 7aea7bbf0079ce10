"""Fan-out through the monitor in process (``ost_ros.node.bundles``): a bundle's messages reach a
robot's receive path each as if it had come on its own topic — checked by the robot's own tag,
signer and counter — and a bundle that does not fit is dropped with one throttled warning."""

import array

import pytest

from ost_msgs_py import auth, cdr, wire
from ost_ros.lockstep.messages import Sample
from ost_ros.node import transport as tp
from ost_ros.node.bundles import BUNDLE, MAX_BYTES, Bundler, Unbundler, receivers_for
from ost_ros.node.signing import NodeAuth
from ost_ros.protocols.ccp.messages import Selection
from ost_ros.realtime.messages import Mark
from ost_ros.realtime.topics import MARKS, NEEDS, relayed

RUN = "abc123"
TOPICS = relayed("ccp")
KIND = {topic: k for k, (topic, _) in enumerate(TOPICS)}


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    d = tmp_path_factory.mktemp("keys")
    auth.make_keys(d, [0, 1, 2], run=RUN)
    return d


def member(keys, who) -> auth.Keys:
    return auth.Keys(auth.load_team(keys), who, auth.load_private(keys, who))


def sealed(k: auth.Keys, value, topic: str) -> bytes:
    s = auth.Sealer(k)
    data = wire.to_cdr(value, run=RUN, counter=s.next(), signer=s.signer, tags=s.size)
    s.seal(data, f"/ost/{topic}", None)
    return bytes(data)


def bundle(items: list[tuple[int, bytes]], run: str = RUN) -> bytes:
    kinds, sizes = array.array("B", [k for k, _ in items]), array.array("I", [len(d) for _, d in items])
    return bytes(cdr.encode(BUNDLE(run=run, kinds=kinds, sizes=sizes, data=b"".join(d for _, d in items))))


class Log:
    def __init__(self):
        self.lines: list[str] = []

    def warning(self, text: str) -> None:
        self.lines.append(text)


class FakeNode:
    """What the bundles need of a node: names resolved in /ost, a one-shot timer."""

    def __init__(self):
        self.timers: list[FakeTimer] = []

    def resolve_topic_name(self, topic: str) -> str:
        return f"/ost/{topic}"

    def create_timer(self, period, callback, clock=None, autostart=True):
        t = FakeTimer(callback)
        self.timers.append(t)
        return t


class FakeTimer:
    def __init__(self, callback):
        self.callback, self.armed = callback, False

    def reset(self):
        self.armed = True

    def cancel(self):
        self.armed = False


class Pub:
    def __init__(self):
        self.sent: list[bytes] = []

    def publish(self, data: bytes) -> None:
        self.sent.append(data)


def robot(keys, who):
    """``who``'s way in for bundles: (the unbundler, what it took, its log, its NodeAuth)."""
    guard, log, took = NodeAuth(member(keys, who)), Log(), []
    throttle = tp.Throttle(log)
    receivers = receivers_for(
        FakeNode(), TOPICS, [took.append] * len(TOPICS), [None] * len(TOPICS), guard, throttle
    )
    u = Unbundler(receivers, RUN, guard, throttle)
    u.topic = "/ost/bundles"
    return u, took, log, guard


def selection(sender: int) -> Sample:
    return Sample(Selection(sender, 3, 1, (4, 5)), 3, 1, RUN, 2)


def test_each_message_of_a_bundle_is_taken_as_its_topic_would_take_it(keys):
    sel, mark = selection(0), Mark(0, 2, 1)
    items = [
        (KIND["selection"], sealed(member(keys, 0), sel, "selection")),
        (KIND[MARKS], sealed(member(keys, 0), mark, MARKS)),
    ]
    for who in (1, 2, auth.WORLD):
        u, took, log, guard = robot(keys, who)
        u(bundle(items))
        assert took == [sel, mark] and not log.lines
        u(bundle(items))  # the same again: each refused as a replay, nothing taken twice
        assert took == [sel, mark] and guard.counts()[auth.REPLAYED] == 2


def test_a_message_under_another_topics_kind_is_refused(keys):
    """The tags cover the topic: the monitor cannot pass a robot's mark off as its need."""
    data = sealed(member(keys, 0), Mark(0, 2, 1), MARKS)
    u, took, log, guard = robot(keys, 1)
    u(bundle([(KIND[NEEDS], data)]))
    assert took == [] and sum(guard.counts().values()) == 1
    assert "/ost/needs" in log.lines[0] and "forged" in log.lines[0]


def test_an_altered_or_foreign_message_in_a_bundle_is_dropped_and_the_rest_taken(keys):
    good = sealed(member(keys, 0), Mark(0, 2, 1), MARKS)
    altered = bytearray(sealed(member(keys, 2), Mark(2, 5, 3), MARKS))
    altered[20] ^= 1
    stranger = bytes(wire.to_cdr(Mark(1, 9, 9), run=RUN))  # no keys: no tags
    u, took, log, guard = robot(keys, 1)
    u(bundle([(KIND[MARKS], bytes(altered)), (KIND[MARKS], stranger), (KIND[MARKS], good)]))
    assert took == [Mark(0, 2, 1)] and sum(guard.counts().values()) == 2 and len(log.lines) == 2


@pytest.mark.parametrize(
    "case, why",
    [
        ("not a bundle", "malformed"),
        ("sizes that do not add up", "malformed"),
        ("a kind the run does not have", "malformed: kind 200"),
    ],
)
def test_a_bundle_that_does_not_fit_is_dropped_with_one_line(keys, case, why):
    good = sealed(member(keys, 0), Mark(0, 2, 1), MARKS)
    if case == "not a bundle":
        data = b"\x00\x01\x00\x00\x07"
    elif case == "sizes that do not add up":
        kinds, sizes = array.array("B", [KIND[MARKS]]), array.array("I", [len(good) + 1])
        data = bytes(cdr.encode(BUNDLE(run=RUN, kinds=kinds, sizes=sizes, data=good)))
    else:
        data = bundle([(200, good), (KIND[MARKS], good)])
    u, took, log, guard = robot(keys, 1)
    u(data)
    assert len(log.lines) == 1 and why in log.lines[0] and "/ost/bundles" in log.lines[0]
    assert took == ([Mark(0, 2, 1)] if case.startswith("a kind") else [])
    assert sum(guard.counts().values()) == 1


def test_another_runs_bundle_is_ignored(keys):
    u, took, log, guard = robot(keys, 1)
    u(bundle([(KIND[MARKS], sealed(member(keys, 0), Mark(0, 2, 1), MARKS))], run="other"))
    assert took == [] and not log.lines and sum(guard.counts().values()) == 0


def test_the_monitor_passes_on_what_it_collected_in_one_bundle(keys):
    """One bundle for what came within the window (the timer armed by the first message), in
    the order it came; a full bundle goes out at once."""
    node, pub = FakeNode(), Pub()
    b = Bundler(node, pub, RUN, NodeAuth())
    timer = node.timers[0]
    marks = [sealed(member(keys, i), Mark(i, 2, 1), MARKS) for i in (0, 1, 2)]
    for data in marks:
        b.add(KIND[MARKS], data)
    assert timer.armed and pub.sent == []
    b.flush()
    assert not timer.armed and len(pub.sent) == 1 and (b.bundles, b.messages) == (1, 3)
    u, took, _log, _guard = robot(keys, auth.WORLD)
    u(pub.sent[0])
    assert took == [Mark(i, 2, 1) for i in (0, 1, 2)]
    b.flush()  # nothing collected: nothing sent
    assert len(pub.sent) == 1
    big = marks[0] * (MAX_BYTES // len(marks[0]) + 1)
    b.add(KIND[MARKS], big)
    assert len(pub.sent) == 2 and not timer.armed
