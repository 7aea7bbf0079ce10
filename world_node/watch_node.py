"""``watch_node``: records a run (rosbag2-style MCAP) and/or shows it live in Foxglove.

    watch_node --ros-args -r __ns:=/ost -p record:=run.mcap -p foxglove_port:=8765

Like ``ros2 bag record`` it subscribes to every topic of its namespace as the topic appears in
the graph, with the QoS its publishers offer, and takes each sample as the CDR bytes that
crossed DDS (``raw``): the recording holds exactly what the nodes said. Started with the run and
counted as an observer (the world and agents' ``observers`` parameter), it is matched with every
lockstep writer before step 0, so nothing of the run is missing.

The live view follows the run with :class:`ost_ros.lockstep.follow.RunFollower` — the world's own
bookkeeping fed the run's messages — and streams it on a Foxglove WebSocket server
(``foxglove-sdk``): ``/ost/scene`` (``foxglove.SceneUpdate``: grid, subareas, objects by state,
destinations, robots coloured by state) and ``/ost/robots`` (JSON: step, deliveries, each
robot's cell, state and load), at most ``foxglove_rate`` times a second.

Parameters: the run configuration's watch settings (:func:`ost_ros.runconfig.of_node`,
read-only): ``record`` (MCAP path; '': none), ``foxglove_port`` (0: none), ``foxglove_host``,
``foxglove_rate`` (Hz), ``exit_when_done`` (finish the file and leave ``grace`` s after the run's
result; false: stay until stopped).
"""

from __future__ import annotations

import functools
import sys
import time
from typing import Any

from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from ost_msgs_py import bag, wire
from ost_ros.lockstep.follow import FollowError, RunFollower
from ost_ros.lockstep.messages import Acted, AgentReport, Ready, RunEnd, RunInfo, Tick
from ost_ros.node import transport as tp
from ost_ros.node.params import ParameterError, declare_role
from ost_ros.node.run import run_node
from ost_ros.runconfig import WATCH
from ost_ros.world import World
from world_node.live import LiveView

FOLLOWED = {wire.type_name(c) for c in (RunInfo, Ready, Tick, Acted, RunEnd, AgentReport)}


class WatchNode(Node):
    """``<ns>/watch``: the run's recorder and live view."""

    def __init__(self):
        super().__init__("watch", namespace=tp.NAMESPACE)
        p = declare_role(self, WATCH)  # the run configuration's watch settings (ost_ros.runconfig)
        if not p["record"] and not p["foxglove_port"]:
            raise ParameterError("nothing to do: set record:=FILE.mcap and/or foxglove_port:=PORT")
        self.exit_when_done = p["exit_when_done"]
        self.grace = p["grace"]
        self.throttle = tp.Throttle(self.get_logger())
        self.writer = bag.BagWriter(p["record"]) if p["record"] else None
        self.live = (
            LiveView(p["foxglove_host"], p["foxglove_port"], p["foxglove_rate"])
            if p["foxglove_port"]
            else None
        )
        self.follower = RunFollower(on_step=self.on_step) if self.live else None
        self.subs: dict[str, Any] = {}
        self.channels: dict[str, int] = {}
        self.types: dict[str, str] = {}
        self.prefix = self.get_namespace().rstrip("/") + "/"
        self.result_at: float | None = None
        self.done = False
        self.scan()
        self.timer = self.create_timer(0.1, self.on_timer)
        what = [f"recording to {p['record']}"] if self.writer else []
        if self.live:
            what.append(f"live view on ws://{p['foxglove_host']}:{self.live.port}")
        self.get_logger().info(f"watching {self.prefix}*: " + ", ".join(what))

    # ------------------------------------------------------------------ topics

    def scan(self) -> None:
        """Subscribe to every topic of the namespace not yet taken (as ``ros2 bag record`` does)."""
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subs or not topic.startswith(self.prefix) or len(types) != 1:
                continue
            pubs = self.get_publishers_info_by_topic(topic)
            if not pubs:
                continue
            try:
                cls = bag.ros_class(types[0])
            except bag.BagError as exc:
                self.throttle.note(("type", topic), f"not recording {topic}: {exc}")
                self.subs[topic] = None
                continue
            offered = pubs[0].qos_profile
            # Discovery tells reliability and durability, not history: keep everything (a
            # recorder must not drop a sample the run depended on).
            reliable = offered.reliability == ReliabilityPolicy.RELIABLE
            qos = QoSProfile(
                history=HistoryPolicy.KEEP_ALL if reliable else HistoryPolicy.KEEP_LAST,
                depth=1000,
                reliability=offered.reliability,
                durability=offered.durability,
            )
            if self.writer is not None:
                try:
                    self.channels[topic] = self.writer.channel(topic, types[0], offered)
                except bag.BagError as exc:
                    self.throttle.note(("type", topic), f"not recording {topic}: {exc}")
                    self.subs[topic] = None
                    continue
            self.types[topic] = types[0]
            self.subs[topic] = self.create_subscription(
                cls,
                topic,
                functools.partial(self.on_sample, topic),
                qos,
                raw=True,
                event_callbacks=tp.no_events_sub(),
            )

    def on_sample(self, topic: str, data: bytes) -> None:
        now = time.time_ns()
        if self.writer is not None and not self.writer.closed:
            self.writer.write(self.channels[topic], data, now)
        type_name = self.types[topic]
        if self.follower is not None and type_name in FOLLOWED:
            self.follow(topic, type_name, data)
        if topic == self.prefix + tp.RESULT and self.result_at is None:
            self.result_at = time.monotonic()

    def follow(self, topic: str, type_name: str, data: bytes) -> None:
        assert self.follower is not None
        try:
            self.follower.feed(wire.from_cdr(type_name, data))  # (not checked: a viewer holds no key)
        except (wire.MessageError, FollowError) as exc:
            self.throttle.warn(topic, "?", str(exc))
        if self.follower.lost:
            self.throttle.note(("follow", "watch"), f"live view stopped following: {self.follower.lost}")

    def on_step(self, world: World, actions: list) -> None:
        assert self.live is not None and self.follower is not None
        self.live.step(self.follower, world, actions)

    # ------------------------------------------------------------------ end

    def on_timer(self) -> None:
        self.scan()
        if self.live is not None and self.follower is not None and self.follower.rt is not None:
            self.live.tick(self.follower, self.follower.rt.world)
        if self.result_at is not None and time.monotonic() - self.result_at >= self.grace:
            self.finish()
            if self.exit_when_done:
                self.done = True

    def finish(self) -> None:
        if self.writer is not None and not self.writer.closed:
            self.writer.close()
            self.get_logger().info(
                f"recorded {self.writer.messages} messages on {len(self.channels)} topics to {self.writer.path}"
            )

    def close(self) -> None:
        self.finish()
        if self.live is not None:
            self.live.stop()


def main(args=None) -> int:
    return run_node(
        "watch_node",
        WatchNode,
        args,
        done=lambda node: node.done,
        executor_name=lambda _node: "single",
        errors=(bag.BagError,),  # an unwritable recording
        close=lambda node: node.close(),  # the recording is closed, also when stopped
    )


if __name__ == "__main__":
    sys.exit(main())
