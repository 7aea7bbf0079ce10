"""``agent_node``: one robot — the core agent behind a DDS transport.

    agent_node --ros-args -p agent_id:=3 -p scenario:=run.yaml -p ci:=1

Parameters: the run configuration's agent settings (:func:`ost_ros.runconfig.of_node`, read-only,
each with its description and range: ``ros2 param describe /ost/agent_0 ci`` when it runs with
``param_services:=true``, :func:`ost_ros.node.params.robot_node_options`) — ``agent_id`` and
``scenario`` first, the protocol and its options, the coordination trigger, fault injection
(``die_at_step``, ``mute_negotiation_from``), the liveliness lease, keys, executor. The agent is
built by its protocol's factory (the registry) and runs unchanged: the node only orders its calls
(the lockstep runtime, :mod:`ost_ros.lockstep.agent`) and moves messages.
"""

from __future__ import annotations

import dataclasses
import functools
import sys
import time
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription
from std_msgs.msg import String

from ost_msgs_py import wire
from ost_ros.coordination import CoordinationPolicy
from ost_ros.lockstep.agent import AgentRuntime, ProtocolViolation
from ost_ros.lockstep.messages import Acted, AgentReport, Ready, Resend, RunEnd, Sample, Tick
from ost_ros.model import Scenario
from ost_ros.node import transport as tp
from ost_ros.node.params import (
    ParameterError,
    declare_agent,
    param_from_args,
    realtime_from_args,
    robot_node_options,
)
from ost_ros.node.plumbing import Alive, Leaving, awaiting_endpoints, die_at, renew_endpoints
from ost_ros.node.run import run_node
from ost_ros.node.signing import node_auth
from ost_ros.team import TeamInfo

# Without the world for this long after the start, the agent gives up (it would wait forever).
WORLD_LOST_S = 10.0
# A tick held this long for peers' step messages is reported (whose are missing).
STALL_S = 5.0
# Peers' sealed samples kept for relaying: the newest steps (the runtime relays from its last 3).
RELAY_STEPS = 8


class AgentNode(Node):
    """``<ns>/agent_<id>`` (default namespace ``/ost``): parameters → core agent →
    :class:`AgentRunner` on its topics."""

    def __init__(self, name: str = "agent", **options: Any):
        super().__init__(name, namespace=tp.NAMESPACE, **options)
        scenario, policy, runtime = load_agent(self)
        self.runner = AgentRunner(self, scenario, policy, runtime)


def load_agent(node: Node) -> tuple[Scenario, CoordinationPolicy, AgentRuntime]:
    """Declare and check the parameters (the run configuration's agent settings); the runtime
    around the core agent."""
    p, cfg, scenario, spec = declare_agent(node)
    policy, settings = cfg.policy(), cfg.protocol_settings()
    ids = tuple(a.id for a in scenario.agents)
    agent = spec.make_agent(p["agent_id"], TeamInfo.from_scenario(scenario), policy, settings)
    if p["mute_negotiation_from"] >= 0 and spec.silence is not None:
        # fault injection (tests, demos): this negotiator stops answering from that step on
        spec.silence(agent, p["mute_negotiation_from"])
    return scenario, policy, AgentRuntime(agent, ids, p["lookahead"])


class AgentRunner:
    """Wires one :class:`AgentRuntime` to its topics."""

    def __init__(self, node: Node, scenario: Scenario, policy: CoordinationPolicy, runtime: AgentRuntime):
        self.node = node
        self.rt = runtime
        self.organisation = policy.organisation
        self.n = len(runtime.team)
        # A recorder or live view must hold every sample of the run: the start waits for it too.
        self.observers = node.get_parameter("observers").value
        self.fingerprint = tp.scenario_fingerprint(scenario)
        self.protocol = runtime.agent.protocol
        self.done = False
        self.exit_code = 0
        self.ready_sent = False
        self.world_seen = False
        self.world_lost_since: float | None = None
        self.held_since: float | None = None
        self.throttle = tp.Throttle(node.get_logger())
        self.created = time.monotonic()  # for saying what discovery lacks when it takes long
        self.discovery = tp.Unchanged()  # what it lacks, and since when (the rediscover_s parameter)
        self.rediscover_s = node.get_parameter("rediscover_s").value
        me = runtime.me
        self.guard = node_auth(node.get_parameter("keys").value, node.get_parameter("insecure").value, me)
        # Peers' samples as received (sealed by them): what this agent relays for a peer that a
        # third one lacks (Resend) must carry the peer's own tags, byte for byte. The newest
        # steps only.
        self.originals: dict[int, dict[tuple[int, int], bytes]] = {}
        self.report_sent: AgentReport | None = None
        self.leaving = Leaving()
        q = tp.LOCKSTEP_QOS
        self.tick_topic = tp.tick_topic(me)
        pub = tp.no_events_pub
        g, th = self.guard, self.throttle
        self.pub_acted = node.create_publisher(wire.ros_type(Acted), tp.ACTED, q, event_callbacks=pub())
        self.pub_ready = node.create_publisher(
            wire.ros_type(Ready), tp.READY, tp.LATCHED_ALL_QOS, event_callbacks=pub()
        )
        self.pub_report = node.create_publisher(
            wire.ros_type(AgentReport), tp.REPORTS, tp.LATCHED_ALL_QOS, event_callbacks=pub()
        )
        self.sub_tick = tp.subscribe(node, Tick, self.tick_topic, self.on_tick, q, g, th)
        self.pub_resend = node.create_publisher(wire.ros_type(Resend), tp.RESEND, q, event_callbacks=pub())
        self.sub_resend = tp.subscribe(node, Resend, tp.RESEND, self.on_resend, q, g, th)
        self.resent_at: float | None = None
        self.sub_end = tp.subscribe(node, RunEnd, tp.RUN_END, self.on_end, tp.LATCHED_ALL_QOS, g, th)
        # One topic per message kind of the protocol (object_found, selection, ...), every agent
        # publishing and subscribing: all of them are part of the step's barrier.
        self.kind_pubs = {
            kind: node.create_publisher(wire.ros_type(kind), tp.message_topic(kind), q, event_callbacks=pub())
            for kind in runtime.kinds
        }
        self.kind_subs = [
            # keep_bytes: a peer's sample may have to be relayed as it came
            tp.subscribe(
                node,
                kind,
                tp.message_topic(kind),
                functools.partial(self.on_sample, kind=kind),
                q,
                g,
                th,
                keep_bytes=True,
            )
            for kind in runtime.kinds
        ]
        self.sub_result = node.create_subscription(String, tp.RESULT, self.on_result, tp.RESULT_QOS)
        # Published to once (at ready); after that DDS asserts its liveliness by itself and the
        # world watches it (failures).
        lease = node.get_parameter("failure_timeout").value
        if not isinstance(lease, (int, float)) or lease < 0:
            raise ParameterError(f"failure_timeout: {lease!r} must be a non-negative number of seconds")
        self.alive = Alive(node, me, float(lease))
        self.die_at = node.get_parameter("die_at_step").value
        self.timer = node.create_timer(0.1, self.on_timer)

    # ------------------------------------------------------------------ discovery

    def lacking(self) -> list[tuple[Publisher | Subscription, str, int, int]]:
        """The endpoints whose matching is not complete (counted, never waited for by sleeping):
        (endpoint, ``readers of <topic>`` or ``writers of <topic>``, matched, needed)."""
        k = self.observers
        counts: list[tuple[Publisher | Subscription, int, int]] = [
            (self.pub_acted, self.pub_acted.get_subscription_count(), 1 + k),
            (self.pub_ready, self.pub_ready.get_subscription_count(), 1 + k),
            (self.pub_report, self.pub_report.get_subscription_count(), 1 + k),
            (self.sub_tick, self.sub_tick.get_publisher_count(), 1),
            (self.sub_end, self.sub_end.get_publisher_count(), 1),
            # its one sample must reach the world, not only an observer that matched first
            (self.alive.pub, self.alive.pub.get_subscription_count(), 1 + k),
            (self.pub_resend, self.pub_resend.get_subscription_count(), self.n + k),
            *((pub, pub.get_subscription_count(), self.n + k) for pub in self.kind_pubs.values()),
            *((sub, sub.get_publisher_count(), self.n) for sub in self.kind_subs),
        ]
        return [
            (e, f"{'readers' if isinstance(e, Publisher) else 'writers'} of {e.topic_name}", have, need)
            for e, have, need in counts
            if have < need
        ]

    def rediscover(self, endpoints: list[Publisher | Subscription]) -> None:
        """Create ``endpoints`` anew (the rediscover_s parameter); before the run, so nothing is
        in flight on them."""
        singles = ("pub_acted", "pub_ready", "pub_report", "sub_tick", "sub_end", "pub_resend")
        renew_endpoints(self.node, self, endpoints, singles)

    def on_timer(self) -> None:
        self.leave_if_reported()
        if not self.ready_sent:
            if awaiting_endpoints(
                self.node,
                self.throttle,
                self.lacking(),
                self.created,
                self.discovery,
                self.rediscover_s,
                self.rediscover,
            ):
                return
            # One sample asserts this robot's liveliness at once (the world waits for it)
            self.alive.say()
            ready = Ready(self.rt.me, self.protocol, self.fingerprint, self.organisation)
            self.guard.publish(self.pub_ready, ready)
            self.ready_sent = True
            self.world_seen = True
            self.node.get_logger().info(f"ready: {self.n} agents and the world matched")
            return
        self.alive.again_to_new_readers()  # (a restarted world)
        now = self.node.get_clock().now().nanoseconds * 1e-9
        held = self.rt.held()
        if held is not None and held[1]:
            self.held_since = self.held_since or now
            if now - self.held_since > tp.RESEND_S and now - (self.resent_at or 0.0) > tp.RESEND_S:
                resend = Resend(self.rt.me, self.rt.last, held[1], self.rt.run or "")
                self.guard.publish(self.pub_resend, resend)
                self.resent_at = now
            if now - self.held_since > STALL_S:
                self.throttle.note(
                    ("stall", "barrier"),
                    f"tick {held[0]} held for {STALL_S:g} s: messages missing "
                    f"from agents {list(held[1])} (asked again every "
                    f"{tp.RESEND_S:g} s)",
                )
                self.held_since = now
        else:
            self.held_since = None
        # The world gone for good: stop instead of waiting forever (lockstep only: Leaving says why)
        if self.sub_tick.get_publisher_count() == 0:
            self.world_lost_since = self.world_lost_since or now
            if now - self.world_lost_since > WORLD_LOST_S:
                self.node.get_logger().error(f"world node gone for {WORLD_LOST_S:.0f} s; exiting")
                self.exit_code, self.done = 1, True
        else:
            self.world_lost_since = None

    # ------------------------------------------------------------------ traffic

    def _progress(self) -> None:
        while self.rt.dropped:  # messages of another run that came before the first tick
            sample, why = self.rt.dropped.pop()
            topic = self.kind_pubs[type(sample.message)].topic_name
            self.throttle.warn(topic, f"agent {sample.message.sender}", why)
        for out in self.rt.progress():
            if isinstance(out, Sample):
                pub = self.kind_pubs[type(out.message)]
                if out.message.sender == self.rt.me or not self.guard.secure:
                    self.guard.publish(pub, out)
                    continue
                # A peer's sample relayed: as the peer sealed it (this agent cannot seal for it;
                # one no longer held is left to the peer's own resend).
                original = self.originals.get(out.step, {}).get((out.message.sender, out.seq))
                if original is not None:
                    self.guard.relay(pub, original)
            elif isinstance(out, Acted):
                self.guard.publish(self.pub_acted, out)
            else:
                if self.report_sent is None:  # the drops so far, fixed: a re-sent report is the same
                    self.report_sent = dataclasses.replace(out, dropped=tuple(self.guard.counts().values()))
                self.guard.publish(self.pub_report, self.report_sent)
                self.node.get_logger().info(f"run ended; report sent ({self.rt.sent} messages)")

    def _feed(self, m, topic: str, accept, data: bytes | None = None) -> None:
        try:
            accept(m)
        except ProtocolViolation as exc:
            self.throttle.warn(topic, tp.sender_of(m), str(exc))
            return
        if data is not None and self.guard.secure and m.message.sender != self.rt.me:
            self.originals.setdefault(m.step, {})[(m.message.sender, m.seq)] = data
            while len(self.originals) > RELAY_STEPS:
                del self.originals[min(self.originals)]
        self._progress()

    def on_tick(self, tick: Tick) -> None:
        die_at(self.node, self.die_at, tick.t)  # fault injection, on the tick of that step
        self._feed(tick, self.sub_tick.topic_name, self.rt.accept_tick)

    def on_sample(self, sample: Sample, data: bytes, kind: type) -> None:
        self._feed(sample, self.kind_pubs[kind].topic_name, self.rt.accept_sample, data)

    def on_resend(self, resend: Resend) -> None:
        self._feed(resend, self.sub_resend.topic_name, self.rt.accept_resend)

    def on_end(self, end: RunEnd) -> None:
        self._feed(end, self.sub_end.topic_name, self.rt.accept_end)

    def on_result(self, msg: String) -> None:
        # The world has every report: this agent's job is over (it leaves as Leaving says). A
        # result before this agent finished: the world ended the run early (a failure its
        # protocol cannot recover from). The result is a display topic (std_msgs/String,
        # unsigned): it never ends this agent's part before its report is with the world, and
        # in a secure run an early one is not believed — the agent leaves once the world is gone.
        if self.rt.finished:
            self.leaving.result = True
            self.leave_if_reported()
        elif self.rt.run is not None and not self.guard.secure:
            self.node.get_logger().error("the world ended the run before this agent finished; exiting")
            self.exit_code, self.done = 1, True
        elif self.rt.run is not None:
            self.throttle.note(
                (tp.RESULT, "result"),
                "a result before this agent finished: not believed (unsigned); "
                f"leaving if the world is gone for {WORLD_LOST_S:.0f} s",
            )

    def leave_if_reported(self) -> None:
        """After the result: leave once every reader of the report has acknowledged it."""
        if self.leaving.may_leave(self.pub_report):
            self.done = True


def agent_id_from_args(argv: list[str]) -> int | None:
    """``agent_id`` as the ROS arguments set it (:func:`ost_ros.node.params.param_from_args`), or
    None when unset or not a non-negative int. The node still declares and checks the parameter
    itself; this only picks its name."""
    value = param_from_args(argv, "agent_id")
    try:
        return int(value) if value is not None and int(value) >= 0 else None
    except (TypeError, ValueError):
        return None


def main(args=None) -> int:
    # The node's name is agent_<id>; the id is a parameter, read here from the ROS arguments.
    # (A throw-away bootstrap node did this before: destroying it right after its creation now
    # and then spun forever inside rcl, hanging the process at start.)
    argv = sys.argv if args is None else args
    agent_id = agent_id_from_args(argv)
    name = tp.agent_node_name(agent_id) if agent_id is not None else "agent"
    options = robot_node_options(argv)
    if realtime_from_args(argv):
        from agent_node.realtime import RealtimeAgentNode

        return run_node(
            "agent_node",
            lambda: RealtimeAgentNode(name, **options),
            args,
            done=lambda node: node.done,
            code=lambda node: node.exit_code,
        )
    return run_node(
        "agent_node",
        lambda: AgentNode(name, **options),
        args,
        done=lambda node: node.runner.done,
        code=lambda node: node.runner.exit_code,
    )


if __name__ == "__main__":
    sys.exit(main())
