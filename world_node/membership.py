"""Who is in the team, over DDS (realtime runs; docs/realtime.md, "Who is in the team"): the
membership role — apart from the simulator's bases, sensing and clock — and ``membership_node``,
the process that runs it on its own (``ros2 run ost_ros membership_node``, one per team).

    membership_node --ros-args -r __ns:=/ost -p scenario:=run.yaml -p realtime:=true ...
    world_node --ros-args ... -p realtime:=true -p membership:=node   (the world without the role)

The role (:class:`Membership`) is :class:`~ost_ros.realtime.membership.Monitor` on the wire:

- it hears every robot's messages (kept sealed, to relay), watermarks (``marks``, ``needs``),
  and the Hellos of robots that were declared out (``hellos``); it notes of each robot the
  highest watermark whose messages it holds all of, commits what every member has passed and
  says so on ``marks`` (sender -2, the monitor) when someone waits — every batch waits for it;
- it watches each robot's liveliness (its ``alive`` topic's lease); silent too long, the robot is
  declared out: its base stopped (``stop_bases`` → the world, which answers the notice's facts on
  ``stopped_bases``; in the world's process, a call), its stamped notice on ``lost`` (latched),
  its messages published again as it sealed them;
- a robot out that runs again asks back (Hello); from then on the monitor waits for its watermark,
  and a member readmits it with a stamped Back (the world takes its base back at its robot's
  first goal of the new life).

By default (``membership:=node``, what ``ost up --realtime`` starts) this node's process runs the
role and the world has none at all; with ``membership:=world`` the world node runs it in its own
process and no membership node is started. On real bases this node and the agents are the team:
nothing of the simulator decides who is in.
"""

from __future__ import annotations

import contextlib
import functools
import math
import sys
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

from rclpy.node import Node

from ost_msgs_py import auth, wire
from ost_ros.lockstep.messages import RunEnd, Sample
from ost_ros.node import realtime as rtp
from ost_ros.node import transport as tp
from ost_ros.node.bundles import BUNDLE_TYPE, Bundler
from ost_ros.node.params import ParameterError, declare_role, node_scenario
from ost_ros.node.plumbing import Liveliness, new_readers
from ost_ros.node.run import run_node
from ost_ros.node.signing import NodeAuth, node_auth
from ost_ros.realtime.membership import Declaration, Monitor
from ost_ros.realtime.messages import Back, BaseStopped, Hello, Lost, Mark, Need, StopBase
from ost_ros.realtime.stamps import Ledger
from ost_ros.runconfig import WORLD

START_S = 0.05  # (standalone) how often it looks whether every endpoint is matched


# (agent, now, until, life) -> the notice's facts now, or None: they come on stopped_bases
Stopper = Callable[[int, float, float, int], BaseStopped | None]


class Membership:
    """The membership role of a node (the world's, or ``membership_node``'s): see the module
    docstring. ``stop`` stops a robot's base and returns its notice's facts (or None: they come
    later, :meth:`stopped`); ``now`` is sim time for the log (the world's clock, if it has one);
    ``on_out(agent, now)``: a robot was declared out."""

    def __init__(
        self,
        node: Node,
        ids: tuple[int, ...],
        p: dict[str, Any],
        stop: Stopper,
        now: Callable[[], float],
        on_out: Callable[[int, float], None] = lambda a, t: None,
        on_heard: Callable[[], None] = lambda: None,
        absent: frozenset[int] = frozenset(),
        lock: AbstractContextManager | None = None,
    ):
        self.node, self.ids, self.stop, self.now, self.on_out = node, ids, stop, now, on_out
        # robots that join mid-run (--join): out from the start, declared once the run starts
        self.absent = absent
        # the world's state, when the role is in its process (its bases' thread runs beside)
        self.lock = lock if lock is not None else contextlib.nullcontext()
        self.on_heard = on_heard  # (the world ticks faster while robots talk)
        self.guard: NodeAuth = node_auth(p["keys"], p["insecure"], auth.MEMBERSHIP)
        self.run = self.guard.run or ""
        self.throttle = tp.Throttle(node.get_logger())
        self.monitor = Monitor(ids)
        # What it heard of each robot, as a robot's batches keep it of a peer (which messages
        # arrived, the watermarks they and its marks carried): what the monitor may count on is
        # the highest watermark whose messages it holds all of (Ledger.held), since it relays
        # them should the robot be declared out. A watermark not above the last one heard adds
        # nothing (an older mark come late): the monitor may then count on a lower watermark
        # than it could for a while — it commits less and stamps a notice lower, never wrongly.
        self.ledgers = {i: Ledger() for i in ids}
        # Each robot's messages as it sealed them, (its kind's number, the writer, the bytes),
        # for the whole run: a robot that joins (or comes back from a cut longer than DDS keeps a
        # peer) needs every message from the start to compute the same schedule, and the monitor
        # relays them for a robot out or dead, which nobody else would — so they stay whole.
        self.originals: dict[int, list[tuple[int, Any, bytes]]] = {i: [] for i in ids}
        self.waiting: dict[int, Declaration] = {}  # declared, its base's facts to come
        self.started = self.ended = False
        self.failure_timeout = float(p["failure_timeout"])
        self._endpoints(p)

    def _endpoints(self, p: dict[str, Any]) -> None:
        node, q, g, th, quiet = self.node, tp.LOCKSTEP_QOS, self.guard, self.throttle, tp.no_events_pub

        other_run = tp.other_run(self.run)

        def known(m) -> bool:  # (a copy it holds: a robot says everything again to a new reader)
            return other_run(m) or (m.sender in self.ledgers and self.ledgers[m.sender].has(m.seq))

        self.kind_subs, self.kind_pubs = [], []
        self.readers = 0  # readers of what it says again at the last look (a robot that joins)
        self.looked = 0.0
        # fanout:=monitor: what robots say goes to the monitor alone, which passes it on in
        # bundles (ost_ros.node.bundles); the kinds numbered as rtp.relayed lists them
        self.bundler: Bundler | None = None
        if p["fanout"] == "monitor":
            pub_bundles = node.create_publisher(BUNDLE_TYPE, rtp.BUNDLES, q, event_callbacks=quiet())
            self.bundler = Bundler(node, pub_bundles, self.run, g)
        # each relayed topic's number in a bundle's kinds
        self.kind_of = {
            topic: i for i, (topic, _k) in enumerate(rtp.relayed(p["protocol"], p["coordination"]))
        }
        for kind in rtp.message_kinds(p["protocol"], p["coordination"]):
            topic = tp.message_topic(kind)
            pub = node.create_publisher(wire.ros_type(kind), topic, q, event_callbacks=quiet())
            self.kind_pubs.append(pub)
            on = functools.partial(self.on_sample, self.kind_of[topic], pub)
            self.kind_subs.append(tp.subscribe(node, kind, topic, on, q, g, th, keep_bytes=True, skip=known))
        self.pub_lost = node.create_publisher(wire.ros_type(Lost), rtp.LOST, tp.LATCHED_ALL_QOS)
        self.pub_marks = node.create_publisher(wire.ros_type(Mark), rtp.MARKS, q, event_callbacks=quiet())
        on_mark = functools.partial(self.on_mark, self.kind_of[rtp.MARKS])
        on_need = functools.partial(self.on_mark, self.kind_of[rtp.NEEDS])
        keep = self.bundler is not None
        self.sub_marks = tp.subscribe(
            node, Mark, rtp.MARKS, on_mark, q, g, th, keep_bytes=keep, skip=other_run
        )
        self.sub_needs = tp.subscribe(
            node, Need, rtp.NEEDS, on_need, q, g, th, keep_bytes=keep, skip=other_run
        )
        self.sub_hellos = tp.subscribe(
            node, Hello, rtp.HELLOS, self.on_hello, q, g, th, keep_bytes=keep, skip=other_run
        )
        # Liveliness: a robot's lease lapsing makes it a suspect; silent on, it is declared out.
        self.alive = Liveliness(
            node, self.ids, self.failure_timeout, suspect=lambda _i: self.started and not self.ended
        )

    def lacking(self) -> list[str]:
        """What the run's start waits for on the monitor's side: every robot's writers matched,
        its liveliness seen, every robot reading notices."""
        n, out = len(self.ids) - len(self.absent), []
        writers = min((s.get_publisher_count() for s in self.kind_subs), default=n)
        if writers < n or self.sub_marks.get_publisher_count() < n:
            out.append(f"message writers {writers}/{n}")
        unseen = self.alive.unseen([i for i in self.ids if i not in self.absent])
        if unseen:
            out.append(f"liveliness from {unseen[:8]}")
        if self.pub_lost.get_subscription_count() < n:
            out.append("lost readers")
        if self.bundler is not None and self.bundler.pub.get_subscription_count() < n:
            out.append(f"bundles readers {self.bundler.pub.get_subscription_count()}/{n}")
        return out

    # ------------------------------------------------------------------ what robots say

    def start(self) -> None:
        """The run has started (the first thing a robot said): the robots that join later are
        declared out now, before the monitor commits anything — so every batch from the first
        on counts them out, as it does a robot silent from the start."""
        if self.started:
            return
        self.started = True
        with self.lock:  # (a callback: in the world's process, its bases' thread runs beside)
            for a in sorted(self.absent):
                self.declare(a)

    def on_sample(self, kind: int, pub: Any, s: Sample, data: bytes) -> None:
        sender = s.message.sender
        ledger = self.ledgers.get(sender)
        if ledger is None or not ledger.arrived(s.seq):
            return  # (a copy it holds: its own relay)
        ledger.mark(s.watermark, s.seq)
        self.start()
        self.on_heard()
        self.originals[sender].append((kind, pub, data))
        if self.bundler is not None:
            self.bundler.add(kind, data)
        self.alive.heard_from(sender)
        if getattr(s.message, "SHARED", True):
            self.monitor.want(s.step)  # every member will need that batch
        if isinstance(s.message, Back):
            why = self.monitor.misfit(s.message)
            if why is not None:
                self.stale(tp.message_topic(Back), sender, why)
                return
            self.monitor.readmitted(s.message)
        self.heard_from(sender)

    def on_mark(self, kind: int, m: Mark | Need, data: bytes = b"") -> None:
        ledger = self.ledgers.get(m.sender)
        if ledger is None:
            return  # (its own)
        if self.bundler is not None:
            self.bundler.add(kind, data)
        self.start()
        self.on_heard()
        ledger.mark(m.watermark, m.seq)
        self.alive.heard_from(m.sender)
        if isinstance(m, Need):
            self.monitor.want(m.stamp)
        self.heard_from(m.sender)

    def on_hello(self, h: Hello, data: bytes = b"") -> None:
        """A robot declared out asks to come back: from now on the monitor waits for its
        watermark again (a member readmits it with a stamped Back). With ``fanout:=monitor`` the
        members hear it from the monitor: passed on as it came (each member judges it)."""
        if self.bundler is not None:
            self.bundler.add(self.kind_of[rtp.HELLOS], data)
        why = self.monitor.misfit(h)
        if why is not None:
            self.stale(rtp.HELLOS, h.sender, why)
        elif h.sender in self.ledgers:
            self.node.get_logger().info(f"agent {h.sender} asks to come back (life {h.incarnation})")
            # (what it may commit now — a batch wanted since a declaration whose base has not
            # answered yet, say — goes out at once: hear ticks)
            self.announce(self.monitor.hear(h, math.inf))

    def stale(self, topic: str, sender: int, why: str) -> None:
        """A membership message that does not fit the team: dropped, counted, warned (throttled)."""
        self.guard.drop(f"{auth.STALE}: {why}")
        self.throttle.warn(topic, f"agent {sender}", f"{auth.STALE}: {why}")

    def heard_from(self, agent: int) -> None:
        """What the monitor may count on of ``agent`` moved: it commits what every member has
        passed, and says so if someone waits. (Every base event up to that watermark was handled
        by the robot, so what it sensed up to there it reported in those messages.)"""
        ledger = self.ledgers[agent]
        w, s = ledger.held()
        ledger.forget(w)  # (the watermarks below it are of no more use: the ledger stays short)
        self.monitor.note(agent, w, s)
        self.announce(self.monitor.tick(math.inf))

    def end(self) -> None:
        """The run is over: nobody is declared from now on; what was passed on, said."""
        self.ended = True
        if self.bundler is not None:
            self.bundler.flush()
            b = self.bundler
            self.node.get_logger().info(f"fanout: passed on {b.messages} messages in {b.bundles} bundles")

    def announce(self, marks: list[Mark]) -> None:
        for m in marks:
            if self.bundler is None:
                self.guard.publish(self.pub_marks, m, run=self.run)
            else:
                self.bundler.add(self.kind_of[rtp.MARKS], self.guard.encode(self.pub_marks, m, run=self.run))

    def relay(self, originals: list[tuple[int, Any, bytes]]) -> None:
        """Say robots' messages again, as they sealed them: on their topics, or in bundles."""
        for kind, pub, data in originals:
            if self.bundler is None:
                self.guard.relay(pub, data)
            else:
                self.bundler.add(kind, data)

    # ------------------------------------------------------------------ silence

    def check_suspects(self, wall: float) -> None:
        self.alive.check(wall, self.declare)
        if wall - self.looked >= 1.0:
            self.looked = wall
            self.readers_back()

    def readers_back(self) -> None:
        """A robot that joins (or one back from a partition longer than DDS keeps a peer) is a
        new reader, and what was published before never reaches it; the live robots say their
        own again (``RealtimeAgentNode.readers_back``), and the monitor relays the originals of
        the robots out or dead, which nobody else would."""
        pubs = self.kind_pubs if self.bundler is None else [self.bundler.pub]
        back, self.readers = new_readers(pubs, self.readers)
        if not back or not self.started:
            return
        if self.bundler is None:
            for a in self.monitor.away():
                self.relay(self.originals[a])
            return
        # fanout:=monitor: the robots' own topics have one reader, the monitor, so nobody but
        # the monitor can say again what a new reader missed: every message (the watermarks a
        # new reader lacks it asks for: a Need, which the members answer)
        for a in self.ids:
            self.relay(self.originals[a])

    def declare(self, agent: int) -> None:
        """The robot is silent too long: declared out with a notice stamped one above the last
        watermark whose messages the monitor holds all of (counting those messages: it relays
        them, so each member can have them all; its sensing counted up to that watermark); its
        base stopped, the notice's facts from it."""
        d = self.monitor.declare(agent)
        if d is None:
            return
        now = self.now()
        facts = self.stop(agent, now, float(d.watermark), d.life)
        if facts is None:
            self.waiting[agent] = d  # its base answers on stopped_bases
        else:
            self.publish_notice(d, facts)

    def stopped(self, facts: BaseStopped) -> None:
        """A base stopped for a declaration: its notice goes out."""
        d = self.waiting.get(facts.agent)
        if d is None or d.life != facts.life:
            self.throttle.warn(
                "stopped_bases", f"agent {facts.agent}", f"no declaration of life {facts.life} waits"
            )
            return
        del self.waiting[facts.agent]
        self.publish_notice(d, facts)

    def publish_notice(self, d: Declaration, f: BaseStopped) -> None:
        notice = Lost(
            d.agent,
            d.stamp,
            f.dropped,
            seq=d.seq,
            at=f.at,
            delivered=f.delivered,
            incarnation=d.life,
            serial=d.serial,
        )
        self.guard.publish(self.pub_lost, notice, run=self.run)
        self.relay(self.originals[d.agent])  # as it was sealed by the robot itself
        why = (
            "joins later"
            if d.agent in self.absent and d.life == 0
            else f"no liveliness for 2 x {self.failure_timeout:g} s"
        )
        self.node.get_logger().warning(
            f"agent {d.agent} out ({why}) at sim time "
            f"{f.t:.1f}: notice stamped {d.stamp} (life {d.life}), its sensing counted up to {d.watermark}"
        )
        self.on_out(d.agent, f.t)
        self.announce(self.monitor.tick(math.inf))


class MembershipNode(Node):
    """``<ns>/membership``: the membership role in a process of its own (the world node with
    ``membership:=node`` has none)."""

    def __init__(self):
        super().__init__("membership", namespace=tp.NAMESPACE)
        p = declare_role(self, WORLD)
        scenario = node_scenario(p)
        self.ids = tuple(a.id for a in scenario.agents)
        self.done = False
        self.role = Membership(self, self.ids, p, self.stop, lambda: -1.0, absent=rtp.joining(p["joins"]))
        g, th, q = self.role.guard, self.role.throttle, tp.LOCKSTEP_QOS
        other_run = tp.other_run(self.role.run)
        self.pub_stop = self.create_publisher(wire.ros_type(StopBase), rtp.STOP_BASES, q)
        self.sub_stopped = tp.subscribe(
            self, BaseStopped, rtp.STOPPED_BASES, self.role.stopped, q, g, th, skip=other_run
        )
        self.sub_end = tp.subscribe(self, RunEnd, tp.RUN_END, self.on_end, tp.LATCHED_ALL_QOS, g, th)
        self.timer = self.create_timer(START_S, self.on_tick)
        self.get_logger().info(
            f"membership of {len(self.ids)} robots; failure timeout {p['failure_timeout']:g} s"
        )

    def stop(self, agent: int, now: float, until: float, life: int) -> None:
        self.role.guard.publish(
            self.pub_stop, StopBase(agent, life, until), run=self.role.run, receivers=(auth.WORLD,)
        )

    def on_tick(self) -> None:
        self.role.check_suspects(time.monotonic())

    def on_end(self, end: RunEnd) -> None:
        if end.run == self.role.run and not self.done:
            self.role.end()
            self.done = True


def main(args=None) -> int:
    try:
        return run_node(
            "membership_node",
            MembershipNode,
            args,
            done=lambda node: node.done,
            code=lambda node: 0,
            interrupted=130,
        )
    except ParameterError as exc:  # (run_node reports its own; a belt for direct calls)
        print(f"membership_node: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
