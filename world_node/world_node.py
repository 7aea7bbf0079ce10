"""``world_node``: the grid truth of a run, stepping N agent nodes in lockstep over DDS.

    world_node --ros-args -p scenario:=run.yaml -p result_file:=/tmp/result.json

Parameters: the run configuration's world settings (:func:`ost_ros.runconfig.of_node`, read-only,
each with its description and range: ``ros2 param describe /ost/world scenario``) — the scenario
and team, the step limit, event skipping, the files it writes for whoever supervises the run
(``result_file``, ``progress_file``, ``ready_file``, ``checkpoint_file``; ``resume`` continues
from the checkpoint), the liveliness lease it asks of every agent (``failure_timeout``: a robot
whose process is gone for about two of them is declared failed and the survivors re-plan),
``observers``, keys, executor, ``rediscover_s``.

Topics are relative to the node's namespace (default ``/ost``): publishes ``clock`` (sim time:
step t = t seconds), ``markers``, each agent's ``agent_<i>/tick`` (``ost_msgs/msg/Tick``),
``run_end`` and the result on ``result`` (JSON in ``std_msgs/msg/String``, transient local: it
stays readable while the world runs). Invalid or out-of-turn messages are dropped with a
throttled warning naming the sender; illegal actions are rejected by ``World.apply`` with a
reason that goes into the result.
"""

from __future__ import annotations

import contextlib
import json
import os
import pickle
import secrets
import statistics
import sys
import time
from pathlib import Path

from builtin_interfaces.msg import Time
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from visualization_msgs.msg import MarkerArray

from ost_msgs_py import auth, wire
from ost_ros.bounds import lower_bound
from ost_ros.lockstep.messages import Acted, AgentReport, RunEnd, RunInfo, Tick
from ost_ros.lockstep.world import ProtocolViolation, WorldRuntime
from ost_ros.node import transport as tp
from ost_ros.node.params import ParameterError, declare_role, node_scenario, realtime_from_args
from ost_ros.node.plumbing import Liveliness, Readiness, Result, SignalFiles
from ost_ros.node.run import process_age, run_node
from ost_ros.node.signing import node_auth
from ost_ros.runconfig import WORLD
from ost_ros.scenario import dump_scenario
from world_node.markers import world_markers

# A step taking longer than this is reported (who has not acted yet).
STALL_S = 5.0


class WorldNode(Node):
    """``<ns>/world`` (default namespace ``/ost``): the grid truth, stepping the agents."""

    def __init__(self):
        super().__init__(tp.WORLD_NODE, namespace=tp.NAMESPACE)
        p = declare_role(self, WORLD)  # the run configuration's world settings (ost_ros.runconfig)
        scenario = node_scenario(p)
        self.scenario = scenario
        self.fingerprint = tp.scenario_fingerprint(scenario)
        self.guard = node_auth(p["keys"], p["insecure"], auth.WORLD)
        # A fresh id per run: messages of any other run (a stray node) are told apart. A secure
        # run's id comes with its keys: every process knows it from team.yaml.
        run = self.guard.run or secrets.token_hex(6)
        self.rt = WorldRuntime(scenario, p["max_steps"] or None, p["event_skipping"], run=run)
        self.marker_every = p["marker_every"]
        self.rediscover_s = p["rediscover_s"]
        self.observers = p["observers"]
        self.ids = self.rt.ids
        self.throttle = tp.Throttle(self.get_logger())
        self.files = SignalFiles(p, self.throttle)
        self.started = False
        self.done = False
        self.ticks_sent = 0
        # Round trips timed (tick sent → last action in), quiet ones and those with protocol
        # messages apart (benchmarks/bench_ros.py sets them against bench_floor.py's floor):
        # a float each for the whole run, since the transport stats give their medians.
        self.tick_at = 0.0
        self.round_trip_s: dict[str, list[float]] = {"quiet": [], "messages": []}
        self.bring_up_s: float | None = None
        self.t_start = 0.0
        self.last_progress = self.stall_since = time.monotonic()
        self.discovery = tp.Unchanged()  # what start lacks, and since when (rediscover_s)
        self.last_sent: list = []  # what the current step published (Ticks or a RunEnd), for resend()
        self.last_agents: list[int] = []  # ... to whom (the survivors)
        self.checkpoint_file = p["checkpoint_file"]
        self.resumed = False
        if p["resume"]:
            self.load_checkpoint()

        q = tp.LOCKSTEP_QOS
        self.pub_clock = self.create_publisher(Clock, tp.CLOCK, tp.LATEST_QOS)
        self.pub_markers = self.create_publisher(MarkerArray, tp.MARKERS, tp.LATEST_QOS)
        pub = tp.no_events_pub  # lockstep endpoints: see no_events_pub
        self.pub_tick = {
            i: self.create_publisher(wire.ros_type(Tick), tp.tick_topic(i), q, event_callbacks=pub())
            for i in self.ids
        }
        self.pub_end = self.create_publisher(
            wire.ros_type(RunEnd), tp.RUN_END, tp.LATCHED_ALL_QOS, event_callbacks=pub()
        )
        self.result = Result(self, p)
        self.pub_info = self.create_publisher(
            wire.ros_type(RunInfo), tp.RUN_INFO, tp.LATCHED_ALL_QOS, event_callbacks=pub()
        )
        info = RunInfo(
            self.rt.run, dump_scenario(scenario), self.fingerprint, self.rt.skipping, self.rt.max_steps or 0
        )
        self.guard.publish(self.pub_info, info)
        g, th = self.guard, self.throttle
        self.sub_acted = tp.subscribe(self, Acted, tp.ACTED, self.on_acted, q, g, th)
        self.ready = Readiness(self, self.ids, self.fingerprint, g, th, then=self.try_start)
        self.sub_report = tp.subscribe(
            self, AgentReport, tp.REPORTS, self.on_report, tp.LATCHED_ALL_QOS, g, th
        )
        # One liveliness reader per robot: a killed agent process is reported within the lease;
        # lost after the start, it fails if the loss lasts another failure_timeout with nothing
        # heard from it.
        self.failure_timeout = p["failure_timeout"]
        self.alive = Liveliness(
            self,
            self.ids,
            p["failure_timeout"],
            suspect=lambda i: self.started and self.result.at is None and i not in self.rt.failed,
            then=self.try_start,
            say=True,
        )
        self.timer = self.create_timer(0.1, self.on_timer)
        self.publish_state(self.rt.world.t)
        if self.resumed:
            self.get_logger().info(
                f"resuming at step {self.rt.world.t} from {self.checkpoint_file}; "
                f"waiting for {len(self.ids)} agents to match"
            )
        else:
            self.get_logger().info(f"waiting for {len(self.ids)} agents ({self.fingerprint})")

    # ------------------------------------------------------------------ checkpoint

    def save_checkpoint(self) -> None:
        """The whole truth and what this step publishes, written atomically (tmp + rename)."""
        if not self.checkpoint_file:
            return
        state = {
            "fingerprint": self.fingerprint,
            "rt": self.rt,
            "ticks_sent": self.ticks_sent,
            "last_sent": self.last_sent,
            "last_agents": self.last_agents,
        }
        tmp = f"{self.checkpoint_file}.tmp"
        try:
            with open(tmp, "wb") as f:
                pickle.dump(state, f, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, self.checkpoint_file)
        except OSError as exc:
            self.throttle.note(
                ("checkpoint", "world"),
                f"checkpoint_file: cannot write {self.checkpoint_file} ({exc.strerror})",
            )

    def load_checkpoint(self) -> None:
        if not self.checkpoint_file:
            raise ParameterError("resume: needs a checkpoint_file")
        try:
            with open(self.checkpoint_file, "rb") as f:
                state = pickle.load(f)
        except FileNotFoundError:
            self.get_logger().warning(f"resume: no checkpoint at {self.checkpoint_file}; starting afresh")
            return
        except (OSError, pickle.UnpicklingError, EOFError, AttributeError) as exc:
            raise ParameterError(f"resume: cannot read {self.checkpoint_file} ({exc})") from None
        if not isinstance(state, dict) or state.get("fingerprint") != self.fingerprint:
            raise ParameterError(
                f"resume: {self.checkpoint_file} is not a checkpoint of this scenario ({self.fingerprint})"
            )
        self.rt = state["rt"]
        self.ticks_sent = state["ticks_sent"]
        self.last_sent = list(state["last_sent"])
        self.last_agents = list(state.get("last_agents", self.rt.live))
        self.resumed = True

    # ------------------------------------------------------------------ start

    def try_start(self) -> None:
        if self.started:
            return
        if not self.ready.complete and not self.resumed:
            if time.monotonic() - self.stall_since > tp.DISCOVERY_NOTE_S:  # say who is not ready
                waiting = self.ready.missing()
                self.throttle.note(
                    ("start", "world"),
                    f"not starting yet: no ready from agents {waiting[:8]}"
                    + (f" and {len(waiting) - 8} more" if len(waiting) > 8 else "")
                    + " (each says what its discovery lacks in its log)",
                )
            return
        ticks = [i for i in self.rt.live if self.pub_tick[i].get_subscription_count() < 1 + self.observers]
        writers = self.sub_acted.get_publisher_count()
        unseen = self.alive.unseen(self.rt.live)
        if ticks or writers < len(self.rt.live) or unseen:
            now = time.monotonic()
            if (ticks or writers < len(self.rt.live)) and self.discovery.for_s(
                (ticks, writers), now
            ) > self.rediscover_s:
                self.get_logger().warning(
                    f"discovery has not moved for {self.rediscover_s:g} s (tick readers unmatched "
                    f"{ticks[:8]}, action writers {writers}/{len(self.rt.live)}): creating those "
                    "endpoints anew"
                )
                for i in ticks:
                    self.pub_tick[i] = tp.renew(self, self.pub_tick[i])
                if writers < len(self.rt.live):
                    self.sub_acted = tp.renew(self, self.sub_acted)
                self.discovery.restart(now)
            if now - self.stall_since > STALL_S:  # say what discovery lacks
                self.throttle.note(
                    ("start", "world"),
                    f"not starting yet: tick readers unmatched {ticks[:8]}, action "
                    f"writers {writers}/{len(self.rt.live)}, liveliness not seen "
                    f"from {unseen[:8]}",
                )
            return  # the timer tries again
        if self.resumed:
            # The agents are mid-run: publish the checkpointed step again (resend does it).
            self.started = True
            self.t_start = time.monotonic()
            self.get_logger().info(f"all {len(self.ids)} agents matched; resuming step {self.rt.world.t}")
            self.publish_state(self.rt.world.t)
            self.resend(all_agents=True)
            return
        protocols = {r.protocol for r in self.ready.of.values()}
        if len(protocols) > 1:
            self.throttle.warn(self.ready.sub.topic_name, "agents", f"mixed protocols {sorted(protocols)}")
        self.rt.protocol = min(protocols)  # what a failure can be recovered by
        self.rt.organisation = min(r.organisation for r in self.ready.of.values())
        self.started = True
        self.t_start = time.monotonic()
        self.bring_up_s = process_age()
        self.get_logger().info(f"all {len(self.ids)} agents ready; step 0")
        self.send(self.rt.start())
        self.files.ready(self.bring_up_s)

    def on_timer(self) -> None:
        now = time.monotonic()
        self.write_progress()
        if not self.started:
            self.try_start()
            return
        if self.result.at is not None:
            # Leave once every agent is gone (it has read the result), or after a while.
            # (a failed agent's endpoint stays in the graph until its participant lease ends)
            if self.result.leave(now, lambda: self.sub_acted.get_publisher_count() <= len(self.rt.failed)):
                self.done = True
            return
        if self.alive.suspects:
            self.alive.check(now, self.declare_failed)
        if self.result.at is not None:
            return
        if now - self.last_progress > tp.RESEND_S:
            self.resend()
        if self.rt.ended is None and now - self.stall_since > STALL_S:
            # Say who the barrier waits for: a silent stall is the worst failure to debug.
            missing = [i for i in self.rt.live if i not in self.rt.acted_agents()]
            self.throttle.note(
                ("stall", "world"),
                f"step {self.rt.world.t} stalled for {STALL_S:g} s: no action yet "
                f"from agents {missing} (ticks re-sent every {tp.RESEND_S:g} s)",
            )
            self.stall_since = now

    # ------------------------------------------------------------------ stepping

    def send(self, nxt) -> None:
        self.last_progress = self.stall_since = time.monotonic()
        t = self.rt.world.t
        self.publish_state(t)
        if isinstance(nxt, RunEnd):
            self.last_sent = [nxt]
            self.save_checkpoint()
            self.guard.publish(self.pub_end, nxt)
            self.get_logger().info(
                f"run ended at step {nxt.steps} (completed: {nxt.completed}); collecting reports"
            )
            return
        self.last_sent = list(nxt)
        self.last_agents = [tick.observation.agent for tick in nxt]
        self.ticks_sent += 1
        self.save_checkpoint()  # before publishing: a published step is always recoverable
        self.tick_at = time.monotonic()
        for tick in nxt:
            agent = tick.observation.agent  # its topic has one reader of the team: one tag
            self.guard.publish(self.pub_tick[agent], tick, receivers=(agent,))

    def resend(self, all_agents: bool = False) -> None:
        """A step waits too long: publish its ticks (to agents that have not acted) or the
        run_end again. Agents answer a tick they already answered by re-sending their answer."""
        self.last_progress = time.monotonic()
        if self.rt.ended is not None:
            if (self.rt.missing_reports or all_agents) and self.last_sent:
                self.guard.publish(self.pub_end, self.last_sent[0])
            return
        acted = set() if all_agents else set(self.rt.acted_agents())
        for agent, tick in zip(self.last_agents, self.last_sent):
            if agent not in acted and agent in self.rt.live:  # sealed afresh: a new counter
                self.guard.publish(self.pub_tick[agent], tick, receivers=(agent,))

    def publish_state(self, t: int) -> None:
        stamp = Time(sec=t, nanosec=0)
        self.pub_clock.publish(Clock(clock=stamp))
        due = self.marker_every and (self.ticks_sent % self.marker_every == 0 or self.rt.ended)
        # Built for someone listening only (RViz, Foxglove, a recorder; the topic is volatile, so
        # nobody later misses one): ~1 ms of the world's time per tick (docs/ros.md).
        if due and self.pub_markers.get_subscription_count() > 0:
            self.pub_markers.publish(world_markers(self.rt.world, stamp))

    def write_progress(self, last: bool = False) -> None:
        """'step delivered objects' for a progress line (ost_up.sh on a terminal)."""
        self.files.progress(self.rt.world.t, self.rt.world.objects.values(), last)

    def on_acted(self, a: Acted) -> None:
        if a.run != self.rt.run:  # another run's (a stray): say so whether or not we started
            self.throttle.warn(
                self.sub_acted.topic_name,
                f"agent {a.action.agent}",
                f"action of run {a.run!r}, this is run {self.rt.run!r}",
            )
            return
        if not self.started:
            self.throttle.warn(
                self.sub_acted.topic_name, f"agent {a.action.agent}", "action before the run started"
            )
            return
        self.alive.heard_from(a.action.agent)
        try:
            self.rt.accept_acted(a)
        except ProtocolViolation as exc:
            self.throttle.warn(self.sub_acted.topic_name, f"agent {a.action.agent}", str(exc))
            return
        if self.rt.step_complete:
            before = self.rt.messages
            nxt = self.rt.advance()
            kind = "messages" if self.rt.messages > before else "quiet"
            self.round_trip_s[kind].append(time.monotonic() - self.tick_at)
            self.send(nxt)

    # ------------------------------------------------------------------ failures

    def declare_failed(self, agent: int) -> None:
        if self.result.at is not None or agent in self.rt.failed:
            return
        if self.rt.ended is not None:
            self.rt.fail(agent)
            self.get_logger().warning(f"agent {agent} lost after the run ended; not waiting for its report")
            if not self.rt.missing_reports:
                self.finish()
            return
        step = self.rt.world.t
        nxt = self.rt.fail(agent)
        self.get_logger().warning(
            f"agent {agent} lost (no liveliness for 2 x {self.failure_timeout:g} s): failed in step "
            f"{step}; {len(self.rt.live)} survivors"
            + (f"; {self.rt.aborted}" if self.rt.aborted else ", re-coordinating")
        )
        if nxt is not None:
            self.send(nxt)
        if self.rt.aborted:
            self.finish()

    # ------------------------------------------------------------------ end

    def on_report(self, r: AgentReport) -> None:
        self.alive.heard_from(r.agent)
        try:
            self.rt.accept_report(r)
        except ProtocolViolation as exc:
            self.throttle.warn(self.sub_report.topic_name, f"agent {r.agent}", str(exc))
            return
        if not self.rt.missing_reports and self.result.at is None:
            self.finish()

    def finish(self) -> None:
        result = self.rt.result()
        result.lower_bound = lower_bound(self.scenario).value  # as `ost sim` prints it
        out_at = self.result.publish(json.dumps(result.to_dict(), indent=1))
        self.write_progress(last=True)
        wall = out_at - self.t_start
        stats = {
            "wall_s": round(wall, 3),
            "steps": self.rt.world.t,
            "round_trips": self.rt.round_trips,
            "skipped_steps": self.rt.skipped,
            "protocol_messages": self.rt.messages,
            # median round trip (ms) and how many, quiet and with protocol messages
            "round_trip_ms": {
                k: {"median": round(1000 * statistics.median(v), 2) if v else None, "n": len(v)}
                for k, v in self.round_trip_s.items()
            },
            "bring_up_s": None if self.bring_up_s is None else round(self.bring_up_s, 2),
            # messages dropped (unsealed, forged, replayed, malformed), by the world and (their
            # reports) the agents
            "auth": {"secure": self.guard.secure, "dropped": self.dropped()},
        }
        self.get_logger().info(
            f"result: makespan {result.makespan}, completed {result.completed}; transport {json.dumps(stats)}"
        )
        if self.result.file:
            with contextlib.suppress(OSError):  # the stats are a nicety; the result is written
                Path(self.result.file + ".transport.json").write_text(json.dumps(stats) + "\n")

    def dropped(self) -> dict[str, int]:
        total = self.guard.counts()
        for r in self.rt.reports.values():
            for reason, n in zip(auth.REASONS, r.dropped):
                total[reason] += n
        return total


def main(args=None) -> int:
    if realtime_from_args(sys.argv if args is None else args):
        from world_node.realtime import RealtimeWorldNode

        return run_node(
            "world_node",
            RealtimeWorldNode,
            args,
            done=lambda node: node.done,
            code=lambda node: node.exit_code,
            interrupted=130,
        )
    return run_node(
        "world_node",
        WorldNode,
        args,
        done=lambda node: node.done,
        # 0: the run completed; 1: it ended otherwise (step limit, every agent gone)
        code=lambda node: 0 if node.rt.ended is not None and node.rt.ended.completed else 1,
        interrupted=130,
    )


if __name__ == "__main__":
    sys.exit(main())
