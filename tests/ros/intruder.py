"""A foreign process on a run's domain, attacking it as a stranger can (tests/ros/test_secure.py).

    python tests/ros/intruder.py --agents 0,1,2 --protocol ccp --stolen-key DIR/agent_1.key --team DIR

It learns the run id and scenario fingerprint from the world's public ``run_info``, then until
the result appears it publishes, on every topic of the run, well-formed messages of that topic's
type, in five ways: unsealed (an empty tag vector); sealed with a key of its own as the sender
it claims; with one robot's real key (``--stolen-key``: agent 1's) as agent 1 but claiming to be
another robot or the world; with that key in another member's name C for every other receiver B
— the keys agent 1 shares with B are not C's, so B must refuse it (agent 1's own slot is left
empty: there the key does work, what MACs give up — tests/ost_msgs_py/test_auth.py); and with that
key for another run. It also captures the run's messages (the bytes, all but its own) and
publishes them again, on their own topic (replays) and a tick on another robot's tick topic.
Prints a JSON count of what it sent, by kind of attack.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

import rclpy
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey
from rclpy.node import Node
from std_msgs.msg import String

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ost_msgs_py import auth, wire
from ost_ros import protocols
from ost_ros.lockstep.messages import Acted, AgentReport, Ready, Resend, RunEnd, RunInfo, Sample, Tick
from ost_ros.messages import Action, ActionKind, ObjectFound, ObjectInfo, Observation, SearchDone, Status
from ost_ros.node import transport as tp
from ost_ros.protocols.ccp.messages import ScheduleUpdate, Selection


def forged_messages(
    run: str, fingerprint: str, ids: list[int], protocol: str, t: int
) -> list[tuple[str, object]]:
    """(topic, dataclass) of every kind the run has: what a stranger would send."""
    victim, other = ids[1], ids[2]
    obj = ObjectInfo(99, (1, 1), (2, 2), 1)
    kinds = {
        ObjectFound: ObjectFound(other, t, obj),
        SearchDone: SearchDone(victim, t),
        Selection: Selection(other, t, 0, (99,)),
        Status: Status(victim, t, t + 1, (1, 1)),
        ScheduleUpdate: ScheduleUpdate(victim, t, 0, ()),
    }
    out: list[tuple[str, object]] = [
        (tp.ACTED, Acted(Action(victim, t, ActionKind.WAIT), 0, run=run)),
        (tp.READY, Ready(other, protocol, fingerprint)),
        (tp.REPORTS, AgentReport(victim, protocol, "ci=1", None, 0, (), (), (), 0, run=run)),
        (tp.RESEND, Resend(victim, t, (ids[0],), run)),
        (tp.RUN_END, RunEnd(t + 1, t, True, run=run)),
        (tp.RUN_INFO, RunInfo(run, "", fingerprint, True, 0)),
    ]
    out += [(tp.tick_topic(i), Tick(t + 1, t, Observation(i, t + 1, (0, 0)), run=run)) for i in ids]
    for kind in protocols.get(protocol).messages:
        if kind in kinds:
            out.append((tp.message_topic(kind), Sample(kinds[kind], t, 0, run)))
    return out


def sealed(keys: auth.Keys, value: object, topic: str, receivers=None) -> bytes:
    s = auth.Sealer(keys)
    data = wire.to_cdr(value, counter=s.next(), signer=s.signer, tags=s.size)
    s.seal(data, topic, receivers)
    return bytes(data)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--agents", required=True)
    ap.add_argument("--protocol", default="ccp")
    ap.add_argument("--stolen-key", required=True)
    ap.add_argument("--team", required=True, help="the run's public team.yaml directory (public)")
    ap.add_argument("--seconds", type=float, default=120)
    args = ap.parse_args()
    ids = [int(x) for x in args.agents.split(",")]
    stolen = serialization.load_pem_private_key(Path(args.stolen_key).read_bytes(), password=None)
    assert isinstance(stolen, X25519PrivateKey)
    own = X25519PrivateKey.generate()
    thief = ids[1]  # whose key was stolen: it may not speak for anyone else
    team = auth.load_team(args.team)
    # Pairwise keys it can compute: its own key's with the team, the stolen key's (as the thief,
    # as each other member, and for another run).
    as_itself = auth.Keys(team, thief, stolen)
    own_keys = {m: auth.Keys(team, m, own) for m in team.members}
    in_name_of = {m: auth.Keys(team, m, stolen) for m in team.members}
    other_run = auth.Keys(auth.Team("another" + team.run, team.keys), thief, stolen)
    not_thief = [m for m in team.members if m != thief]

    rclpy.init()
    node = Node("intruder", namespace=tp.NAMESPACE)
    q = tp.LOCKSTEP_QOS
    latched = tp.LATCHED_ALL_QOS
    info: list[RunInfo] = []
    done: list = []
    mine: set[bytes] = set()  # what it published itself (its subscriptions hear it too)
    captured: dict[str, list[bytes]] = {}
    types = {
        tp.ACTED: (Acted, q),
        tp.READY: (Ready, latched),
        tp.REPORTS: (AgentReport, latched),
        tp.RESEND: (Resend, q),
        tp.RUN_END: (RunEnd, latched),
        tp.RUN_INFO: (RunInfo, latched),
        **{tp.tick_topic(i): (Tick, q) for i in ids},
        **{tp.message_topic(k): (k, q) for k in protocols.get(args.protocol).messages},
    }
    pubs, subs = {}, []
    for topic, (cls, qos) in types.items():
        ros_type = wire.ros_type(cls)
        pubs[topic] = node.create_publisher(ros_type, topic, qos)

        def keep(data: bytes, topic=topic) -> None:
            if topic == tp.RUN_INFO and not info:
                info.append(wire.from_cdr(RunInfo, data))  # (read, not checked: it has no key of the world's)
            if data not in mine:
                captured.setdefault(topic, []).append(data)

        subs.append(node.create_subscription(ros_type, topic, keep, qos, raw=True))
    subs.append(node.create_subscription(String, tp.RESULT, lambda m: done.append(m), tp.RESULT_QOS))

    sent: Counter[str] = Counter()
    end = time.monotonic() + args.seconds
    while not info and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.1)
    if not info:
        print("intruder: no run_info", file=sys.stderr)
        return 1
    run, fingerprint = info[0].run, info[0].fingerprint
    # every reader of the run (the world's, the agents') matched to this process first
    want = {tp.ACTED: 1, tp.READY: 1, tp.REPORTS: 1, **{tp.tick_topic(i): 1 for i in ids[:2]}}
    while any(pubs[t].get_subscription_count() < n + 1 for t, n in want.items()) and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    print(f"intruder: matched; run {run}", file=sys.stderr, flush=True)
    replayed: dict[str, int] = {}

    def publish(pub, data: bytes, how: str) -> None:
        mine.add(data)
        try:
            pub.publish(data)
            sent[how] += 1
        except RuntimeError:  # (RCLError) a keep-all writer whose readers lag: DDS refuses
            sent["refused by DDS"] += 1

    t = 0
    while not done and time.monotonic() < end:
        t += 1
        for topic, value in forged_messages(run, fingerprint, ids, args.protocol, t):
            pub = pubs[topic]
            full = pub.topic_name
            claimed = auth.claimed_signer(wire.to_ros(value))
            assert claimed is not None
            publish(pub, bytes(wire.to_cdr(value)), "unsigned")
            publish(pub, sealed(own_keys[claimed], value, full), "own key")  # as the sender it claims
            if claimed != thief:
                # the stolen key as itself, claiming another robot or the world
                publish(pub, sealed(as_itself, value, full), "stolen key, own id")
                # ... in the claimed member's name, to every receiver but itself
                publish(pub, sealed(in_name_of[claimed], value, full, not_thief), "stolen key, other id")
                publish(pub, sealed(other_run, value, full), "stolen key, other run")
        # genuine messages again: on their own topic, and a tick on another robot's tick topic
        for topic, msgs in list(captured.items()):
            for data in msgs[replayed.get(topic, 0) :]:
                publish(pubs[topic], data, "replay")
                if topic.endswith("/tick"):
                    agent = wire.decode(Tick, data)[0].observation.agent
                    other = tp.tick_topic(ids[(ids.index(agent) + 1) % len(ids)])
                    publish(pubs[other], data, "replay, other topic")
            replayed[topic] = len(msgs)
        end_spin = time.monotonic() + 0.1
        while time.monotonic() < end_spin:
            rclpy.spin_once(node, timeout_sec=0.02)
    for pub in pubs.values():
        pub.wait_for_all_acked(rclpy.duration.Duration(seconds=5))
    print(json.dumps(dict(sent)), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
