"""``agent_node`` of a realtime run (``realtime:=true``; docs/realtime.md): one robot with no barrier.

The node wires :class:`~ost_ros.realtime.agent.RealtimeAgent` — the protocol's own agent as a set of
callbacks — to DDS, and does nothing else: peers' messages (stamped ``Envelope`` s on the
protocol's topics, watermarks on ``marks``, requests on ``needs``, the world's notices on
``lost``), its base's events (the ``FollowCells`` action's results and lift feedback, its
``detections``, ``where`` answers) and its timers go in as they arrive; what the runtime returns —
messages to publish, goals for its base, a question for ``where``, a timer, a digest — goes out.

Time is the world's ``<ns>/clock`` (sim time, steps), extrapolated between two clock messages at
the run's ``rtf`` so the robot's own timers are exact; it never goes back. A base event that comes
later than the robot's clock (the network) is taken then, and a message it causes is stamped
then: the agreement holds, only a little time is lost.
"""

from __future__ import annotations

import functools
import os
import signal
import time
from typing import Any

from ost_msgs.action import FollowCells
from ost_msgs.srv import Where
from rclpy.action import ActionClient
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from ost_msgs_py import wire
from ost_msgs_py.wire import MessageError
from ost_ros.lockstep.messages import AgentReport, Ready, RunEnd, Sample, ScheduleEntry
from ost_ros.node import realtime as rtp
from ost_ros.node import transport as tp
from ost_ros.node.params import declare_agent
from ost_ros.node.signing import node_auth
from ost_ros.realtime.agent import AskFeedback, Output, Publish, RealtimeAgent, SendGoal, WakeAt
from ost_ros.realtime.messages import Digest, Envelope, Lost, Mark, Need, ObjectInfo
from ost_ros.realtime.run import make_agent
from ost_ros.realtime.stamps import LateMessage
from ost_ros.realtime.world import Carry, CarryStarted, Detection, Feedback, Follow, GoalResult, Stand
from ost_ros.team import TeamInfo

START_S = 0.05  # how often it looks whether its endpoints are matched, before the run
# A service answer can be lost while the world's reply writer has not yet matched this client's
# reader (the request side matched first): the warm-up question is asked again after this long.
# The base's action has two such reply paths (the goal's acceptance, its result): a robot that
# never heard its first goal's acceptance would never commit its time, and hold its team up.
WARM_RETRY_S = 1.0
WARM_GOAL = 0  # the warm-up goal's id (the robot's own goals count from 1)
# A robot held up this long (wall) by a batch says what it waits for (throttled): a stalled team
# names the robot it waits on, and that robot says what it waits for.
STALL_S = 5.0


class RealtimeAgentNode(Node):
    """``<ns>/agent_<id>`` of a realtime run (see the module docstring)."""

    def __init__(self, name: str = "agent"):
        super().__init__(name, namespace=tp.NAMESPACE)
        p, cfg, scenario, _spec = declare_agent(self)
        ids = tuple(a.id for a in scenario.agents)
        me = p["agent_id"]
        self.me, self.ids, self.p = me, ids, p
        self.rt: RealtimeAgent = make_agent(
            TeamInfo.from_scenario(scenario), me, p["protocol"], cfg.policy(), cfg.protocol_settings()
        )
        self.rt.remote_base = True
        self.fingerprint = tp.scenario_fingerprint(scenario)
        self.guard = node_auth(p["keys"], p["insecure"], me)
        self.run = self.guard.run or ""
        self.rtf = float(p["rtf"])
        self.throttle = tp.Throttle(self.get_logger())
        self.done = False
        self.exit_code = 0
        self.ready_sent = self.started = False
        self.clock = (0.0, 0.0)  # (sim time, monotonic time it came)
        self._now = 0.0
        self.goal_kind: dict[int, tuple[int, tuple[int, ...]]] = {}  # goal id -> (object, group)
        self.wake_timer: Any = None
        self.wake_at: float | None = None
        self.report_sent = False
        self.die_at = p["die_at_step"]
        # Where its base stands idle since its last goal ended (time, cell, goal, what it senses):
        # where-am-I is answered here then, without a round trip to the world.
        self.idle: tuple[float, tuple[int, int], int, tuple] | None = None
        self.warm: Any = None
        self.warm_at = 0.0
        self.early: list[Envelope | Mark | Need | Lost] = []  # what peers said before its start
        self.warm_goal_at: float | None = None  # when the warm-up goal went out
        self.warm_goal_done = False  # its acceptance and its result came back
        self.created = time.monotonic()
        # The node's ROS clock is the run's sim time (use_sim_time, /clock); its timers run on the
        # steady clock, because it extrapolates sim time between clock messages at the run's rtf.
        self.wall = RosClock(clock_type=ClockType.STEADY_TIME)
        self.last_goal = 0  # the id of the goal sent last
        self.accepted = 0  # the latest goal whose acceptance came back
        self.ended = 0  # the latest goal whose result came back
        self.ask_at: float | None = None  # a where-am-I held (until an acceptance or a result)
        self.follow_end: dict[int, tuple[int, tuple[int, int]]] = {}  # FOLLOW id -> (cells, last)
        self.said = {"messages": 0, "marks": 0, "needs": 0}  # what it published (the report's log line)
        self._build_endpoints()
        self.start_timer = self.create_timer(START_S, self.try_ready, clock=self.wall)
        self.stall_timer = self.create_timer(STALL_S / 2, self.watch, clock=self.wall)
        self.asking: tuple[float | None, float] = (None, 0.0)  # (the decision asking, since)

    # ------------------------------------------------------------------ endpoints

    def _build_endpoints(self) -> None:
        q, me = tp.LOCKSTEP_QOS, self.me
        g, th = self.guard, self.throttle

        def other_run(m) -> bool:  # (checked before the replay window: tp.Receiver)
            return m.run != self.run

        def not_for_me(m) -> bool:
            return m.run != self.run or m.sender == self.me

        self.kind_pubs: dict[type, Any] = {}
        self.kind_subs = []
        for kind in rtp.message_kinds(self.p["protocol"]):
            topic = tp.message_topic(kind)
            self.kind_pubs[kind] = self.create_publisher(wire.ros_type(kind), topic, q)
            self.kind_subs.append(
                tp.subscribe(
                    self,
                    kind,
                    topic,
                    functools.partial(self.on_sample, self.resolve_topic_name(topic)),
                    q,
                    g,
                    th,
                    events=True,
                    # (a copy it has: the world publishes a failed robot's messages again)
                    skip=lambda m: not_for_me(m) or self.rt.batches.seen(m.sender, m.seq),
                )
            )
        self.pub_marks = self.create_publisher(wire.ros_type(Mark), rtp.MARKS, q)
        self.sub_marks = tp.subscribe(
            self, Mark, rtp.MARKS, self.on_mark, q, g, th, skip=not_for_me, events=True
        )
        self.pub_needs = self.create_publisher(wire.ros_type(Need), rtp.NEEDS, q)
        self.sub_needs = tp.subscribe(
            self, Need, rtp.NEEDS, self.on_need, q, g, th, skip=not_for_me, events=True
        )
        self.sub_lost = tp.subscribe(
            self, Lost, rtp.LOST, self.on_lost, tp.LATCHED_ALL_QOS, g, th, skip=other_run, events=True
        )
        self.pub_digests = self.create_publisher(wire.ros_type(Digest), rtp.DIGESTS, q)
        self.sub_clock = self.create_subscription(Clock, tp.CLOCK, self.on_clock, tp.LATEST_QOS)
        self.sub_det = tp.subscribe(
            self,
            Detection,
            rtp.detections_topic(me),
            self.on_detection,
            q,
            g,
            th,
            skip=other_run,
            events=True,
        )
        self.base = ActionClient(self, FollowCells, rtp.follow_action(me))
        self.where = self.create_client(Where, rtp.where_service(me))
        self.pub_ready = self.create_publisher(wire.ros_type(Ready), tp.READY, tp.LATCHED_ALL_QOS)
        self.pub_report = self.create_publisher(wire.ros_type(AgentReport), tp.REPORTS, tp.LATCHED_ALL_QOS)
        self.sub_end = tp.subscribe(
            self, RunEnd, tp.RUN_END, self.on_end, tp.LATCHED_ALL_QOS, g, th, events=True
        )
        self.sub_result = self.create_subscription(String, tp.RESULT, self.on_result, tp.RESULT_QOS)
        lease = self.p["failure_timeout"]
        self.pub_alive = None
        if lease > 0:
            self.pub_alive = self.create_publisher(String, tp.alive_topic(me), tp.alive_qos(float(lease)))

    def lacking(self) -> list[str]:
        """What is not matched yet: every peer on every topic, the world's endpoints."""
        n, out = len(self.ids), []
        for kind, pub in self.kind_pubs.items():
            if pub.get_subscription_count() < n + 1:  # the team and the world
                out.append(f"{tp.message_topic(kind)} readers")
        for sub in self.kind_subs:
            if sub.get_publisher_count() < n + 1:
                out.append(f"{sub.topic_name} writers")
        if self.pub_marks.get_subscription_count() < n + 1 or self.sub_marks.get_publisher_count() < n:
            out.append("marks")
        if self.pub_needs.get_subscription_count() < n or self.sub_needs.get_publisher_count() < n:
            out.append("needs")
        for what, ok in (
            ("clock", self.sub_clock.get_publisher_count() >= 1),
            ("detections", self.sub_det.get_publisher_count() >= 1),
            ("lost", self.sub_lost.get_publisher_count() >= 1),
            ("digests", self.pub_digests.get_subscription_count() >= 1),
            ("follow_cells", self.base.server_is_ready()),
            ("where", self.where.service_is_ready()),
            ("alive", self.pub_alive is None or self.pub_alive.get_subscription_count() >= 1),
        ):
            if not ok:
                out.append(what)
        return out

    def try_ready(self) -> None:
        if self.ready_sent:
            return
        lacking = self.lacking()
        if lacking:
            if time.monotonic() - self.created > tp.DISCOVERY_NOTE_S:
                self.throttle.note(("start", "agent"), f"not ready yet: not matched {lacking[:8]}")
            return
        wall = time.monotonic()
        # first calls set up the reply paths (both at once): not at the run's first decision
        base_warm = self.base_warm(wall)
        if self.warm is None or (not self.warm.done() and wall - self.warm_at > WARM_RETRY_S):
            if self.warm is not None:
                self.where.remove_pending_request(self.warm)
                self.throttle.note(("start", "where"), "where-am-I not answered yet: asking again")
            self.warm, self.warm_at = self.where.call_async(Where.Request(at=0.0)), wall
            return
        if not self.warm.done() or not base_warm:
            return
        r = self.warm.result()
        if r is not None:  # the base at sim time 0 (the world does not move before the start)
            sensed = tuple(wire.from_ros_value(ObjectInfo, o, "where.sensed") for o in r.sensed)
            self.idle = (0.0, (r.cell.x, r.cell.y), int(r.goal), sensed)
        self.ready_sent = True
        self.start_timer.cancel()
        if self.pub_alive is not None:
            self.pub_alive.publish(String(data=f"agent {self.me}"))
        ready = Ready(self.me, self.p["protocol"], self.fingerprint, self.p["coordination"])
        self.guard.publish(self.pub_ready, ready)

    def base_warm(self, wall: float) -> bool:
        """Whether a goal's acceptance and result reach this robot: a STAND goal before the run,
        which the world accepts and refuses ("the run has not started"), sent again after
        WARM_RETRY_S without both answers."""
        if self.warm_goal_done:
            return True
        if self.warm_goal_at is None or wall - self.warm_goal_at > WARM_RETRY_S:
            if self.warm_goal_at is not None:
                self.throttle.note(("start", "base"), "base goal not answered yet: sending again")
            self.warm_goal_at = wall
            g = FollowCells.Goal()
            g.id, g.kind = WARM_GOAL, FollowCells.Goal.STAND
            self.base.send_goal_async(g).add_done_callback(self.on_warm_accepted)
        return False

    def on_warm_accepted(self, fut) -> None:
        handle = fut.result()
        if handle is None or not handle.accepted:
            self.warm_goal_done = handle is not None  # a rejection came back the same way
            return
        handle.get_result_async().add_done_callback(lambda _f: setattr(self, "warm_goal_done", True))

    # ------------------------------------------------------------------ time

    def now(self) -> float:
        """Sim time: the world's clock, extrapolated at rtf since it came; never backwards."""
        sim, at = self.clock
        self._now = max(self._now, sim + (time.monotonic() - at) * self.rtf)
        return self._now

    def on_clock(self, msg: Clock) -> None:
        t = msg.clock.sec + msg.clock.nanosec * 1e-9
        self.clock = (t, time.monotonic())
        if not self.started:
            if not self.ready_sent:
                return
            self.started = True
            self._now = t
            self.out(self.rt.start(self.now()))
            early, self.early = self.early, []
            for payload in early:
                self.take(payload)
            return
        now = self.now()
        if 0 <= self.die_at <= now:  # fault injection: die as a robot does, with no last word
            self.get_logger().warning(
                f"die_at_step {self.die_at}: killing this process (SIGKILL) at {now:.1f}"
            )
            os.kill(os.getpid(), signal.SIGKILL)
        self.fire(now)

    def arm(self, t: float) -> None:
        """A timer for sim time ``t`` (the earliest asked for wins)."""
        if self.wake_at is not None and self.wake_at <= t:
            return
        self.wake_at = t
        if self.wake_timer is not None:
            self.destroy_timer(self.wake_timer)
        delay = max(0.0, (t - self.now()) / self.rtf)
        self.wake_timer = self.create_timer(max(delay, 1e-4), self.on_wake, clock=self.wall)

    def on_wake(self) -> None:
        if self.wake_timer is not None:
            self.destroy_timer(self.wake_timer)
        self.wake_timer, self.wake_at = None, None
        self.fire(self.now())

    def watch(self) -> None:
        """Say what holds the robot up, once it has waited STALL_S of wall time."""
        if not self.started or self.report_sent:
            return
        now, wall = self.now(), time.monotonic()
        base = f"goals sent {self.last_goal}, accepted {self.accepted}, ended {self.ended}"
        held = self.rt.waiting(now)
        if held is not None and now - held[0] > STALL_S * self.rtf:
            self.throttle.note(("stall", "batch"), f"held up at sim time {now:.0f}: {held[1]} ({base})")
        # a decision waiting for where its base is holds its commit, and so its peers' batches
        asking = self.rt.asking()
        if asking is None or asking != self.asking[0]:
            self.asking = (asking, wall)
        elif wall - self.asking[1] > STALL_S:
            why = "the world's answer"  # a where-am-I is out
            if self.ask_at is not None:  # held until the last goal is accepted, or has ended
                why = "its last goal's " + ("acceptance" if self.accepted < self.last_goal else "result")
            self.throttle.note(
                ("stall", "where"),
                f"held up at sim time {now:.0f}: the decision of time {asking:g} has waited "
                f"{wall - self.asking[1]:.0f} s for where its base is: for {why} ({base})",
            )

    def fire(self, now: float) -> None:
        """The runtime's timers due by now (and the time passed committed)."""
        if self.started and not self.report_sent:
            self.out(self.rt.on_clock(now))
            pending = sorted(w for w in self.rt._wakes if w > now)
            if pending:
                self.arm(pending[0])

    # ------------------------------------------------------------------ what comes in

    def on_sample(self, topic: str, s: Sample) -> None:
        if isinstance(s, Sample):
            env = Envelope(s.message.sender, int(s.seq), int(s.step), s.message)
            self.take(env)

    def on_mark(self, m: Mark) -> None:
        self.take(m)

    def on_need(self, m: Need) -> None:
        self.take(m)

    def on_lost(self, m: Lost) -> None:
        if m.agent == self.me:
            self.declared_failed(m)
        else:
            self.take(m)

    def declared_failed(self, notice: Lost) -> None:
        """The world has declared this robot failed (its liveliness lapsed: a lossy link, a stall
        longer than the lease) and stopped its base; the team has re-planned without it from
        batch ``notice.t`` on. It cannot take part again: it leaves (exit code 1)."""
        if self.done:
            return
        self.get_logger().error(
            f"declared failed by the world at sim time {notice.t} (no liveliness for 2 x "
            f"{self.p['failure_timeout']:g} s; a longer --failure-timeout suits a lossy link): leaving"
        )
        self.exit_code, self.done = 1, True

    def take(self, payload: Envelope | Mark | Need | Lost) -> None:
        if not self.started:
            # a peer that heard the world's first clock sooner has started and spoken: kept for
            # the start (dropped, its message or watermark was lost for good and batch 1 with it
            # — 11 of 50 robots waited on one peer's batch 1 for the rest of a run)
            self.early.append(payload)
            return
        if not self.report_sent and not self.done:
            try:
                self.out(self.rt.on_message(payload, self.now()))
            except LateMessage as exc:  # a peer broke its watermark: said, never a crash
                self.throttle.note(("late", str(getattr(payload, "sender", "?"))), f"dropped: {exc}")

    def on_detection(self, d: Detection) -> None:
        if self.started:
            if os.environ.get("OST_RT_DEBUG"):
                self.get_logger().info(f"t={self._now:.1f} detection {d}")
            self.out(self.rt.on_detection(d, self.now()))

    # ------------------------------------------------------------------ what goes out

    def out(self, outputs: list[Output]) -> None:
        if os.environ.get("OST_RT_DEBUG"):
            self.get_logger().info(f"t={self._now:.1f} out {outputs}")
        for o in outputs:
            if isinstance(o, Publish):
                self.publish(o.payload)
            elif isinstance(o, Digest):
                self.guard.publish(self.pub_digests, o, run=self.run)
            elif isinstance(o, SendGoal):
                self.send_goal(o)
            elif isinstance(o, AskFeedback):
                self.where_am_i(float(o.at))
            elif isinstance(o, WakeAt):
                self.arm(o.time)

    def where_am_i(self, at: float) -> None:
        """Where its base is at ``at``: known here if it stands where its last goal ended; else
        asked of the world — once the goal sent last is in the world's hands, because the service
        and the action are separate DDS paths and an answer from before that goal would make the
        robot decide on a state it has left (and send the same goal twice)."""
        if self.idle is not None:
            t, cell, gid, sensed = self.idle
            fb = Feedback(self.me, max(at, t), cell, gid, -1, -1, sensed)
            self.out(self.rt.on_feedback(fb, self.now()))
        elif self.accepted < self.last_goal:
            self.ask_at = at  # asked when the goal's acceptance comes back (on_accepted)
        else:
            fut = self.where.call_async(Where.Request(at=at))
            fut.add_done_callback(functools.partial(self.on_where, at))

    def publish(self, payload: Envelope | Mark | Need) -> None:
        if isinstance(payload, Envelope):
            kind = type(payload.message)
            sample = Sample(payload.message, payload.stamp, payload.seq, self.run)
            self.guard.publish(self.kind_pubs[kind], sample)
            self.said["messages"] += 1
        elif isinstance(payload, Mark):
            self.guard.publish(self.pub_marks, payload, run=self.run)
            self.said["marks"] += 1
        else:
            self.guard.publish(self.pub_needs, payload, run=self.run)
            self.said["needs"] += 1

    def send_goal(self, o: SendGoal) -> None:
        self.last_goal = o.id
        if self.idle is not None and isinstance(o.goal, Stand):
            self.idle = (self.idle[0], self.idle[1], o.id, self.idle[3])  # still there
        else:
            self.idle = None
        g = FollowCells.Goal()
        g.id, g.at, g.state = int(o.id), float(o.at), o.goal.state
        if isinstance(o.goal, Follow):
            g.kind = FollowCells.Goal.FOLLOW
            g.path = [wire.to_ros_cell(c) for c in o.goal.path]
            self.follow_end[o.id] = (len(o.goal.path), o.goal.path[-1])
        elif isinstance(o.goal, Carry):
            g.kind, g.object, g.group = FollowCells.Goal.CARRY, o.goal.object, list(o.goal.group)
            self.goal_kind[o.id] = (o.goal.object, o.goal.group)
        else:
            assert isinstance(o.goal, Stand)
            g.kind = FollowCells.Goal.STAND
        sent = self.base.send_goal_async(g, feedback_callback=functools.partial(self.on_feedback, o.id))
        sent.add_done_callback(functools.partial(self.on_accepted, o.id))

    def on_accepted(self, gid: int, fut) -> None:
        handle = fut.result()
        self.accepted = max(self.accepted, gid)
        if self.ask_at is not None and self.accepted >= self.last_goal:
            at, self.ask_at = self.ask_at, None
            self.where_am_i(at)
        if not handle.accepted:
            self.on_goal_result(gid, None)
            return
        handle.get_result_async().add_done_callback(lambda f: self.on_goal_result(gid, f.result().result))

    def on_goal_result(self, gid: int, res) -> None:
        self.goal_kind.pop(gid, None)
        self.follow_end.pop(gid, None)
        self.ended = max(self.ended, gid)
        if not self.started or self.report_sent:
            return
        if res is None:
            r = GoalResult(
                self.me, gid, "refused", self.now(), (0, 0), "REJECTED", "the base rejected the goal"
            )
        else:
            self.late_detections(res.detections)
            outcome, code = res.outcome, res.code
            if outcome == "preempted" and gid == self.last_goal:  # not by itself: another client's goal
                outcome, code = "aborted", "PREEMPTED"
            r = GoalResult(self.me, gid, outcome, res.t, (res.cell.x, res.cell.y), code, res.reason)
            if gid == self.last_goal and res.outcome in ("reached", "aborted"):
                sensed = tuple(wire.from_ros_value(ObjectInfo, o, "result.sensed") for o in res.sensed)
                self.idle = (float(res.t), r.cell, gid, sensed)
        if os.environ.get("OST_RT_DEBUG"):
            self.get_logger().info(f"t={self._now:.1f} result {r}")
        self.out(self.rt.on_result(r, self.now()))
        if self.ask_at is not None and self.ended >= self.last_goal:  # held for this result
            at, self.ask_at = self.ask_at, None
            self.where_am_i(at)

    def late_detections(self, msgs) -> None:
        """The detections a goal result repeats, before the result itself: one still missing from
        the detections topic is taken now (it is news only once, whichever path comes first)."""
        for m in msgs:
            try:
                d = wire.from_ros_value(Detection, m, "result.detections")
            except MessageError as exc:
                self.throttle.warn(rtp.follow_action(self.me), "a goal result", str(exc))
                continue
            self.out(self.rt.on_detection(d, self.now()))

    def on_feedback(self, gid: int, msg) -> None:
        fb = msg.feedback
        if fb.lifted and gid in self.goal_kind and self.started and not self.report_sent:
            obj, group = self.goal_kind[gid]
            self.out(self.rt.on_carry(CarryStarted(obj, group, fb.t), self.now()))

    def on_where(self, at: float, fut) -> None:
        r = fut.result()
        if r is None or not self.started or self.report_sent:
            return
        if self.idle is not None:
            # the last goal's result came in the meantime (another DDS path): it says where the
            # robot stands; this answer may be from before it (mid-carry, an object since delivered)
            self.where_am_i(at)
            return
        end = self.follow_end.get(int(r.goal)) if r.goal == self.last_goal else None
        if end is not None and (r.index >= end[0] - 1 or (r.index < 0 and (r.cell.x, r.cell.y) == end[1])):
            # at (or bound for) its path's last cell: the goal's result decides, not this answer
            # — the result repeats the goal's detections, and a sweep must not end before them
            self.ask_at = at
            return
        if r.goal < self.last_goal and self.ended < self.last_goal:
            # the world had not begun the goal sent last (accepted, not yet executed): again
            self.where_am_i(at)
            return
        sensed = tuple(wire.from_ros_value(ObjectInfo, o, "where.sensed") for o in r.sensed)
        fb = Feedback(self.me, r.time, (r.cell.x, r.cell.y), r.goal, r.index, r.carrying, sensed)
        self.out(self.rt.on_feedback(fb, self.now()))

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
            len(self.rt.sent),
            k.view,
            run=self.run,
            dropped=tuple(self.guard.counts().values()),
            lag=float(self.rt.max_lag),
        )
        self.guard.publish(self.pub_report, report)
        said = ", ".join(f"{n} {what}" for what, n in self.said.items())
        self.get_logger().info(
            f"report sent: published {said}; took {len(self.rt.processed)} batches; "
            f"largest lag {self.rt.max_lag:.1f} steps"
        )

    def on_result(self, _msg: String) -> None:
        if self.report_sent:
            self.done = True
