"""``world_node`` of a realtime run (``realtime:=true``; docs/realtime.md): the robots' bases in sim
time, with no barrier. It serves :class:`~ost_ros.realtime.world.RealtimeWorld` to the agents:

- ``<ns>/clock`` (``rosgraph_msgs/Clock``): sim time, ``rtf`` steps per wall second, ``clock_hz``
  times a second;
- per robot ``<ns>/agent_<i>/follow_cells`` (``ost_msgs/action/FollowCells``: follow a path,
  stand, carry an object with its group; a new goal preempts the running one; feedback when a
  carry is lifted), ``<ns>/agent_<i>/where`` (``ost_msgs/srv/Where``: where the base will be at
  its next cell boundary), ``<ns>/agent_<i>/detections`` (``ost_msgs/Detection``: objects coming
  into its sensor) and ``<ns>/agent_<i>/pose`` (``geometry_msgs/PoseStamped``, frame ``map``,
  1 cell = 1 m, 10 times a second);
- failures: an agent whose liveliness is lost (as in lockstep) is killed in the world and declared
  with a stamped notice on ``<ns>/lost`` above its last watermark the world heard; the world keeps
  every robot's signed messages and publishes the dead robot's again, so a survivor that lacks one
  of its counted messages gets it;
- the end: once every object is delivered and every robot finished, ``run_end`` asks for the
  agents' reports; their digests (``<ns>/digests``, as they came) are compared and the result —
  ``ost sim``'s JSON plus ``mode``, ``rtf``, ``disagreements`` and each agent's largest lag — goes
  to ``<ns>/result`` and ``result_file``.

The robot-to-base link (the action, the service, the detections) is the robot's own hardware in a
real team: it is not signed; every robot-to-robot message and the world's notices are.
"""

from __future__ import annotations

import functools
import json
import math
import time
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from ost_msgs.action import FollowCells
from ost_msgs.srv import Where
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from ost_msgs_py import auth, wire
from ost_ros.bounds import lower_bound
from ost_ros.lockstep.messages import AgentReport, Ready, RunEnd
from ost_ros.lockstep.world import result_from_reports
from ost_ros.node import realtime as rtp
from ost_ros.node import transport as tp
from ost_ros.node.params import ParameterError, declare_role, node_scenario
from ost_ros.node.run import process_age, write_file
from ost_ros.node.signing import node_auth
from ost_ros.realtime.messages import Digest, Mark
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

PROGRESS_S = 0.25  # the progress file, at most this often (wall)
POSE_HZ = 10.0  # poses and follow feedback, a modest rate (wall)
# The world polls its bases this often (wall): events are due at most this late. Each wake of
# rclpy's single-threaded executor rebuilds the wait set of every robot's action server and
# service, so the period grows with the team: 2 ms up to 10 robots, 0.2 ms a robot beyond (a
# 50-robot world polled at 2 ms spent most of a core waking; docs/realtime.md).
TIMER_S, TIMER_S_PER_AGENT, TIMER_S_MAX = 0.002, 0.0002, 0.02


def poll_period(agents: int) -> float:
    """The world's poll period (s) for a team of ``agents``."""
    return min(TIMER_S_MAX, max(TIMER_S, TIMER_S_PER_AGENT * agents))


START_S = 0.05  # how often it looks whether the team is ready, before the run


class RealtimeWorldNode(Node):
    """``<ns>/world`` of a realtime run (see the module docstring)."""

    def __init__(self):
        super().__init__(tp.WORLD_NODE, namespace=tp.NAMESPACE)
        p = declare_role(self, WORLD)
        scenario = node_scenario(p)
        try:
            stalls = RunConfig.of(p).stalls()
            self.world = RealtimeWorld(scenario, p["speed_jitter"], p["noise_seed"], tuple(stalls))
        except ScenarioError as exc:
            raise ParameterError(f"scenario: {exc}") from None
        except (ConfigError, ValueError) as exc:
            raise ParameterError(f"stalls: {exc}") from None
        self.scenario, self.p = scenario, p
        self.ids = tuple(a.id for a in scenario.agents)
        self.fingerprint = tp.scenario_fingerprint(scenario)
        self.guard = node_auth(p["keys"], p["insecure"], auth.WORLD)
        # The run id comes with the keys (every process knows it); an insecure run has none.
        self.run = self.guard.run or ""
        self.rtf = float(p["rtf"])
        self.throttle = tp.Throttle(self.get_logger())
        self.started = self.done = False
        self.t0 = 0.0  # monotonic time of sim time 0
        self.ready: dict[int, Ready] = {}
        self.reports: dict[int, AgentReport] = {}
        self.ended: float | None = None  # sim time the world was done at
        self.ended_wall = 0.0
        self.result_at: float | None = None
        self.completed = False
        self.bring_up_s: float | None = None
        self.created = time.monotonic()
        self.last_try = 0.0
        self.last_clock = self.last_pose = self.progress_at = -1.0
        self.live = set(self.ids)
        self.suspects: dict[int, float] = {}
        self.alive_seen: set[int] = set()
        # What the world hears of every robot: its watermark and message count (for a failure's
        # stamp), its signed messages (to relay a dead robot's), its coordination digests.
        self.heard: dict[int, tuple[int, int]] = {i: (-1, 0) for i in self.ids}
        self.originals: dict[int, list[tuple[Any, Any]]] = {i: [] for i in self.ids}
        self.digests: dict[int, dict[int, tuple[str, str]]] = {}  # stamp -> agent -> digest
        self.messages = 0
        self.goals: dict[tuple[int, int], tuple[Future, Any, Any]] = {}  # (agent, goal id) -> ...
        self.carrying: dict[int, tuple[int, Any]] = {}  # agent -> (object, goal handle) of its carry
        # agent -> its detections since its last goal result: the next result repeats them (a
        # sample lost on the detections topic is repaired by DDS, late; the robot may have ended
        # its search by then, so its finds must not hang on that repair alone)
        self.detections: dict[int, list[Any]] = {}
        self._build_endpoints(p)
        self.timer = self.create_timer(poll_period(len(self.ids)), self.on_timer)
        self.get_logger().info(
            f"realtime: waiting for {len(self.ids)} agents ({self.fingerprint}); rtf {self.rtf:g}"
        )

    # ------------------------------------------------------------------ endpoints

    def _build_endpoints(self, p: dict[str, Any]) -> None:
        q = tp.LOCKSTEP_QOS
        self.pub_clock = self.create_publisher(Clock, tp.CLOCK, tp.LATEST_QOS)
        self.pub_result = self.create_publisher(String, tp.RESULT, tp.RESULT_QOS)
        self.pub_end = self.create_publisher(wire.ros_type(RunEnd), tp.RUN_END, tp.LATCHED_ALL_QOS)
        self.pub_lost = self.create_publisher(wire.ros_type(rtp.Lost), rtp.LOST, tp.LATCHED_ALL_QOS)
        g, th = self.guard, self.throttle
        self.sub_ready = tp.subscribe(
            self, Ready, tp.READY, self.on_ready, tp.LATCHED_ALL_QOS, g, th, events=True
        )
        self.sub_report = tp.subscribe(
            self, AgentReport, tp.REPORTS, self.on_report, tp.LATCHED_ALL_QOS, g, th, events=True
        )
        # Every robot's messages: what it said (its watermark, its count) and, signed, to relay.
        self.kind_pubs: dict[str, Any] = {}
        self.kind_subs = []
        for kind in rtp.message_kinds(p["protocol"]):
            topic = tp.message_topic(kind)
            self.kind_pubs[self.resolve_topic_name(topic)] = self.create_publisher(
                wire.ros_type(kind), topic, q
            )
            self.kind_subs.append(
                tp.subscribe(
                    self,
                    kind,
                    topic,
                    functools.partial(self.on_sample, self.resolve_topic_name(topic)),
                    q,
                    g,
                    th,
                    keep_bytes=True,
                    events=True,
                    # (a failed robot's: the world's own copies of its messages)
                    skip=lambda m: m.run != self.run or m.sender not in self.live,
                )
            )

        def other_run(m) -> bool:  # (checked before the replay window: tp.Receiver)
            return m.run != self.run

        self.sub_marks = tp.subscribe(
            self, Mark, rtp.MARKS, self.on_mark, q, g, th, skip=other_run, events=True
        )
        self.sub_digests = tp.subscribe(
            self, Digest, rtp.DIGESTS, self.on_digest, q, g, th, skip=other_run, events=True
        )
        self.servers, self.wheres, self.pub_det, self.pub_pose = {}, {}, {}, {}
        for i in self.ids:
            self.servers[i] = ActionServer(
                self,
                FollowCells,
                rtp.follow_action(i),
                execute_callback=functools.partial(self.execute, i),
                goal_callback=lambda _goal: GoalResponse.ACCEPT,
                cancel_callback=lambda _goal: CancelResponse.REJECT,  # a new goal preempts
            )
            self.wheres[i] = self.create_service(
                Where, rtp.where_service(i), functools.partial(self.on_where, i)
            )
            self.pub_det[i] = self.create_publisher(wire.ros_type(Detection), rtp.detections_topic(i), q)
            self.pub_pose[i] = self.create_publisher(PoseStamped, rtp.pose_topic(i), tp.LATEST_QOS)
        # Liveliness: a killed agent process is a failed robot (as in lockstep).
        self.failure_timeout = p["failure_timeout"]
        self.sub_alive = {}
        if self.failure_timeout > 0:
            for i in self.ids:
                events = SubscriptionEventCallbacks(
                    liveliness=functools.partial(self.on_liveliness, i), use_default_callbacks=False
                )
                self.sub_alive[i] = self.create_subscription(
                    String,
                    tp.alive_topic(i),
                    functools.partial(self.on_alive_sample, i),
                    tp.alive_qos(self.failure_timeout),
                    event_callbacks=events,
                )

    # ------------------------------------------------------------------ time

    def sim_now(self) -> float:
        return (time.monotonic() - self.t0) * self.rtf if self.started else 0.0

    def stamp(self, t: float) -> Time:
        return Time(sec=int(t), nanosec=int((t - int(t)) * 1e9))

    # ------------------------------------------------------------------ start

    def on_ready(self, r: Ready) -> None:
        if r.agent not in self.ids:
            self.throttle.warn(self.sub_ready.topic_name, f"agent {r.agent}", "not in the scenario's team")
        elif r.scenario != self.fingerprint:
            self.throttle.warn(
                self.sub_ready.topic_name,
                f"agent {r.agent}",
                f"loaded scenario {r.scenario}, the world runs {self.fingerprint}",
            )
        else:
            self.ready[r.agent] = r

    def try_start(self) -> None:
        n = len(self.ids)
        lacking = [i for i in self.ids if i not in self.ready]
        writers = min((s.get_publisher_count() for s in self.kind_subs), default=n)
        unseen = sorted(set(self.ids) - self.alive_seen) if self.sub_alive else []
        if lacking or writers < n or self.sub_marks.get_publisher_count() < n or unseen:
            if time.monotonic() - self.created > tp.DISCOVERY_NOTE_S:
                self.throttle.note(
                    ("start", "world"),
                    f"not starting yet: no ready from agents {lacking[:8]}, message writers "
                    f"{writers}/{n}, liveliness not seen from {unseen[:8]}",
                )
            return
        self.started = True
        self.t0 = time.monotonic()
        self.bring_up_s = process_age()
        self.get_logger().info(f"all {n} agents ready; sim time 0 (rtf {self.rtf:g})")
        self.publish_clock(0.0)
        _write(self.p["ready_file"], f"{self.bring_up_s or 0.0:.3f}\n", self)

    # ------------------------------------------------------------------ the base

    async def execute(self, agent: int, handle) -> Any:
        """One goal of robot ``agent``: handed to the world now; the result when it ends."""
        req = handle.request
        fut: Future = Future()
        self.goals[(agent, req.id)] = (fut, handle, req)
        goal: Follow | Stand | Carry
        if req.kind == FollowCells.Goal.FOLLOW:
            goal = Follow(tuple((c.x, c.y) for c in req.path), req.state)
        elif req.kind == FollowCells.Goal.CARRY:
            goal = Carry(int(req.object), tuple(int(j) for j in req.group), req.state)
            self.carrying[agent] = (int(req.object), handle)
        else:
            goal = Stand(req.state)
        if agent not in self.live or not self.started:
            self.finish_goal(GoalResult(agent, req.id, "refused", self.sim_now(), (0, 0), "FAILED",
                                        "the robot has failed" if self.started else "the run has not started"))  # fmt: skip
        else:
            for r in self.world.goal(agent, req.id, goal, max(float(req.at), self.sim_now())):
                self.finish_goal(r)
        res = await fut
        if res.outcome == REACHED:
            handle.succeed()
        else:
            handle.abort()
        return res

    def finish_goal(self, r: GoalResult) -> None:
        entry = self.goals.pop((r.agent, r.goal), None)
        if entry is None:
            return
        fut, handle, _request = entry
        if self.carrying.get(r.agent, (None, None))[1] is handle:
            del self.carrying[r.agent]
        res = FollowCells.Result()
        res.outcome, res.code, res.reason, res.t = r.outcome, r.code, r.reason, float(r.time)
        res.cell.x, res.cell.y = r.cell
        res.detections = self.detections.pop(r.agent, [])
        if r.outcome in (REACHED, ABORTED) and r.agent in self.live:  # it stands there, idle
            res.sensed = [wire.to_ros(o) for o in self.world.feedback(r.agent, float(r.time)).sensed]
        fut.set_result(res)

    def on_where(self, agent: int, request, response):
        fb = self.world.feedback(agent, max(float(request.at), self.sim_now()))
        response.time = float(fb.time)
        response.cell.x, response.cell.y = fb.cell
        response.goal, response.index, response.carrying = int(fb.goal), int(fb.index), int(fb.carrying)
        response.sensed = [wire.to_ros(o) for o in fb.sensed]
        return response

    # ------------------------------------------------------------------ the clock

    def on_timer(self) -> None:
        if not self.started:
            if time.monotonic() - self.last_try >= START_S:  # discovery needs the CPU more
                self.last_try = time.monotonic()
                self.try_start()
            return
        wall = time.monotonic()
        now = self.sim_now()
        if self.ended is None:
            for ev in self.world.advance(now):
                self.dispatch(ev)
            self.check_suspects(wall, now)
            if self.world.done:
                self.end_run(now)
        if wall - self.last_clock >= 1.0 / self.p["clock_hz"]:
            self.last_clock = wall
            self.publish_clock(now)
        if wall - self.last_pose >= 1.0 / POSE_HZ:
            self.last_pose = wall
            self.publish_poses(now)
        if self.result_at is not None:
            # the agents have read the result (or not, after linger): leave
            gone = all(s.get_publisher_count() <= 1 for s in self.kind_subs)  # its own relay's
            if self.p["exit_when_done"] and (gone or wall - self.result_at > self.p["linger"]):
                self.done = True
        elif self.ended is not None and wall - self.ended_wall > 10.0 and self.result_at is None:
            missing = [i for i in self.live if i not in self.reports]
            self.get_logger().warning(f"no report from agents {missing} after 10 s: the result without them")
            self.finish()

    def publish_clock(self, now: float) -> None:
        self.pub_clock.publish(Clock(clock=self.stamp(now)))
        self.write_progress(now)

    def write_progress(self, now: float, last: bool = False) -> None:
        """'step delivered objects' for ost up's progress line, at most every PROGRESS_S (a file
        written at the clock's rate cost the N=50 world a tenth of its time)."""
        wall = time.monotonic()
        if not self.p["progress_file"] or (not last and wall - self.progress_at < PROGRESS_S):
            return
        self.progress_at = wall
        delivered = sum(o.delivered is not None for o in self.world.objects.values())
        _write(self.p["progress_file"], f"{math.floor(now)} {delivered} {len(self.world.objects)}\n", self)

    def publish_poses(self, now: float) -> None:
        stamp = self.stamp(now)
        for i in self.live:
            cell = self.world.position(i, now)
            msg = PoseStamped()
            msg.header.stamp, msg.header.frame_id = stamp, "map"
            msg.pose.position.x, msg.pose.position.y = float(cell[0]), float(cell[1])
            msg.pose.orientation.w = 1.0
            self.pub_pose[i].publish(msg)

    def dispatch(self, ev: Any) -> None:
        if isinstance(ev, GoalResult):
            self.finish_goal(ev)
        elif isinstance(ev, Detection):
            if ev.agent in self.live:
                self.guard.publish(self.pub_det[ev.agent], ev, run=self.run, receivers=(ev.agent,))
                self.detections.setdefault(ev.agent, []).append(wire.to_ros(ev, run=self.run))
        elif isinstance(ev, CarryStarted):
            for j in ev.group:
                obj, handle = self.carrying.get(j, (None, None))
                if obj == ev.object and handle is not None:
                    fb = FollowCells.Feedback()
                    fb.t, fb.lifted, fb.index = float(ev.time), True, -1
                    fb.cell.x, fb.cell.y = self.world.objects[ev.object].at
                    handle.publish_feedback(fb)

    # ------------------------------------------------------------------ what robots say

    def heard_of(self, agent: int, watermark: int, seq: int) -> None:
        w, s = self.heard.get(agent, (-1, 0))
        self.heard[agent] = (max(w, watermark), max(s, seq))
        self.heard_from(agent)

    def on_sample(self, topic: str, s: Any, data: bytes) -> None:
        sender = s.message.sender
        if sender in self.originals:
            self.originals[sender].append((self.kind_pubs[topic], data))
            self.heard_of(sender, int(s.step) - 1, int(s.seq))

    def on_mark(self, m: Mark) -> None:
        self.heard_of(m.sender, m.watermark, m.seq)

    def on_digest(self, d: Digest) -> None:
        self.digests.setdefault(d.stamp, {})[d.sender] = (d.input, d.output)

    # ------------------------------------------------------------------ failures

    def on_liveliness(self, agent: int, info) -> None:
        if info.alive_count > 0:
            self.alive_seen.add(agent)
            self.suspects.pop(agent, None)
            return
        if info.not_alive_count_change > 0 and self.started and agent in self.live and self.ended is None:
            self.suspects.setdefault(agent, time.monotonic())

    def on_alive_sample(self, agent: int, _msg=None) -> None:
        self.alive_seen.add(agent)
        self.heard_from(agent)

    def heard_from(self, agent: int) -> None:
        self.suspects.pop(agent, None)

    def check_suspects(self, wall: float, now: float) -> None:
        for agent, since in list(self.suspects.items()):
            if wall - since >= self.failure_timeout:
                del self.suspects[agent]
                self.declare_failed(agent, now)

    def declare_failed(self, agent: int, now: float) -> None:
        """The robot is gone: stopped in the world, declared to the survivors with a notice stamped
        above its last watermark, and its signed messages published again for any survivor that
        lacks one of those that count."""
        if agent not in self.live:
            return
        self.live.discard(agent)
        self.world.kill(agent, now)  # its partners' goals end at the next advance
        watermark, seq = self.heard[agent]
        # stamped by the time now, not the timer's: declaring a robot republishes what it signed,
        # and a 50-robot world declaring several in one pass took seconds — a robot only thought
        # failed commits on meanwhile, and its notice must come after what it committed
        stamp = max(watermark + 1, math.ceil(max(now, self.sim_now()) - 1e-9))
        notice = self.world.notice(agent, stamp, seq)
        self.guard.publish(self.pub_lost, notice, run=self.run)
        for pub, data in self.originals[agent]:
            self.guard.relay(pub, data)  # as the robot itself sealed it
        self.get_logger().warning(
            f"agent {agent} lost (no liveliness for 2 x {self.failure_timeout:g} s): failed at sim "
            f"time {now:.1f}, notice stamped {notice.t}; {len(self.live)} survivors"
        )
        if not self.live:
            self.end_run(now)

    # ------------------------------------------------------------------ end

    def end_run(self, now: float) -> None:
        """The world is done (or every robot failed): ask the survivors for their reports."""
        ends = [b.finished for b in self.world.bots.values() if b.finished is not None]
        ends += [o.delivered for o in self.world.objects.values() if o.delivered is not None]
        self.world.end = max(ends, default=now)
        self.ended, self.ended_wall = self.world.end, time.monotonic()
        self.completed = self.world.done and not self.world.undeliverable()
        end = RunEnd(self.world.t, self.world.t, self.completed, run=self.run)
        self.guard.publish(self.pub_end, end)
        self.write_progress(self.world.end, last=True)
        self.get_logger().info(f"run over at sim time {self.world.end:g}; collecting reports")
        if not self.live:
            self.finish()

    def on_report(self, r: AgentReport) -> None:
        if r.run != self.run or r.agent not in self.ids:
            return
        self.reports[r.agent] = r
        if self.ended is not None and self.result_at is None and all(i in self.reports for i in self.live):
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
            "lag": {str(r.agent): r.lag for r in sorted(self.reports.values(), key=lambda r: r.agent)},
            "wall_s": round(wall, 3),
            "bring_up_s": None if self.bring_up_s is None else round(self.bring_up_s, 2),
        }
        text = json.dumps(data, indent=1)
        if self.p["result_file"]:
            try:
                write_file(self.p["result_file"], text + "\n")
            except OSError as exc:
                self.get_logger().error(f"result_file: cannot write {self.p['result_file']} ({exc.strerror})")
        self.pub_result.publish(String(data=text))
        self.result_at = time.monotonic()
        self.get_logger().info(
            f"result: makespan {result.makespan}, completed {result.completed}, disagreements {bad} "
            f"of {compared}; wall {wall:.1f} s"
        )

    @property
    def exit_code(self) -> int:
        return 0 if self.completed else 1


def _write(path: str, text: str, node: Node) -> None:
    if not path:
        return
    try:
        write_file(path, text)
    except OSError as exc:
        node.get_logger().warning(f"cannot write {path} ({exc.strerror})")
