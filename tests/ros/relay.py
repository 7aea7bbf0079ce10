"""A dead robot's message relayed by another process, byte for byte, over DDS (tests/ros/test_secure.py).

    python tests/ros/relay.py speak --keys DIR --agent 2    # seal one Selection as agent 2, publish, exit
    python tests/ros/relay.py relay --readers 3             # keep the first sample heard; once its
                                                            # speaker is gone and 3 readers are matched,
                                                            # publish it again (and an altered copy)
    python tests/ros/relay.py listen --keys DIR --agent 0   # say what it accepts and drops, until both came

Each role waits for the endpoints it needs by counting them, never by sleeping.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import rclpy
from rclpy.duration import Duration
from rclpy.node import Node

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ost_msgs_py import wire
from ost_ros.lockstep.messages import Sample
from ost_ros.node import transport as tp
from ost_ros.node.signing import NodeAuth, node_auth
from ost_ros.protocols.ccp.messages import Selection

TOPIC = tp.message_topic(Selection)


def spin_until(node: Node, done, seconds: float = 60) -> bool:
    end = time.monotonic() + seconds
    while not done() and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    return bool(done())


def speak(node: Node, guard: NodeAuth, agent: int) -> int:
    pub = node.create_publisher(wire.ros_type(Selection), TOPIC, tp.LOCKSTEP_QOS)
    if not spin_until(node, lambda: pub.get_subscription_count() >= 1):
        return 1
    guard.publish(pub, Sample(Selection(agent, 5, 7, (3, 1)), 5, 0, guard.run or ""))
    pub.wait_for_all_acked(Duration(seconds=10))
    print(f"speaker: sealed as agent {agent} and gone", flush=True)
    return 0


def relay(node: Node, readers: int) -> int:
    kept: list[bytes] = []
    sub = node.create_subscription(
        wire.ros_type(Selection), TOPIC, lambda data: kept.append(data), tp.LOCKSTEP_QOS, raw=True
    )
    pub = node.create_publisher(wire.ros_type(Selection), TOPIC, tp.LOCKSTEP_QOS)
    if not spin_until(node, lambda: kept):
        return 1
    print(f"relay: kept {len(kept[0])} bytes", flush=True)
    # the speaker gone (only this process's own writer left), the receivers there (+ its own reader)
    if not spin_until(
        node, lambda: sub.get_publisher_count() <= 1 and pub.get_subscription_count() >= readers + 1
    ):
        return 1
    guard = NodeAuth()  # no keys: a relay needs none
    altered = bytearray(kept[0])
    altered[20] ^= 1
    guard.relay(pub, kept[0])
    guard.relay(pub, bytes(altered))
    pub.wait_for_all_acked(Duration(seconds=10))
    print("relay: relayed", flush=True)
    return 0


def listen(node: Node, guard: NodeAuth) -> int:
    heard: list[Sample] = []
    tp.subscribe(node, Selection, TOPIC, heard.append, tp.LOCKSTEP_QOS, guard, tp.Throttle(node.get_logger()))
    print("listener: up", flush=True)
    if not spin_until(node, lambda: heard and guard.counts()["forged"]):
        return 1
    s = heard[0]
    print(
        f"listener: accepted {s.message.TYPE} {s.message.coordination} from agent {s.message.sender}",
        flush=True,
    )
    return 0


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("role", choices=("speak", "relay", "listen"))
    ap.add_argument("--keys")
    ap.add_argument("--agent", type=int)
    ap.add_argument("--readers", type=int, default=1)
    args = ap.parse_args()
    rclpy.init()
    node = Node(
        f"{args.role}_{args.agent if args.agent is not None else 'x'}".replace("-", "m"),
        namespace=tp.NAMESPACE,
    )
    try:
        if args.role == "relay":
            return relay(node, args.readers)
        guard = node_auth(args.keys, False, args.agent)
        return speak(node, guard, args.agent) if args.role == "speak" else listen(node, guard)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
