"""What every world and agent node does around its runtime, whatever its kind (lockstep, realtime,
and the kinds to come): once here, so a new node kind composes it instead of copying it.

World side (the lockstep and realtime world nodes; the membership role watches liveliness too):

- :class:`Readiness`: the agents' ``ready`` hand-shakes, one per robot of the team that loaded
  the world's scenario;
- :class:`Liveliness`: every robot's ``alive`` topic with its lease — who was seen, who is a
  suspect (liveliness lost), who is due to be declared failed or out;
- :class:`SignalFiles`: the files the run's supervisor polls (``ready_file``, ``progress_file``);
- :class:`Result`: the result's JSON to ``result_file`` and ``result``, and when to leave after it.

Agent side (the lockstep ``agent_node`` and the realtime one):

- :class:`Alive`: the robot's ``alive`` topic — its leased liveliness and the one sample the world
  starts on;
- :func:`awaiting_endpoints`: before its Ready, what discovery lacks, said; the endpoints whose
  matching stopped moving created anew (:func:`renew_endpoints`);
- :class:`Leaving`: when it leaves, its part over;
- :func:`die_at`: fault injection, the process killed as a robot dies.

Any node: :func:`new_readers` — a publisher's readers grew, so what it said before is said again.
"""

from __future__ import annotations

import functools
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription
from std_msgs.msg import String

from ost_ros.lockstep.messages import Ready
from ost_ros.node import transport as tp
from ost_ros.node.run import write_file
from ost_ros.node.signing import NodeAuth

# How often the progress file may change (a file written and renamed costs ~1-2 ms of the world's
# time, which a lockstep waits for; a progress line needs no more than this).
PROGRESS_S = 0.25


class Readiness:
    """The agents' Ready messages (``ready``, latched): kept for a robot of the scenario's team
    that loaded the world's scenario; any other dropped with a warning. ``then()`` runs after
    each one (a world that starts as soon as it can)."""

    def __init__(
        self,
        node: Node,
        ids: tuple[int, ...],
        fingerprint: str,
        guard: NodeAuth,
        throttle: tp.Throttle,
        then: Callable[[], None] = lambda: None,
        later: Collection[int] = (),
    ):
        self.ids, self.fingerprint, self.throttle, self.then = ids, fingerprint, throttle, then
        self.later = frozenset(later)  # robots that join mid-run: not awaited at the start
        self.of: dict[int, Ready] = {}  # agent -> its Ready
        self.sub = tp.subscribe(node, Ready, tp.READY, self.on_ready, tp.LATCHED_ALL_QOS, guard, throttle)

    def on_ready(self, r: Ready) -> None:
        if r.agent not in self.ids:
            self.throttle.warn(self.sub.topic_name, f"agent {r.agent}", "not in the scenario's team")
        elif r.scenario != self.fingerprint:
            self.throttle.warn(
                self.sub.topic_name,
                f"agent {r.agent}",
                f"loaded scenario {r.scenario}, the world runs {self.fingerprint}",
            )
        else:
            self.of[r.agent] = r
        self.then()

    @property
    def complete(self) -> bool:
        return not self.missing()

    def missing(self) -> list[int]:
        """The robots not ready yet, in team order (those that join later aside)."""
        return [i for i in self.ids if i not in self.of and i not in self.later]


class Liveliness:
    """One liveliness reader per robot on its alive topic (:func:`~ost_ros.node.transport.alive_qos`
    with the lease ``lease_s``; none at all when it is 0): a killed robot process is reported
    within the lease. A robot whose liveliness is lost while ``suspect(agent)`` says it matters
    becomes a suspect; anything heard from it clears that (a lossy network can drop the
    assertions of a live robot for a whole lease); a suspect for another lease is due
    (:meth:`check`). ``then()`` runs after each liveliness seen (a world waiting to start on it);
    ``say``: log a suspect that turned out alive."""

    def __init__(
        self,
        node: Node,
        ids: tuple[int, ...],
        lease_s: float,
        suspect: Callable[[int], bool],
        then: Callable[[], None] = lambda: None,
        say: bool = False,
    ):
        self.node, self.lease_s, self.suspect, self.then, self.say = node, lease_s, suspect, then, say
        self.seen: set[int] = set()  # robots whose liveliness (or sample) has come
        self.suspects: dict[int, float] = {}  # liveliness lost since (monotonic s), not yet due
        self.subs: dict[int, Subscription] = {}
        if lease_s > 0:
            for i in ids:
                events = SubscriptionEventCallbacks(
                    liveliness=functools.partial(self.on_liveliness, i), use_default_callbacks=False
                )
                self.subs[i] = node.create_subscription(
                    String,
                    tp.alive_topic(i),
                    functools.partial(self.on_sample, i),
                    tp.alive_qos(lease_s),
                    event_callbacks=events,
                )

    def unseen(self, among: Collection[int]) -> list[int]:
        """Robots of ``among`` whose liveliness has not come (none when nothing is watched)."""
        return sorted(set(among) - self.seen) if self.subs else []

    def on_liveliness(self, agent: int, info: Any) -> None:
        if info.alive_count > 0:
            self.seen.add(agent)
            if self.suspects.pop(agent, None) is not None and self.say:
                self.node.get_logger().info(f"agent {agent}: liveliness back; not failed")
            self.then()
            return
        if info.not_alive_count_change > 0 and self.suspect(agent):
            self.suspects.setdefault(agent, time.monotonic())

    def on_sample(self, agent: int, _msg: String | None = None) -> None:
        """The robot's one sample on its alive topic: it is alive (with 50 robots some
        liveliness-changed events never fired at the start; the sample always arrives)."""
        self.seen.add(agent)
        self.heard_from(agent)
        self.then()

    def heard_from(self, agent: int) -> None:
        """Something from ``agent``: not a suspect (it is alive after all)."""
        if self.suspects.pop(agent, None) is not None and self.say:
            self.node.get_logger().info(
                f"agent {agent}: heard from it after its liveliness was lost; not failed"
            )

    def check(self, now: float, declare: Callable[[int], None]) -> None:
        """``declare(agent)`` for each suspect silent for another lease since its loss."""
        for agent, since in list(self.suspects.items()):
            if now - since >= self.lease_s:
                del self.suspects[agent]
                declare(agent)


class SignalFiles:
    """The files a run's supervisor polls (``ost up``): ``ready_file`` once the run starts (the
    bring-up, s) and ``progress_file`` (``step delivered objects``) as it goes — each replaced at
    once; a write error is noted (throttled), never raised: they are a nicety."""

    def __init__(self, p: Mapping[str, Any], throttle: tp.Throttle, who: str = "world"):
        self.ready_file, self.progress_file = str(p["ready_file"]), str(p["progress_file"])
        self.throttle, self.who = throttle, who
        self.progress_at = float("-inf")
        self.shown: tuple[int, int] | None = None

    def ready(self, bring_up_s: float | None) -> None:
        self.write(self.ready_file, f"{bring_up_s or 0.0:.3f}\n", "ready_file")

    def progress(self, step: int, objects: Collection[Any], last: bool = False) -> None:
        """The progress line when it changed, at most every PROGRESS_S (``last``: now);
        ``objects``: the world's, each with its ``delivered`` (None: not yet)."""
        if not self.progress_file:
            return
        clock = time.monotonic()
        if not last and clock - self.progress_at < PROGRESS_S:
            return
        self.progress_at = clock
        now = (step, sum(o.delivered is not None for o in objects))
        if now == self.shown:
            return
        self.shown = now
        self.write(self.progress_file, f"{now[0]} {now[1]} {len(objects)}\n", "progress_file")

    def write(self, path: str, text: str, what: str) -> None:
        if not path:
            return
        try:
            write_file(path, text)
        except OSError as exc:
            self.throttle.note((what, self.who), f"{what}: cannot write ({exc.strerror})")


class Result:
    """The run's result: its JSON to ``result_file`` and on ``result`` (transient local: it stays
    readable while the world runs); then the world leaves (``exit_when_done``) once every agent
    is gone — it has read the result — or after ``linger`` s."""

    def __init__(self, node: Node, p: Mapping[str, Any]):
        self.node = node
        self.file = str(p["result_file"])
        self.exit_when_done, self.linger = bool(p["exit_when_done"]), float(p["linger"])
        self.pub: Publisher = node.create_publisher(String, tp.RESULT, tp.RESULT_QOS)
        self.at: float | None = None  # monotonic time it went out

    def publish(self, text: str) -> float:
        """The result out; the monotonic time it went out."""
        if self.file:
            try:
                write_file(self.file, text + "\n")
            except OSError as exc:
                self.node.get_logger().error(f"result_file: cannot write {self.file} ({exc.strerror})")
        self.pub.publish(String(data=text))
        self.at = time.monotonic()
        return self.at

    def leave(self, now: float, gone: Callable[[], bool]) -> bool:
        """Whether the world may leave now: the result is out, and every agent ``gone()``
        or the linger over."""
        if self.at is None or not self.exit_when_done:
            return False
        return gone() or now - self.at > self.linger


class Alive:
    """A robot's alive topic: its liveliness (MANUAL_BY_TOPIC with the lease ``lease_s``, asserted
    ``ASSERTS`` times a lease from a thread of its own: a robot busy in a long callback still
    asserts, since Python hands the GIL over every few milliseconds) and one sample to every
    reader matched (:meth:`say`) — the world (or the monitor) starts on it."""

    ASSERTS = 4  # assertions per lease: one late or lost assertion is not a lost lease

    def __init__(self, node: Node, me: int, lease_s: float):
        self.me = me
        self.pub: Publisher = node.create_publisher(
            String, tp.alive_topic(me), tp.alive_qos(lease_s, writer=True)
        )
        self.readers = 0  # readers matched when it last said so
        self.stop = threading.Event()
        if lease_s > 0:
            threading.Thread(
                target=self._assert, args=(lease_s / self.ASSERTS,), name="alive", daemon=True
            ).start()

    def _assert(self, period: float) -> None:
        while not self.stop.wait(period):
            try:
                self.pub.assert_liveliness()  # (renewed by rediscover: the attribute is read anew)
            except Exception:
                # a publisher destroyed under it: renewed (rediscover swaps it in a moment
                # later) or the node going away, when its liveliness goes with it
                if not rclpy.ok():
                    return

    def say(self) -> None:
        self.readers = self.pub.get_subscription_count()
        self.pub.publish(String(data=f"agent {self.me}"))

    def again_to_new_readers(self) -> None:
        """A reader came since the last sample (a restarted world): it has not seen it, and the
        liveliness-changed event alone does not always fire for it."""
        back, self.readers = new_readers([self.pub], self.readers)
        if back:
            self.pub.publish(String(data=f"agent {self.me}"))


def renew_endpoints(node: Node, holder: Any, olds: Collection[Any], singles: Collection[str]) -> None:
    """Create ``olds`` anew (an agent node's discovery that stopped moving, ``rediscover_s``)
    where ``holder`` keeps them: its attributes ``singles``, its ``alive.pub``, its ``kind_pubs``
    (kind -> publisher) and ``kind_subs``. Before the run only, when nothing is in flight."""
    for old in olds:
        new = tp.renew(node, old)
        for name in singles:
            if getattr(holder, name) is old:
                setattr(holder, name, new)
        alive = getattr(holder, "alive", None)
        if alive is not None and alive.pub is old:
            alive.pub = new
        holder.kind_pubs = {kind: new if p is old else p for kind, p in holder.kind_pubs.items()}
        holder.kind_subs = [new if s is old else s for s in holder.kind_subs]


def awaiting_endpoints(
    node: Node,
    throttle: tp.Throttle,
    lacking: Sequence[tuple[Any, str, int, int]],
    since: float,
    moved: tp.Unchanged,
    rediscover_s: float,
    renew: Callable[[list[Any]], None],
) -> bool:
    """An agent node before its Ready (both kinds): whether some endpoint is still unmatched —
    ``lacking``: (endpoint, what, matched, needed) of each. Said (throttled) once discovery has
    taken DISCOVERY_NOTE_S since ``since``; when none of those counts has moved for
    ``rediscover_s`` (``moved`` keeps since when), ``renew(endpoints)`` creates them anew."""
    if not lacking:
        return False
    text = [f"{what} {have}/{need}" for _, what, have, need in lacking]
    now = time.monotonic()
    if now - since > tp.DISCOVERY_NOTE_S:
        throttle.note(("start", "agent"), f"not ready yet: {', '.join(text[:6])}")
    if moved.for_s(text, now) > rediscover_s:
        node.get_logger().warning(
            f"discovery has not moved for {rediscover_s:g} s ({', '.join(text[:6])}): "
            "creating those endpoints anew"
        )
        renew([e for e, _, _, _ in lacking])
        moved.restart(now)
    return True


class Leaving:
    """When an agent node leaves, its part over — one rule for both kinds: the result has come
    after its report, and every reader of the report has acknowledged it (the report is
    latched, and a writer gone takes its samples along: leaving at once could take the report
    from a reader that has not read it yet, the world or a recorder; docs/ros.md).

    What else ends a lockstep agent (``agent_node``) is its own, and a realtime robot has neither:
    the world gone for ``WORLD_LOST_S`` (a realtime robot is cut from the world by a partition
    for longer than that, and the run goes on once it heals: docs/realtime.md), and a result
    before its report (a lockstep world ends a run early when its protocol cannot recover; a
    realtime world asks for the reports, ``run_end``, before any result, and its result may
    overtake ``run_end`` on the way — a result before the report is not the end of its part)."""

    def __init__(self) -> None:
        self.result = False  # the result has come after its report

    def may_leave(self, pub_report: Any) -> bool:
        """Whether it may leave now (asked again until it may)."""
        return self.result and bool(pub_report.wait_for_all_acked(Duration(seconds=0)))


def die_at(node: Node, step: int, now: float) -> None:
    """Fault injection (``die_at_step``, both agent nodes): from sim time ``step`` on (``now``;
    -1: never) the process kills itself with SIGKILL — as a robot dies, with no last word."""
    if 0 <= step <= now:
        node.get_logger().warning(f"die_at_step {step}: killing this process (SIGKILL) at {now:g}")
        sys.stderr.flush()
        os.kill(os.getpid(), signal.SIGKILL)


def new_readers(pubs: Iterable[Any], before: int) -> tuple[bool, int]:
    """Readers back: whether ``pubs`` have more readers than ``before`` (their count at the last
    look), and their count now — a reader that came (a robot that joins, a peer back from a
    partition longer than DDS keeps one, a restarted world) missed what was published before
    it, so the caller says it again. (One reader gone and another come count as none new: the
    caller looks every second or so.)"""
    readers = sum(p.get_subscription_count() for p in pubs)
    return readers > before, readers
