"""``world_node`` of a realtime run (``realtime:=true``; docs/realtime.md): the robots' bases in sim
time, with no barrier. It serves :class:`~ost_ros.realtime.world.RealtimeWorld` to the agents:

- the robots' goals on ``<ns>/base_goals`` (``ost_msgs/BaseGoal``: follow a path, stand, carry an
  object with its group; a new goal preempts the running one) — one way, what a robot drives its
  base with;
- per robot ``<ns>/agent_<i>/follow_cells`` (``ost_msgs/action/FollowCells``, the same goals;
  feedback when a carry is lifted; results), served by the node ``<ns>/bases`` — for ``ros2
  action send_goal``, an operator or any action client;
- per robot ``<ns>/agent_<i>/base`` (``ost_msgs/BaseEvent``): everything the base does, numbered
  and in order — a goal took over (from which cell and time, when its first move leaves, how long
  a move takes), a stall, a lift, a detection (objects coming into its sensor), a goal's end. The
  robot keeps its own picture of its base from these (:mod:`ost_ros.realtime.base`): it never
  asks where it is;
- ``<ns>/base_clock`` (``ost_msgs/BaseClock``): sim time, ``rtf`` steps per wall second,
  ``clock_hz`` times a second but no more than 4 times a sim step (and right after events), with
  how many base events each robot's
  base has sent so far — a robot holding all of them has every base event up to that time;
  ``<ns>/clock`` (``rosgraph_msgs/Clock``) for tools and ``use_sim_time``, 10 times a second;
- ``<ns>/agent_<i>/pose`` (``geometry_msgs/PoseStamped``, frame ``map``, 1 cell = 1 m) when the
  robot has moved, at most 10 times a second;
- who is in the team: the membership role (``world_node.membership``: every batch waits for its
  watermark, a robot silent past its lease is declared out with a stamped notice on ``lost`` and
  its base stopped, a robot out that runs again asks back and is readmitted by the team) runs in
  a ``membership_node`` of its own by default (``membership:=node``, what ``ost up --realtime``
  starts), and this node only stops a base when asked (``stop_bases`` → ``stopped_bases``, the
  notice's facts); with ``membership:=world`` the role runs in this process. A stopped base
  takes goals again from its robot's next life (``BaseGoal.life``);
- the end: once every object is delivered and every robot finished, ``run_end`` asks for the
  agents' reports; their digests (``<ns>/digests``, as they came) are compared and the result —
  ``ost sim``'s JSON plus ``mode``, ``rtf``, ``disagreements`` and each agent's largest lag — goes
  to ``<ns>/result`` and ``result_file``.

Everything a robot reads from the world (base events, the bases' clock, notices, run_end) is
sealed like a robot's messages (docs/ros.md); the action and the display topics are not.

The world node runs on rclpy's EventsExecutor: a goal, a sample or its tick wakes it (the tick
at ``clock_hz``, at most 500 / team size; the bases' clock on a tick at most 4 times a sim step,
and 2 Hz while nothing happens). The actions are on the
node ``<ns>/bases``, spun by rclpy's SingleThreadedExecutor in a thread of its own with a timer
for the world's next event (:class:`BasesNode`); the two share the world under one lock.
"""

from __future__ import annotations

import functools
import json
import math
import os
import threading
import time
from typing import Any

import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from ost_msgs.action import FollowCells
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock

from ost_msgs_py import auth, wire
from ost_ros.bounds import lower_bound
from ost_ros.lockstep.messages import AgentReport, RunEnd
from ost_ros.lockstep.world import result_from_reports
from ost_ros.node import realtime as rtp
from ost_ros.node import transport as tp
from ost_ros.node.params import ParameterError, declare_role, node_scenario, without_services
from ost_ros.node.plumbing import Readiness, Result, SignalFiles, new_readers
from ost_ros.node.run import process_age
from ost_ros.node.signing import node_auth
from ost_ros.realtime.base import pack
from ost_ros.realtime.messages import BaseClock, BaseEvent, BaseGoal, BaseStopped, Digest, StopBase
from ost_ros.realtime.world import (
    ABORTED,
    REACHED,
    Carry,
    CarryStarted,
    Detection,
    Follow,
    GoalResult,
    RealtimeWorld,
    Stand,
)
from ost_ros.runconfig import WORLD, ConfigError, RunConfig
from ost_ros.scenario import ScenarioError
from world_node.membership import Membership

POSE_HZ = 10.0  # poses of robots that moved, and the rosgraph clock (wall)
IDLE_HZ = 2.0  # the bases' clock and the rosgraph clock while nothing happens (wall)
CLOCK_DELIVERIES = 500.0  # the bases' clock: robots x ticks per second, at most
# ... and no more than this many a sim step while active (events bring one at once): a robot
# decides at whole steps once the batches before are committed, and a commit needs only a clock
# past the batch — four a step are ahead of every decision. A slow run (rtf 1, or a team that
# stands still at rtf 0.01) is then not sent 10-50 clocks a step for nothing.
CLOCKS_PER_STEP = 4.0
START_S = 0.05  # how often it looks whether the team is ready, before the run
DEBUG = bool(os.environ.get("OST_RT_DEBUG"))
RESULT_KEPT_S = 10  # an ended goal's result, kept for its client (s)


class BasesNode(Node):
    """``<ns>/bases``: the robots' bases as actions, one ``FollowCells`` server per robot, and the
    timer of the world's next event — spun by rclpy's SingleThreadedExecutor in a thread of its
    own. rclpy's EventsExecutor (the world's) resumes a goal's waiting coroutine again and again
    (one waiting goal cost 0.4 of a core) and, serving actions, now and then left a goal request
    untaken; rclpy's own executor serves actions as designed and sleeps while nothing comes. The
    world's state is shared under ``world.lock``: a goal is handed to the world here, in this
    thread (``world.execute``), and its result comes back when the world ends it."""

    def __init__(self, world: RealtimeWorldNode):
        # (no parameter services: it has no parameters — the world's node holds them — and they
        # were 14 endpoints every participant of the run discovers)
        super().__init__("bases", namespace=tp.NAMESPACE, **without_services())
        self.world = world
        self.servers = {
            i: ActionServer(
                self,
                FollowCells,
                rtp.follow_action(i),
                execute_callback=functools.partial(self.execute, i),
                goal_callback=lambda _goal: GoalResponse.ACCEPT,
                cancel_callback=lambda _goal: CancelResponse.REJECT,  # a new goal preempts
                # an ended goal is kept this long for a client to ask its result (ros2 action
                # send_goal asks at once; a robot reads its base's events instead): the status
                # array lists every goal kept, and at the 900 s default it grew with the run
                result_timeout=RESULT_KEPT_S,
            )
            for i in world.ids
        }
        # The world's next event: a timer set for it (in this thread), re-set from the other one
        # through the guard condition (a wait in progress is not woken by a timer's reset).
        self.event_timer = self.create_timer(1.0, self.on_event, autostart=False)
        self.wake = self.create_guard_condition(self.arm)
        self.executor_ = SingleThreadedExecutor()
        self.executor_.add_node(self)
        self.thread = threading.Thread(target=self.spin, name="bases", daemon=True)
        self.running = True

    def spin(self) -> None:
        while self.running and rclpy.ok():
            try:
                self.executor_.spin_once(timeout_sec=0.5)
            except Exception:  # the context shut down under it (the process is ending)
                if rclpy.ok():
                    raise
                return

    def stop(self) -> None:
        self.running = False
        self.wake.trigger()
        self.thread.join(timeout=2.0)

    async def execute(self, agent: int, handle: Any) -> Any:
        """One goal of robot ``agent``: to the world; its result when the world ends it."""
        fut: Future = Future()
        with self.world.lock:
            self.world.execute(agent, handle, fut)
        self.arm()
        res = await fut
        if res.outcome == REACHED:
            handle.succeed()
        else:
            handle.abort()
        return res

    def arm(self) -> None:
        """The event timer, set for the world's next event (if it comes before the next tick)."""
        with self.world.lock:
            delay = self.world.next_event_in()
        if delay is None:
            self.event_timer.cancel()
        else:
            self.event_timer.timer_period_ns = max(int(delay * 1e9), 100_000)
            self.event_timer.reset()

    def on_event(self) -> None:
        self.event_timer.cancel()
        with self.world.lock:
            self.world.advance(self.world.sim_now())
        self.arm()


class RealtimeWorldNode(Node):
    """``<ns>/world`` of a realtime run (see the module docstring)."""

    def __init__(self):
        super().__init__(tp.WORLD_NODE, namespace=tp.NAMESPACE)
        p = declare_role(self, WORLD)
        scenario = node_scenario(p)
        try:
            stalls = RunConfig.of(p).stalls()
            self.world = RealtimeWorld(
                scenario, p["speed_jitter"], p["noise_seed"], tuple(stalls), tracking=True, wait_for_out=False
            )
        except ScenarioError as exc:
            raise ParameterError(f"scenario: {exc}") from None
        except (ConfigError, ValueError) as exc:
            raise ParameterError(f"stalls: {exc}") from None
        self.scenario, self.p = scenario, p
        self.ids = tuple(a.id for a in scenario.agents)
        self.joining = rtp.joining(p["joins"])  # robots not in the team at the start (--join)
        # what each robot that joins later was told by its base (said again when it is up), for
        # the whole run: the robot takes its base's events by their numbers, from 1, and holds
        # every later one while one is missing — so they stay whole (robots that join are few,
        # and a base says a few events a goal)
        self.said_to: dict[int, list[Any]] = {i: [] for i in self.joining}
        self.base_readers: dict[int, int] = {}
        self.looked = 0.0
        self.declared = self.rejoins = 0
        self.membership_log: list[tuple[str, int, float]] = []  # (out/back, agent, sim time)
        self.fingerprint = tp.scenario_fingerprint(scenario)
        self.guard = node_auth(p["keys"], p["insecure"], auth.WORLD)
        # The run id comes with the keys (every process knows it); an insecure run has none.
        self.run = self.guard.run or ""
        self.rtf = float(p["rtf"])
        # The tick: clock_hz, or fewer as the team grows — every robot takes every tick of the
        # bases' clock (a team of 50 at 50 Hz spent more than a core of two taking them)
        self.tick_hz = min(float(p["clock_hz"]), CLOCK_DELIVERIES / len(self.ids))
        self.throttle = tp.Throttle(self.get_logger())
        self.files = SignalFiles(p, self.throttle)
        self.started = self.done = False
        self.t0 = 0.0  # monotonic time of sim time 0
        self.reports: dict[int, AgentReport] = {}
        self.ended: float | None = None  # sim time the world was done at
        self.ended_wall = 0.0
        self.completed = False
        self.bring_up_s: float | None = None
        self.created = time.monotonic()
        self.last_clock = -1.0
        self.live = set(self.ids)  # robots not out (a robot back is in again)
        # Every coordination's digests, for the whole run (one per robot and coordination): the
        # result compares them at the end — a survivor that took a batch with no coordination in
        # it sends none, so no batch is known complete before — and says when each came.
        self.digests: dict[int, dict[int, tuple[str, str]]] = {}  # stamp -> agent -> digest
        self.digest_at: dict[int, float] = {}  # stamp -> when its last digest came (epoch s)
        self.events = dict.fromkeys(self.ids, 0)  # base events sent to each robot
        self.sent_events = False  # since the last base clock
        self.advanced = 0.0  # the sim time the world's events are out up to (the bases' clock)
        self.active = False  # something happened since the last tick (events, goals, messages)
        self.always_active = p["membership"] != "world"  # (it hears no robot talk: full rate)
        self.last_base_clock = 0.0
        self.last_base_clock_t = 0.0  # the sim time it said
        self.clock_owed = False  # something happened since the last base clock
        self.posed: dict[int, tuple[int, int]] = {}  # the cell each robot's last pose showed
        self.goals: dict[tuple[int, int], tuple[Any, Future]] = {}  # (agent, goal id) -> (handle, result)
        self.carrying: dict[int, tuple[int, Any]] = {}  # agent -> (object, goal handle) of its carry
        self._build_endpoints(p)
        self.bases.thread.start()
        self.timer = self.create_timer(START_S, self.on_tick)
        self.get_logger().info(
            f"realtime: waiting for {len(self.ids)} agents ({self.fingerprint}); rtf {self.rtf:g}"
        )

    # ------------------------------------------------------------------ endpoints

    def _build_endpoints(self, p: dict[str, Any]) -> None:
        q, g, th, quiet = tp.LOCKSTEP_QOS, self.guard, self.throttle, tp.no_events_pub
        other_run = tp.other_run(self.run)
        self.pub_clock = self.create_publisher(Clock, tp.CLOCK, tp.LATEST_QOS)
        # The bases' clock: the newest is all that counts (its counts are totals), so keep-last 1
        # — kept-all, each tick waited in the writer for 50 readers' acknowledgements (a 50-robot
        # world spent half a core publishing it)
        self.pub_base_clock = self.create_publisher(
            wire.ros_type(BaseClock), rtp.BASE_CLOCK, tp.LATEST_QOS, event_callbacks=quiet()
        )
        self.result = Result(self, p)
        self.pub_end = self.create_publisher(wire.ros_type(RunEnd), tp.RUN_END, tp.LATCHED_ALL_QOS)
        self.ready = Readiness(self, self.ids, self.fingerprint, g, th, later=self.joining)
        self.sub_report = tp.subscribe(
            self, AgentReport, tp.REPORTS, self.on_report, tp.LATCHED_ALL_QOS, g, th
        )
        self.sub_digests = tp.subscribe(self, Digest, rtp.DIGESTS, self.on_digest, q, g, th, skip=other_run)
        self.sub_goals = tp.subscribe(self, BaseGoal, rtp.BASE_GOALS, self.on_goal, q, g, th, skip=other_run)
        self.pub_base, self.pub_pose = {}, {}
        self.lock = threading.RLock()  # the world's state: this thread and the bases' share it
        self.bases = BasesNode(self)
        for i in self.ids:
            self.pub_base[i] = self.create_publisher(
                wire.ros_type(BaseEvent), rtp.base_topic(i), q, event_callbacks=quiet()
            )
            self.pub_pose[i] = self.create_publisher(PoseStamped, rtp.pose_topic(i), tp.LATEST_QOS)
        # Who is in the team (world_node.membership): the role in this process, or a
        # membership_node's (membership:=node), which asks this node to stop a robot's base.
        self.failure_timeout = p["failure_timeout"]
        self.membership: Membership | None = None
        if p["membership"] == "world":
            self.membership = Membership(
                self,
                self.ids,
                p,
                self.stop_base,
                self.sim_now,
                self.on_out,
                self.heard_talk,
                self.joining,
                self.lock,
            )
        else:
            self.pub_stopped = self.create_publisher(wire.ros_type(BaseStopped), rtp.STOPPED_BASES, q)
            self.sub_stop = tp.subscribe(
                self, StopBase, rtp.STOP_BASES, self.on_stop_base, q, g, th, skip=other_run
            )

    # ------------------------------------------------------------------ time

    def sim_now(self) -> float:
        return (time.monotonic() - self.t0) * self.rtf if self.started else 0.0

    def stamp(self, t: float) -> Time:
        return Time(sec=int(t), nanosec=int((t - int(t)) * 1e9))

    # ------------------------------------------------------------------ start

    def lacking(self) -> list[str]:
        """What the start waits for: every robot ready, its writers matched here and the world's
        writers matched there (a sample written before its reader matched is never delivered)."""
        n = len(self.ids)
        out = [] if self.ready.complete else [f"ready from agents {self.ready.missing()[:8]}"]
        if self.membership is not None:
            out += self.membership.lacking()
        elif self.sub_stop.get_publisher_count() < 1 or self.pub_stopped.get_subscription_count() < 1:
            out.append("the membership node")
        bases = [
            i for i in self.ids if i not in self.joining and self.pub_base[i].get_subscription_count() < 1
        ]
        if bases or self.pub_base_clock.get_subscription_count() < n - len(self.joining):
            out.append(f"base readers of {bases[:8]}")
        return out

    def try_start(self) -> None:
        lacking = self.lacking()
        if lacking:
            if time.monotonic() - self.created > tp.DISCOVERY_NOTE_S:
                self.throttle.note(("start", "world"), f"not starting yet: {'; '.join(lacking)}")
            return
        self.started = True
        self.t0 = time.monotonic()
        self.bring_up_s = process_age()
        self.get_logger().info(f"all {len(self.ids)} agents ready; sim time 0 (rtf {self.rtf:g})")
        for i in self.ids:  # what each robot senses where it stands at the start
            sensed = self.world.feedback(i, 0.0).sensed
            if sensed:
                self.emit(i, Detection(i, 0.0, self.world.bots[i].cell, sensed, sensed))
        self.timer.cancel()
        self.timer = self.create_timer(1.0 / self.tick_hz, self.on_tick)
        self.publish_base_clock(0.0)  # the robots start on it
        self.publish_clock(0.0)
        self.files.ready(self.bring_up_s)

    # ------------------------------------------------------------------ the base

    def on_goal(self, g: BaseGoal) -> None:
        """A robot's goal for its own base (``base_goals``)."""
        goal: Follow | Stand | Carry
        if g.kind == "follow":
            goal = Follow(g.path, g.state)
        elif g.kind == "carry":
            goal = Carry(g.object, g.group, g.state)
        elif g.kind in ("stand", "let_go"):
            goal = Stand(g.state, unless_carrying=g.kind == "let_go")
        else:
            self.throttle.warn(
                self.sub_goals.topic_name,
                f"agent {g.agent}",
                f"kind {g.kind!r}: not follow, stand, let_go or carry",
            )
            return
        with self.lock:
            self.active = True
            self.apply(g.agent, g.id, goal, g.at, g.life)
        self.bases.wake.trigger()  # (the event timer, for the goal's events)

    def execute(self, agent: int, handle: Any, fut: Future) -> None:
        """(The bases' thread, under the lock) an action client's goal for robot ``agent``'s base
        (an operator's, ``ros2 action send_goal``): ``fut`` gets its result when it ends."""
        req = handle.request
        goal: Follow | Stand | Carry
        if req.kind == FollowCells.Goal.FOLLOW:
            goal = Follow(tuple((c.x, c.y) for c in req.path), req.state)
        elif req.kind == FollowCells.Goal.CARRY:
            goal = Carry(int(req.object), tuple(int(j) for j in req.group), req.state)
            self.carrying[agent] = (int(req.object), handle)
        else:
            goal = Stand(req.state)
        self.goals[(agent, req.id)] = (handle, fut)
        self.apply(agent, int(req.id), goal, float(req.at), decided=False)

    def apply(
        self,
        agent: int,
        gid: int,
        goal: Follow | Stand | Carry,
        at: float,
        life: int = 0,
        decided: bool = True,
    ) -> None:
        """(Under the lock) goal ``gid`` for ``agent``'s base, handed to the world now (``life``:
        its robot's; a base stopped when its robot was declared out takes a later life back).
        ``decided``: its robot's, which may take over at its decision's time
        (:meth:`RealtimeWorld.takeover`); an operator's takes over from now at the earliest."""
        b = self.world.bots.get(agent)
        if b is not None and b.out and life > b.life and self.started and self.ended is None:
            self.live.add(agent)  # readmitted by the team: its base is its again
            self.rejoins += 1
            self.membership_log.append(("back", agent, round(self.sim_now(), 3)))
            self.get_logger().info(f"agent {agent} back (life {life}) at sim time {self.sim_now():.1f}")
        if DEBUG:
            self.get_logger().info(
                f"goal {gid} of agent {agent} ({type(goal).__name__}) at {self.sim_now():.1f}"
            )
        if agent not in self.live or not self.started or self.ended is not None:
            why = "the robot has failed" if self.started else "the run has not started"
            self.dispatch(GoalResult(agent, gid, "refused", self.sim_now(), (0, 0), "FAILED", why))
        else:
            # Everything due before the goal first: a goal that came while an event was still
            # unprocessed (a carry's delivery between two ticks) would otherwise preempt it — the
            # load dropped short of its destination, and the robots, told it was delivered, went
            # home (rtf 1000: 6 runs of 6 ended so once the event timer ran late).
            now = self.sim_now()
            self.advance(now)
            when = self.world.takeover(agent, goal, at, now) if decided else max(at, now)
            for ev in self.world.goal(agent, gid, goal, when, life):
                self.dispatch(ev)
            self.after_events()

    def finish_goal(self, r: GoalResult, sensed: tuple = ()) -> None:
        entry = self.goals.pop((r.agent, r.goal), None)
        if entry is None:
            return
        handle, fut = entry
        if self.carrying.get(r.agent, (None, None))[1] is handle:
            del self.carrying[r.agent]
        res = FollowCells.Result()
        res.outcome, res.code, res.reason, res.t = r.outcome, r.code, r.reason, float(r.time)
        res.cell.x, res.cell.y = r.cell
        res.sensed = [wire.to_ros(o) for o in sensed]
        fut.set_result(res)
        self.bases.wake.trigger()  # (from this thread or the bases': its coroutine resumes)

    def emit(self, agent: int, ev: Any, sensed: tuple = ()) -> None:
        """Robot ``agent``'s base event ``ev``, numbered, on its base topic (to it alone; to a
        robot out too: it keeps its picture of its stopped base, and asks back from there)."""
        self.events[agent] += 1
        msg = pack(agent, self.events[agent], ev, sensed)
        self.active = True
        self.guard.publish(self.pub_base[agent], msg, run=self.run, receivers=(agent,))
        self.sent_events = True
        if agent in self.said_to:
            self.said_to[agent].append(msg)

    def joiners_back(self) -> None:
        """(Under the lock) A robot that joins mid-run has a new reader of its base topic, and
        what its base said before that never reached it (its sensing where it stands, its
        base stopped at the start): said again, sealed anew, once a reader is matched (the
        robot takes each event once, by its number)."""
        for i, said in self.said_to.items():
            back, self.base_readers[i] = new_readers([self.pub_base[i]], self.base_readers.get(i, 0))
            if back:
                for msg in said:
                    self.guard.publish(self.pub_base[i], msg, run=self.run, receivers=(i,))

    def dispatch(self, ev: Any) -> None:
        if DEBUG:
            self.get_logger().info(f"event {ev}")
        if isinstance(ev, GoalResult):
            sensed: tuple = ()
            if ev.outcome in (REACHED, ABORTED) and ev.agent in self.live:  # it stands there, idle
                sensed = self.world.feedback(ev.agent, float(ev.time)).sensed
            self.emit(ev.agent, ev, sensed)
            self.finish_goal(ev, sensed)
        elif isinstance(ev, CarryStarted):
            for j in ev.group:
                self.emit(j, ev)
                obj, handle = self.carrying.get(j, (None, None))
                if obj == ev.object and handle is not None:  # for action clients: the lift
                    fb = FollowCells.Feedback()
                    fb.t, fb.lifted, fb.index = float(ev.time), True, -1
                    fb.cell.x, fb.cell.y = self.world.objects[ev.object].at
                    handle.publish_feedback(fb)
        else:  # Detection, GoalStarted, Stalled
            self.emit(ev.agent, ev)

    # ------------------------------------------------------------------ the clock

    def on_tick(self) -> None:
        if not self.started:
            with self.lock:
                self.try_start()
            return
        wall = time.monotonic()
        with self.lock:
            now = self.sim_now()  # (under the lock: the bases' thread may have advanced meanwhile)
            if self.ended is None:
                self.advance(now)
                if self.membership is not None:
                    self.membership.check_suspects(wall)
                if self.said_to and wall - self.looked >= 1.0:
                    self.looked = wall
                    self.joiners_back()
                if self.world.done:
                    self.end_run(now)
            # A team that says nothing and whose bases do nothing needs the clock only now and
            # then (its robots extrapolate it); any activity brings it back to every tick that
            # moves sim time on by a quarter step or more.
            self.clock_owed = self.clock_owed or self.active  # (kept until a clock goes out)
            moved = self.advanced - self.last_base_clock_t >= 1.0 / CLOCKS_PER_STEP
            if (self.clock_owed and moved) or wall - self.last_base_clock >= 1.0 / IDLE_HZ:
                self.publish_base_clock(self.advanced)
            soon = self.next_event_in() is not None
        if soon:  # the event timer, for an event due before the next tick (waking the bases'
            self.bases.wake.trigger()  # thread costs a wait set of every robot's action)
        if wall - self.last_clock >= 1.0 / (POSE_HZ if self.active else IDLE_HZ):
            self.last_clock = wall
            with self.lock:
                self.publish_clock(now)
        self.active = self.always_active
        if self.result.at is not None:
            # the agents have read the result (or not, after linger): leave
            if self.result.leave(wall, lambda: self.sub_goals.get_publisher_count() == 0):
                self.done = True
        elif self.ended is not None and wall - self.ended_wall > 10.0:
            missing = [i for i in self.live if i not in self.reports]
            self.get_logger().warning(f"no report from agents {missing} after 10 s: the result without them")
            self.finish()

    def advance(self, now: float) -> None:
        """(Under the lock) the world's events due by ``now``, out."""
        if self.ended is None:
            for ev in self.world.advance(now):
                self.dispatch(ev)
            self.advanced = max(self.advanced, now)
        self.after_events()

    def after_events(self) -> None:
        """Events out: the bases' clock at once (a robot commits as soon as it knows it has them
        all) — at the time the world has been advanced to, never later: an event due since is
        not out yet, and a robot must not commit past it."""
        if self.sent_events:
            self.publish_base_clock(self.advanced)

    def next_event_in(self) -> float | None:
        """(Under the lock) wall seconds to the world's next event, if it comes before the next
        tick (which handles it otherwise); None: nothing to time."""
        t = self.world.next_time() if self.started and self.ended is None else None
        if t is None:
            return None
        delay = (t - self.sim_now()) / self.rtf
        return None if delay >= 1.0 / self.tick_hz else max(delay, 0.0)

    def publish_base_clock(self, now: float) -> None:
        self.sent_events = self.clock_owed = False
        self.last_base_clock, self.last_base_clock_t = time.monotonic(), now
        clock = BaseClock(now, tuple(self.events[i] for i in self.ids))
        self.guard.publish(self.pub_base_clock, clock, run=self.run)

    def publish_clock(self, now: float) -> None:
        self.pub_clock.publish(Clock(clock=self.stamp(now)))
        self.publish_poses(now)
        self.write_progress(now)

    def write_progress(self, now: float, last: bool = False) -> None:
        """'step delivered objects' for ost up's progress line."""
        self.files.progress(math.floor(now), self.world.objects.values(), last)

    def publish_poses(self, now: float) -> None:
        """The pose of every robot that moved since its last one (standing robots cost nothing)."""
        stamp = None
        for i in self.live:
            cell = self.world.position(i, now)
            if self.posed.get(i) == cell:
                continue
            self.posed[i] = cell
            stamp = stamp or self.stamp(now)
            msg = PoseStamped()
            msg.header.stamp, msg.header.frame_id = stamp, "map"
            msg.pose.position.x, msg.pose.position.y = float(cell[0]), float(cell[1])
            msg.pose.orientation.w = 1.0
            self.pub_pose[i].publish(msg)

    # ------------------------------------------------------------------ what robots say

    def on_digest(self, d: Digest) -> None:
        self.digests.setdefault(d.stamp, {})[d.sender] = (d.input, d.output)
        self.digest_at[d.stamp] = time.time()  # the last robot's, so far (ost up --split's heal)

    # ------------------------------------------------------------------ membership

    def stop_base(self, agent: int, now: float, until: float, life: int) -> BaseStopped:
        """(Under the lock) robot ``agent`` is declared out (its life ``life`` ends): its base
        stopped — a lift it was part of called off, a carry's load dropped — and what its notice
        says of it: where it was at ``until``, its load, its deliveries."""
        running = self.world.bots[agent].goal
        self.world.kill(agent, now, out=True)  # its partners' goals end at the next advance
        if running:  # its own goal ends where the base stopped (its picture of its base says so)
            cell = self.world.bots[agent].cell
            self.emit(agent, GoalResult(agent, running, ABORTED, now, cell, "FAILED", "declared out"))
        facts = self.world.notice(agent, 1 << 62, 0, sensed_until=until)
        return BaseStopped(agent, life, now, facts.at, facts.dropped, facts.delivered)

    def heard_talk(self) -> None:
        self.active = True

    def on_out(self, agent: int, now: float) -> None:
        self.live.discard(agent)
        self.declared += 1
        self.membership_log.append(("out", agent, round(now, 3)))
        self.get_logger().warning(f"agent {agent} out at sim time {now:.1f}; {len(self.live)} in the team")
        if not self.live:
            self.end_run(now)

    def on_stop_base(self, m: StopBase) -> None:
        """(membership:=node) the membership node declared a robot out: stop its base, answer."""
        if m.agent not in self.ids:
            self.throttle.warn(self.sub_stop.topic_name, f"agent {m.agent}", "not in the scenario's team")
            return
        with self.lock:
            now = self.sim_now()
            self.advance(now)
            facts = self.stop_base(m.agent, now, m.until, m.life)
            self.guard.publish(self.pub_stopped, facts, run=self.run, receivers=(auth.MEMBERSHIP,))
            self.on_out(m.agent, now)
            self.after_events()

    # ------------------------------------------------------------------ end

    def end_run(self, now: float) -> None:
        """The world is done (or every robot failed): ask the survivors for their reports."""
        ends = [b.finished for b in self.world.bots.values() if b.finished is not None]
        ends += [o.delivered for o in self.world.objects.values() if o.delivered is not None]
        self.world.end = max(ends, default=now)
        self.ended, self.ended_wall = self.world.end, time.monotonic()
        for agent, t in self.world.outs.items():  # out when the run ended: failed, in the record
            self.world.failed.setdefault(agent, t)
        self.completed = self.world.done and not self.world.undeliverable()
        self.guard.publish(self.pub_end, RunEnd(self.world.t, self.world.t, self.completed, run=self.run))
        if self.membership is not None:
            self.membership.end()
        self.write_progress(self.world.end, last=True)
        self.get_logger().info(f"run over at sim time {self.world.end:g}; collecting reports")
        if not self.live:
            self.finish()

    def on_report(self, r: AgentReport) -> None:
        if r.run != self.run or r.agent not in self.ids:
            return
        self.reports[r.agent] = r
        if self.ended is not None and self.result.at is None and all(i in self.reports for i in self.live):
            with self.lock:
                self.finish()

    def disagreements(self) -> tuple[int, int]:
        """(batches whose digests differ between two robots, batches compared). A survivor that
        took a batch without a coordination in it publishes no digest: it disagrees if others did
        and the final schedules differ."""
        views = {r.view for i, r in self.reports.items() if i in self.live}
        bad = 0
        for _stamp, by_agent in sorted(self.digests.items()):
            seen = set(by_agent.values())
            if len(seen) > 1 or (len(views) > 1 and not self.live <= set(by_agent)):
                bad += 1
        return bad, len(self.digests)

    def finish(self) -> None:
        reports = [self.reports[i] for i in sorted(self.live) if i in self.reports]
        protocol = reports[0].protocol if reports else self.p["protocol"]
        messages = sum(r.messages for r in self.reports.values())
        result = result_from_reports(self.world, reports, messages, protocol)
        result.lower_bound = lower_bound(self.scenario).value
        bad, compared = self.disagreements()
        wall = time.monotonic() - self.t0
        data = result.to_dict() | {
            "mode": "realtime",
            "rtf": self.rtf,
            "speed_jitter": self.p["speed_jitter"],
            "stalls": [list(s) for s in RunConfig.of(self.p).stalls()],
            "disagreements": bad,
            "coordinations_compared": compared,
            "membership": {
                "monitor": self.p["membership"],
                "fanout": self.p["fanout"],
                "failure_timeout_s": self.failure_timeout,
                "declared": self.declared,
                "rejoins": self.rejoins,
                "out_at_end": sorted(self.world.outs),
                "events": [list(e) for e in self.membership_log],
            },
            "lag": {str(r.agent): r.lag for r in sorted(self.reports.values(), key=lambda r: r.agent)},
            "digests_at": {str(s): round(t, 3) for s, t in sorted(self.digest_at.items())},
            "wall_s": round(wall, 3),
            "bring_up_s": None if self.bring_up_s is None else round(self.bring_up_s, 2),
        }
        self.result.publish(json.dumps(data, indent=1))
        self.get_logger().info(
            f"result: makespan {result.makespan}, completed {result.completed}, disagreements {bad} "
            f"of {compared}; wall {wall:.1f} s"
        )

    @property
    def exit_code(self) -> int:
        return 0 if self.completed else 1

    def destroy_node(self) -> None:
        """The bases' thread and node first, then this one."""
        self.bases.stop()
        self.bases.destroy_node()
        super().destroy_node()
