"""``agent_node`` of a realtime run (``realtime:=true``; docs/realtime.md): one robot with no barrier.

The node wires :class:`~ost_ros.realtime.agent.RealtimeAgent` — the protocol's own agent as a set of
callbacks — to DDS, and does nothing else: peers' messages (stamped, each carrying its sender's
watermark, on the protocol's topics; watermarks alone on ``marks``, requests on ``needs``; the
membership monitor's notices on ``lost`` — its own too: declared out, it asks back on ``hellos``
and is readmitted by the team), its base's events (``agent_<i>/base``: numbered, in order) and its
timers go in as they arrive; what the runtime returns — messages to publish, goals for its base,
a timer, a digest — goes out.

**A decision is local.** Where its base will be is the robot's own picture of it
(:class:`~ost_ros.realtime.base.BaseMirror`), kept from the events its base sends anyway (a goal
took over, a stall, a lift, a goal's end) and from its own goals: no question to the world on a
decision's path. Goals go out one way on ``<ns>/base_goals`` (``ost_msgs/BaseGoal``, sealed for
the world), as nav2 takes a goal on ``goal_pose`` beside its action: the base's events say what
became of each. Until a goal it sent has started or ended, a decision waits for that event.

**Time** is the bases' clock ``<ns>/base_clock`` (sim time, steps), extrapolated between two of its
messages at the run's ``rtf`` for the robot's own timers; it never goes back. The same message
says how many events this robot's base has sent up to its time: once all of those are in, the
robot has every base event up to that time and may commit it (:meth:`RealtimeAgent.base_known`)
— never sooner, so a find its base made is never promised away.
"""

from __future__ import annotations

import os
import time
from collections import deque
from typing import Any

from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.publisher import Publisher
from std_msgs.msg import String

from ost_msgs_py import auth, wire
from ost_msgs_py.auth import WORLD
from ost_ros.lockstep.messages import AgentReport, Ready, RunEnd, Sample, ScheduleEntry
from ost_ros.node import realtime as rtp
from ost_ros.node import transport as tp
from ost_ros.node.bundles import BUNDLE_TYPE, Unbundler, receivers_for
from ost_ros.node.params import declare_agent
from ost_ros.node.plumbing import Alive, Leaving, awaiting_endpoints, die_at, new_readers, renew_endpoints
from ost_ros.node.signing import node_auth
from ost_ros.realtime.agent import RealtimeAgent
from ost_ros.realtime.base import mirror_of, unpack
from ost_ros.realtime.membership import misfit
from ost_ros.realtime.messages import (
    Back,
    BaseClock,
    BaseEvent,
    BaseGoal,
    Digest,
    Envelope,
    Hello,
    Lost,
    Mark,
    Need,
)
from ost_ros.realtime.outputs import AskFeedback, Output, Publish, SendGoal, WakeAt
from ost_ros.realtime.remote import BaseLink
from ost_ros.realtime.run import make_agent
from ost_ros.realtime.stamps import LateMessage
from ost_ros.realtime.world import Carry, Follow, GoalResult
from ost_ros.team import TeamInfo

START_S = 0.05  # how often it looks whether its endpoints are matched, before the run
# A robot held up this long (wall) by a batch says what it waits for (throttled): a stalled team
# names the robot it waits on, and that robot says what it waits for.
STALL_S = 5.0
# How often it looks whether it is held up, and whether a peer's readers came back (wall s).
WATCH_S = 1.0
DEBUG = bool(os.environ.get("OST_RT_DEBUG"))


class RealtimeAgentNode(Node):
    """``<ns>/agent_<id>`` of a realtime run (see the module docstring)."""

    def __init__(self, name: str = "agent", **options: Any):
        super().__init__(name, namespace=tp.NAMESPACE, **options)
        p, cfg, scenario, _spec = declare_agent(self)
        ids = tuple(a.id for a in scenario.agents)
        me = p["agent_id"]
        self.me, self.ids, self.p = me, ids, p
        self.joining = rtp.joining(p["joins"])  # robots not in the team at the start (--join)
        team = TeamInfo.from_scenario(scenario)
        # (the world's membership monitor takes part: every batch waits for its watermark too)
        # (counts only in its record: a node's run is as long as it is)
        self.rt: RealtimeAgent = make_agent(
            team, me, p["protocol"], cfg.policy(), cfg.protocol_settings(), monitor=True, whole_record=False
        )
        self.rt.across_a_network()
        self.rt.base_known(-1.0)  # nothing of its base known yet: it commits nothing
        # Its picture of its base and the one decide path (ROS-free, as in process): where an
        # object is carried to is what the robot knows of it (it carries only objects it has
        # heard of)
        self.link = BaseLink(self.rt, mirror_of(team, me, lambda obj: self.rt.destination(obj)))
        self.index = ids.index(me)  # its place in the bases' clock
        self.fingerprint = tp.scenario_fingerprint(scenario)
        self.guard = node_auth(p["keys"], p["insecure"], me)
        self.run = self.guard.run or ""
        self.rtf = float(p["rtf"])
        self.throttle = tp.Throttle(self.get_logger())
        self.done = False
        self.exit_code = 0
        self.ready_sent = self.started = False
        self.clock = (0.0, 0.0)  # (sim time of the last base clock, monotonic time it came)
        self._now = 0.0
        self.base_in = 0  # base events taken, in order (1..base_in)
        self.base_ahead: dict[int, BaseEvent] = {}  # events that came before one still missing
        self.base_owed: deque[tuple[float, int]] = deque()  # (time, events by then) not all in yet
        self.wake_at: float | None = None
        self.report_sent = False
        self.die_at = p["die_at_step"]
        self.early: list[Envelope | Mark | Need | Lost | Hello] = []  # said before its start
        self.created = time.monotonic()
        self.discovery = tp.Unchanged()  # what it lacks, and since when (rediscover_s)
        # The node's ROS clock is the run's sim time (use_sim_time, /clock); its timers run on the
        # steady clock, because it extrapolates sim time between base clock messages at the rtf.
        self.wall = RosClock(clock_type=ClockType.STEADY_TIME)
        self.last_goal = 0  # the id of the goal sent last
        self.said = {"messages": 0, "marks": 0, "needs": 0}  # what it published (the report's log line)
        # Its messages as it sealed them, for a peer that comes back after missing them (below)
        self.originals: list[tuple[Any, bytes]] = []
        self.readers = 0  # the readers its message and mark writers had at the last look
        self.leaving = Leaving()  # (its part is over once the result comes after its report)
        self._build_endpoints()
        self.start_timer = self.create_timer(START_S, self.try_ready, clock=self.wall)
        self.wake_timer = self.create_timer(1.0, self.on_wake, clock=self.wall, autostart=False)
        self.stall_timer = self.create_timer(WATCH_S, self.watch, clock=self.wall)
        self.asking: tuple[float | None, float] = (None, 0.0)  # (the decision waiting, since)

    # ------------------------------------------------------------------ endpoints

    def _build_endpoints(self) -> None:
        q, me, g, th = tp.LOCKSTEP_QOS, self.me, self.guard, self.throttle

        other_run = tp.other_run(self.run)

        def not_for_me(m) -> bool:
            return other_run(m) or m.sender == self.me

        def known(m) -> bool:  # (a copy it has: the world publishes a failed robot's messages again)
            return not_for_me(m) or self.rt.batches.seen(m.sender, m.seq)

        # fanout:=direct: each peer's messages, watermarks and needs on their topics; monitor:
        # the robot's own go to the monitor alone, and the peers' come in the monitor's bundles
        # (ost_ros.node.bundles), each checked as if it had come on its topic
        direct = self.p["fanout"] == "direct"
        kinds = rtp.message_kinds(self.p["protocol"], self.p["coordination"])
        self.kind_pubs: dict[type, Any] = {}
        self.kind_subs = []
        for kind in kinds:
            topic = tp.message_topic(kind)
            self.kind_pubs[kind] = self.create_publisher(
                wire.ros_type(kind), topic, q, event_callbacks=tp.no_events_pub()
            )
            if direct:
                self.kind_subs.append(tp.subscribe(self, kind, topic, self.on_sample, q, g, th, skip=known))
        self.pub_marks = self.create_publisher(
            wire.ros_type(Mark), rtp.MARKS, q, event_callbacks=tp.no_events_pub()
        )
        self.pub_needs = self.create_publisher(
            wire.ros_type(Need), rtp.NEEDS, q, event_callbacks=tp.no_events_pub()
        )
        self.sub_marks = self.sub_needs = self.sub_bundles = None
        if direct:
            self.sub_marks = tp.subscribe(self, Mark, rtp.MARKS, self.take, q, g, th, skip=not_for_me)
            self.sub_needs = tp.subscribe(self, Need, rtp.NEEDS, self.take, q, g, th, skip=not_for_me)
        else:
            relayed = rtp.relayed(self.p["protocol"], self.p["coordination"])
            # (a protocol message as a sample; a mark, need or hello as it is)
            receivers = receivers_for(
                self,
                relayed,
                [self.on_sample if k in kinds else self.take for _t, k in relayed],
                [known if k in kinds else not_for_me for _t, k in relayed],
                g,
                th,
            )
            unbundle = Unbundler(receivers, self.run, g, th)
            self.sub_bundles = self.create_subscription(
                BUNDLE_TYPE, rtp.BUNDLES, unbundle, q, raw=True, event_callbacks=tp.no_events_sub()
            )
            unbundle.topic = self.sub_bundles.topic_name
        self.sub_lost = tp.subscribe(
            self, Lost, rtp.LOST, self.take, tp.LATCHED_ALL_QOS, g, th, skip=other_run
        )
        # a robot declared out asks to come back on hellos; every member answers with a Back
        self.pub_hellos = self.create_publisher(
            wire.ros_type(Hello), rtp.HELLOS, q, event_callbacks=tp.no_events_pub()
        )
        self.sub_hellos = None  # (fanout:=monitor: in the bundles)
        if direct:
            self.sub_hellos = tp.subscribe(self, Hello, rtp.HELLOS, self.take, q, g, th, skip=not_for_me)
        self.pub_digests = self.create_publisher(
            wire.ros_type(Digest), rtp.DIGESTS, q, event_callbacks=tp.no_events_pub()
        )
        self.sub_clock = tp.subscribe(
            self, BaseClock, rtp.BASE_CLOCK, self.on_base_clock, tp.LATEST_QOS, g, th, skip=other_run
        )
        # (a robot that joins mid-run: the world says its base's events again once this is matched)
        self.sub_base = tp.subscribe(
            self, BaseEvent, rtp.base_topic(me), self.on_base, q, g, th, skip=other_run
        )
        # Its goals for its base, one way: its base's events say what became of them.
        self.pub_goals = self.create_publisher(
            wire.ros_type(BaseGoal), rtp.BASE_GOALS, q, event_callbacks=tp.no_events_pub()
        )
        self.pub_ready = self.create_publisher(wire.ros_type(Ready), tp.READY, tp.LATCHED_ALL_QOS)
        self.pub_report = self.create_publisher(wire.ros_type(AgentReport), tp.REPORTS, tp.LATCHED_ALL_QOS)
        self.sub_end = tp.subscribe(self, RunEnd, tp.RUN_END, self.on_end, tp.LATCHED_ALL_QOS, g, th)
        self.sub_result = self.create_subscription(String, tp.RESULT, self.on_result, tp.RESULT_QOS)
        lease = self.p["failure_timeout"]
        self.alive = Alive(self, me, float(lease)) if lease > 0 else None

    # the endpoints a robot has one of, by attribute (renewed in place: rediscover)
    SINGLE = (
        "pub_marks",
        "sub_marks",
        "pub_needs",
        "sub_needs",
        "sub_bundles",
        "sub_lost",
        "pub_hellos",
        "sub_hellos",
        "pub_digests",
        "sub_clock",
        "sub_base",
        "pub_goals",
    )

    def unmatched(self) -> list[tuple[Any, str, int, int]]:
        """The endpoints whose matching is not complete: (endpoint, what, matched, needed) —
        every peer on every topic (the monitor too on the messages and marks), the world's. A
        robot that joins later is not awaited; and one that joins awaits no peer but one (some may
        be dead by then): beside the world's endpoints and the monitor's, each peer, once
        matched, says everything again to it (:meth:`readers_back`)."""
        n = 1 if self.me in self.joining else len(self.ids) - len(self.joining)
        # (fanout:=monitor: its own are read by the monitor alone, the peers' come in bundles)
        peers = n + 1 if self.sub_bundles is None else 1
        counts: list[tuple[Any, str, int]] = [
            *((pub, f"{tp.message_topic(kind)} readers", peers) for kind, pub in self.kind_pubs.items()),
            *((sub, f"{sub.topic_name} writers", n + 1) for sub in self.kind_subs),
            (self.pub_marks, "marks readers", peers),
            (self.pub_hellos, "hellos readers", n if self.sub_bundles is None else 1),
            (self.pub_needs, "needs readers", n if self.sub_bundles is None else 1),
        ]
        if self.sub_bundles is None:
            counts += [(self.sub_marks, "marks writers", n + 1), (self.sub_needs, "needs writers", n)]
            counts.append((self.sub_hellos, "hellos writers", n))
        else:
            counts.append((self.sub_bundles, "bundles", 1))
        counts += [
            (self.sub_clock, "base_clock", 1),
            (self.sub_base, "base", 1),
            (self.sub_lost, "lost", 1),
            (self.pub_digests, "digests", 1),
            (self.pub_goals, "base_goals", 1),
        ]
        if self.alive is not None:
            counts.append((self.alive.pub, "alive", 1))
        out = []
        for e, what, need in counts:
            have = e.get_subscription_count() if isinstance(e, Publisher) else e.get_publisher_count()
            if have < need:
                out.append((e, what, have, need))
        return out

    def rediscover(self, endpoints: list[Any]) -> None:
        """Create ``endpoints`` anew (the ``rediscover_s`` parameter: Fast DDS now and then never
        pairs one writer with one reader, docs/ros.md); before the run, so nothing is in flight."""
        renew_endpoints(self, self, endpoints, self.SINGLE)

    def try_ready(self) -> None:
        if self.ready_sent:
            return
        if awaiting_endpoints(
            self,
            self.throttle,
            self.unmatched(),
            self.created,
            self.discovery,
            self.p["rediscover_s"],
            self.rediscover,
        ):
            return
        self.ready_sent = True
        self.start_timer.cancel()
        if self.alive is not None:
            self.alive.say()
        ready = Ready(self.me, self.p["protocol"], self.fingerprint, self.p["coordination"])
        self.guard.publish(self.pub_ready, ready)

    # ------------------------------------------------------------------ time

    def now(self) -> float:
        """Sim time: the bases' clock, extrapolated at rtf since it came; never backwards."""
        sim, at = self.clock
        self._now = max(self._now, sim + (time.monotonic() - at) * self.rtf)
        return self._now

    def on_base_clock(self, msg: BaseClock) -> None:
        if not self.ready_sent or self.index >= len(msg.events):
            return
        self.clock = (msg.t, time.monotonic())
        self.base_owed.append((msg.t, msg.events[self.index]))
        if not self.started:
            self.started = True
            self._now = msg.t
            _, self.readers = new_readers(self.said_on(), 0)
            self.out(self.rt.start(self.now()))
            self.take_base()  # what its base said before (what it senses where it stands)
            early, self.early = self.early, []
            for payload in early:
                self.take(payload)
            return
        now = self.now()
        die_at(self, self.die_at, now)  # fault injection
        self.base_known()
        self.fire(now)

    def base_known(self) -> None:
        """Its base's events are in up to the latest clock whose count it has reached: it may
        commit that far (and no further)."""
        t = None
        while self.base_owed and self.base_owed[0][1] <= self.base_in:
            t = self.base_owed.popleft()[0]
        if t is not None:
            self.rt.base_known(t)

    def arm(self, t: float) -> None:
        """The wake-up timer for sim time ``t`` (the earliest asked for wins): one timer, set
        again (a timer made and destroyed per wake-up cost half a millisecond each)."""
        if self.wake_at is not None and self.wake_at <= t:
            return
        self.wake_at = t
        delay = max(0.0, (t - self.now()) / self.rtf)
        self.wake_timer.timer_period_ns = max(int(delay * 1e9), 100_000)
        self.wake_timer.reset()

    def on_wake(self) -> None:
        self.wake_timer.cancel()
        self.wake_at = None
        self.fire(self.now())

    def fire(self, now: float) -> None:
        """The runtime's timers due by now (and the time passed committed, as far as it may)."""
        if self.started and not self.report_sent:
            self.out(self.rt.on_clock(now))
            pending = self.rt.next_wake(now)
            if pending is not None:
                self.arm(pending)

    def watch(self) -> None:
        """Say what holds the robot up, once it has waited STALL_S of wall time; say again what
        it said to readers that came back; its part over, whether it may leave."""
        if self.report_sent:
            if self.leaving.may_leave(self.pub_report):
                self.done = True
            return
        self.readers_back()
        if not self.started:
            return
        now, wall = self.now(), time.monotonic()
        base = f"goals sent {self.last_goal}; base events in {self.base_in}"
        held = self.rt.waiting(now)
        if held is not None and now - held[0] > STALL_S * self.rtf:
            self.throttle.note(("stall", "batch"), f"held up at sim time {now:.0f}: {held[1]} ({base})")
        asking = self.rt.asking()
        if asking is None or asking != self.asking[0]:
            self.asking = (asking, wall)
        elif wall - self.asking[1] > STALL_S:
            self.throttle.note(
                ("stall", "base"),
                f"held up at sim time {now:.0f}: the decision of time {asking:g} has waited "
                f"{wall - self.asking[1]:.0f} s for its base to start or end the goal sent last ({base})",
            )

    def said_on(self) -> list[Publisher]:
        """The writers of what it says to its peers (their readers, counted: :meth:`readers_back`)."""
        return [*self.kind_pubs.values(), self.pub_marks]

    def readers_back(self) -> None:
        """A peer cut off longer than DDS keeps a participant (its lease: a network partition)
        comes back as a new match, and what was published meanwhile never reaches it: reliable
        delivery is per match. So when its writers' readers grow again, the robot publishes
        every message it sent again, as it sealed them (a receiver drops the copies it has), and
        its watermark (a Mark: the batches a peer waits for complete). A short cut needs none of
        this: DDS repairs it (docs/realtime.md, "Partitions over DDS"). (In process:
        ``_Run.heal``.) So ``originals`` (every message it sealed) stay whole for the run: a robot
        that joins, or comes back from such a cut, needs every message from the start to compute
        the same schedule."""
        back, self.readers = new_readers(self.said_on(), self.readers)
        if not back or not self.started:
            return
        for pub, data in self.originals:
            self.guard.relay(pub, data)
        self.said["again"] = self.said.get("again", 0) + 1
        if not self.done:  # its watermark, the batch it waits for asked again, a Hello if out
            self.out(self.rt.again(self.now()))

    # ------------------------------------------------------------------ what comes in

    def on_sample(self, s: Sample) -> None:
        self.take(Envelope(s.message.sender, s.seq, s.step, s.message, s.watermark))

    def take(self, payload: Envelope | Mark | Need | Lost | Hello) -> None:
        """What peers (and the monitor) say, as it comes — its own notice too: declared out (a
        lossy link, a stall longer than the lease), it stops, asks to come back and is readmitted
        by the team as its next life (docs/realtime.md, "Who is in the team")."""
        if not self.started:
            # a peer that heard the first clock sooner has started and spoken: kept for the start
            # (dropped, its message or watermark was lost for good and batch 1 with it)
            self.early.append(payload)
            return
        why = misfit(payload, self.ids, self.rt.comm.incarnation)
        if why is not None:  # (a copy of the newest life's is fine: said again after a cut)
            self.guard.drop(f"{auth.STALE}: {why}")
            topic = (
                rtp.HELLOS if isinstance(payload, Hello) else rtp.LOST if isinstance(payload, Lost) else ""
            )
            topic = topic or tp.message_topic(Back)
            self.throttle.warn(topic, f"agent {getattr(payload, 'sender', '?')}", f"{auth.STALE}: {why}")
            return
        if not self.report_sent and not self.done:
            try:
                self.out(self.rt.on_message(payload, self.now()))
            except LateMessage as exc:  # a peer broke its watermark: said, never a crash
                self.throttle.note(("late", str(getattr(payload, "sender", "?"))), f"dropped: {exc}")

    def on_base(self, m: BaseEvent) -> None:
        """One of its base's events: taken in their order (one topic, reliable: one that comes
        early waits for those before it), from its start on."""
        if m.seq <= self.base_in or m.agent != self.me:
            return
        self.base_ahead[m.seq] = m
        if self.started:
            self.take_base()

    def take_base(self) -> None:
        while self.base_in + 1 in self.base_ahead:
            self.base_in += 1
            self.base_event(self.base_ahead.pop(self.base_in))
        self.base_known()
        self.out(self.link.retry(self.now()))  # the decision waiting for its picture, if one does

    def base_event(self, m: BaseEvent) -> None:
        try:
            ev = unpack(m)
        except ValueError as exc:
            self.throttle.warn(self.sub_base.topic_name, "the world", str(exc))
            return
        if isinstance(ev, GoalResult) and ev.outcome == "preempted" and ev.goal == self.last_goal:
            # not by itself: another client's goal (an operator's) took its base over
            ev = GoalResult(ev.agent, ev.goal, "aborted", ev.time, ev.cell, "PREEMPTED", ev.reason)
        if DEBUG:
            self.get_logger().info(f"base event {m.seq} {ev} at {self.now():.1f}")
        outputs = self.link.event(ev, m.sensed, self.now())
        if not self.report_sent:  # (its part over: its picture alone)
            self.out(outputs)

    # ------------------------------------------------------------------ what goes out

    def out(self, outputs: list[Output]) -> None:
        for o in outputs:
            if isinstance(o, Publish):
                self.publish(o.payload)
            elif isinstance(o, Digest):
                self.guard.publish(self.pub_digests, o, run=self.run, receivers=(-1,))
            elif isinstance(o, SendGoal):
                self.send(o)
            elif isinstance(o, AskFeedback):
                self.decide(float(o.at))
            elif isinstance(o, WakeAt):
                self.arm(o.time)

    def decide(self, at: float) -> None:
        """Where its base will be, from its own picture of it (:class:`BaseLink`: now, or once
        its base's events make the picture whole)."""
        self.out(self.link.decide(at, self.now()))

    def publish(self, payload: Envelope | Mark | Need | Hello) -> None:
        if DEBUG and isinstance(payload, Envelope):
            self.get_logger().info(f"publish {payload} at {self.now():.1f}")
        if isinstance(payload, Envelope):
            kind = type(payload.message)
            sample = Sample(payload.message, payload.stamp, payload.seq, self.run, payload.implied)
            pub = self.kind_pubs[kind]
            self.originals.append((pub, self.guard.publish(pub, sample)))
            self.said["messages"] += 1
        elif isinstance(payload, Mark):
            self.guard.publish(self.pub_marks, payload, run=self.run)
            self.said["marks"] += 1
        elif isinstance(payload, Hello):
            self.get_logger().warning(
                f"declared out by the team's monitor: asking to come back (life {payload.incarnation})"
            )
            self.guard.publish(self.pub_hellos, payload, run=self.run)
        else:
            self.guard.publish(self.pub_needs, payload, run=self.run)
            self.said["needs"] += 1

    def send(self, o: SendGoal) -> None:
        """A goal for its base, on ``base_goals`` (one way: the base's events say how it went)."""
        self.last_goal = o.id
        self.link.goal(o)
        g = o.goal
        life = self.rt.incarnation
        if isinstance(g, Follow):
            goal = BaseGoal(self.me, o.id, "follow", float(o.at), g.path, state=g.state, life=life)
        elif isinstance(g, Carry):
            goal = BaseGoal(
                self.me, o.id, "carry", float(o.at), object=g.object, group=g.group, state=g.state, life=life
            )
        else:
            kind = "let_go" if g.unless_carrying else "stand"
            goal = BaseGoal(self.me, o.id, kind, float(o.at), state=g.state, life=life)
        self.guard.publish(self.pub_goals, goal, run=self.run, receivers=(WORLD,))
        if DEBUG:
            self.get_logger().info(f"sent goal {o.id} {goal.kind} at {self.now():.1f}")

    # ------------------------------------------------------------------ the end

    def on_end(self, end: RunEnd) -> None:
        if end.run != self.run or self.report_sent:
            return
        self.report_sent = True
        k = self.rt.agent.summary()
        report = AgentReport(
            self.me,
            self.p["protocol"],
            k.trigger,
            k.predicted_makespan,
            k.coordinations,
            tuple(ScheduleEntry(a.object, tuple(a.agents), a.start, a.finish) for a in k.schedule),
            tuple((int(o), int(t)) for o, t in k.found.items()),
            tuple(k.warnings),
            self.rt.record.messages,
            k.view,
            run=self.run,
            dropped=tuple(self.guard.counts().values()),
            lag=float(self.rt.record.max_lag),
        )
        self.guard.publish(self.pub_report, report)
        said = ", ".join(f"{n} {what}" for what, n in self.said.items())
        self.get_logger().info(
            f"report sent: published {said}; took {self.rt.record.batches} batches; "
            f"largest lag {self.rt.record.max_lag:.1f} steps"
        )

    def on_result(self, _msg: String) -> None:
        """The result after its report: it leaves once the report is read (:class:`Leaving`, the
        lockstep agent's rule too; looked at again by :meth:`watch`). One before: not its run's
        end (Leaving says why)."""
        if self.report_sent:
            self.leaving.result = True
            if self.leaving.may_leave(self.pub_report):
                self.done = True
