"""What a delivered sample costs a subscriber process, over DDS (not a test): the CPU of receiving,
checking, decoding and dispatching one sample into a trivial callback, against a plain rclpy
subscriber of the same samples.

    .venv/bin/python benchmarks/bench_receive.py [--samples 10000] [--kind selection] [--rate 2000]

One publisher (this process) and one subscriber process per receive path, all in one run on a
domain of their own, every subscriber getting the same samples: a CCP ``Selection`` (or an
``ObjectFound``) of a 50-robot team, sealed by agent 1 with a tag for each of the 51 members.

- ``plain``: rclpy's typed subscription (``deserialize_message`` into the generated class) and a
  trivial callback — the floor any rclpy node pays;
- ``new``: the nodes' path (``ost_ros.node.transport.subscribe``: a raw subscription, agent 3's
  tag and replay window, the direct CDR decoder, the claimed sender, the dataclass);
- ``old``: the path before (a typed subscription, every field re-encoded canonically, Ed25519
  verification with libsodium, a 65 536-bit integer window, the dataclass from the generated
  message: benchmarks/ed25519_reference.py), on an Ed25519 signature the publisher puts in the
  first 64 bytes of the tag vector (slots nobody of these three checks).

Every subscriber spins an ``EventsExecutor`` and measures its process's CPU (``time.process_time``:
every thread, DDS's included) from its first sample to its last; it prints µs per sample. The
publisher waits until every subscriber is matched (counted, never slept for), publishes at
``--rate`` samples a second, and waits for every sample to be acknowledged. Every process started
is ended, and Fast DDS's shared-memory files left in /dev/shm are removed.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

PATHS = ("plain", "new", "old")
TEAM = 50
RECEIVER = 3  # the new path's member (its slot is past the old path's signature)
SENDER = 1


def _message(kind: str, k: int, run: str):
    from ost_ros.lockstep.messages import Sample
    from ost_ros.messages import ObjectFound, ObjectInfo
    from ost_ros.protocols.ccp.messages import Selection

    if kind == "selection":  # a coordination's picks, one per round (a 50-robot team's many)
        value = Selection(SENDER, 100 + k, 7, tuple(range(k % 5, k % 5 + 12)))
    else:
        value = ObjectFound(SENDER, 100 + k, ObjectInfo(k, (k % 500, k % 200), (3, 4), 2))
    return Sample(value, 100 + k, 0, run)


def subscriber(path: str, kind: str, keys: str, samples: int, topic: str) -> None:
    import ed25519_reference as ed
    import rclpy
    from nacl.exceptions import BadSignatureError
    from rclpy.experimental import EventsExecutor

    from ost_msgs_py import auth, wire
    from ost_ros.node import transport as tp
    from ost_ros.node.signing import node_auth

    rclpy.init()
    node = rclpy.create_node(f"bench_{path}", namespace=tp.NAMESPACE)
    state = {"n": 0, "t0": 0.0, "t1": 0.0, "bad": 0}
    cls = type(_message(kind, 0, "").message)

    def count(_value=None, *_rest) -> None:
        state["n"] += 1
        if state["n"] == 1:
            state["t0"] = time.process_time()
        if state["n"] == samples:
            state["t1"] = time.process_time()

    if path == "plain":
        node.create_subscription(
            wire.ros_type(cls), topic, count, tp.LOCKSTEP_QOS, event_callbacks=tp.no_events_sub()
        )
    elif path == "new":
        guard = node_auth(keys, False, RECEIVER)
        tp.subscribe(node, cls, topic, count, tp.LOCKSTEP_QOS, guard, tp.Throttle(node.get_logger()))
    else:
        verifying = ed.signing_key().verify_key
        window = ed.BigWindow()
        full = node.resolve_topic_name(topic)

        def old(msg) -> None:
            a = msg.auth
            try:
                verifying.verify(ed.signed_bytes("bench", full, msg, a.signer, a.counter), bytes(a.tags[:64]))
            except BadSignatureError:
                state["bad"] += 1
                return
            if a.signer != auth.claimed_signer(msg) or not window.fresh(a.counter):
                state["bad"] += 1
                return
            count(wire.from_ros(msg))

        node.create_subscription(
            wire.ros_type(cls), topic, old, tp.LOCKSTEP_QOS, event_callbacks=tp.no_events_sub()
        )
    ex = EventsExecutor()
    ex.add_node(node)
    print(f"{path}: up", file=sys.stderr, flush=True)
    end = time.monotonic() + 600
    while state["n"] < samples and time.monotonic() < end:
        ex.spin_once(timeout_sec=0.5)
    cpu = (state["t1"] - state["t0"]) / max(1, samples - 1) * 1e6
    print(
        json.dumps({"path": path, "samples": state["n"], "dropped": state["bad"], "cpu_us": round(cpu, 2)}),
        flush=True,
    )
    os._exit(0)  # (rcl's teardown now and then hangs: ost_ros/node/run.py)


def publish(kind: str, keys: str, samples: int, rate: float, topic: str, readers: int) -> float:
    """Publishes the samples once ``readers`` are matched; the wall seconds it took."""
    import ed25519_reference as ed
    import rclpy
    from rclpy.duration import Duration
    from rclpy.serialization import deserialize_message

    from ost_msgs_py import wire
    from ost_ros.node import transport as tp
    from ost_ros.node.signing import node_auth

    rclpy.init()
    node = rclpy.create_node("bench_publisher", namespace=tp.NAMESPACE)
    guard = node_auth(keys, False, SENDER)
    cls = type(_message(kind, 0, "").message)
    pub = node.create_publisher(wire.ros_type(cls), topic, tp.LOCKSTEP_QOS)
    while pub.get_subscription_count() < readers:
        rclpy.spin_once(node, timeout_sec=0.05)
    signing = ed.signing_key()
    full = pub.topic_name
    t0 = time.monotonic()
    for k in range(samples):
        data = bytearray(guard.encode(pub, _message(kind, k, "bench")))
        msg = deserialize_message(bytes(data), wire.ros_type(cls))  # what the old path re-encodes
        sig = signing.sign(ed.signed_bytes("bench", full, msg, msg.auth.signer, msg.auth.counter)).signature
        start = len(data) - guard.sealer.size  # type: ignore[union-attr]
        data[start : start + 64] = sig  # the world's, agent 0's, 1's and 2's slots; agent 3's untouched
        pub.publish(bytes(data))
        due = t0 + (k + 1) / rate
        while time.monotonic() < due:
            rclpy.spin_once(node, timeout_sec=max(0.0, due - time.monotonic()))
    wall = time.monotonic() - t0
    pub.wait_for_all_acked(Duration(seconds=60))
    node.destroy_node()
    rclpy.try_shutdown()
    return wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=10000)
    ap.add_argument("--kind", choices=("selection", "object_found"), default="selection")
    ap.add_argument("--rate", type=float, default=2000.0, help="samples a second")
    ap.add_argument("--paths", nargs="+", choices=PATHS, default=list(PATHS))
    ap.add_argument("--json", action="store_true")
    # a subscriber's role (internal)
    ap.add_argument("--role", choices=PATHS, help=argparse.SUPPRESS)
    ap.add_argument("--keys", help=argparse.SUPPRESS)
    a = ap.parse_args()
    topic = "selection" if a.kind == "selection" else "object_found"
    if a.role:
        subscriber(a.role, a.kind, a.keys, a.samples, topic)
        return 0

    from bench_floor import _env

    from ost_msgs_py import auth

    sys.path.insert(0, str(REPO / "tests/ros"))
    from dds_helpers import release_domain

    env = _env()  # dds_env.sh's, and a domain of its own
    os.environ.update(env)
    keys_dir = tempfile.TemporaryDirectory(prefix="bench_receive_")  # removed at the end
    keys = keys_dir.name
    auth.make_keys(keys, range(TEAM), run="bench")
    shm_before = set(os.listdir("/dev/shm"))
    load = os.getloadavg()[0]
    me = [sys.executable, __file__, "--kind", a.kind, "--samples", str(a.samples), "--keys", keys]
    procs = {
        p: subprocess.Popen([*me, "--role", p], env=env, stdout=subprocess.PIPE, text=True) for p in a.paths
    }
    try:
        wall = publish(a.kind, keys, a.samples, a.rate, topic, len(procs))
        rows = {}
        for p, proc in procs.items():
            out, _ = proc.communicate(timeout=120)
            rows[p] = json.loads(out.strip().splitlines()[-1])
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        release_domain(int(env["ROS_DOMAIN_ID"]))
        keys_dir.cleanup()
        for f in set(os.listdir("/dev/shm")) - shm_before:
            if f.startswith(("fastrtps_", "sem.fastrtps_", "fast_datasharing")):
                with contextlib.suppress(OSError):
                    os.unlink(f"/dev/shm/{f}")
    plain = rows.get("plain", {}).get("cpu_us")
    for r in rows.values():
        r["vs_plain"] = round(r["cpu_us"] / plain, 2) if plain else None
    summary = {
        "kind": a.kind,
        "samples": a.samples,
        "rate": a.rate,
        "publish_s": round(wall, 1),
        "load": load,
    }
    if a.json:
        print(json.dumps({**summary, "paths": rows}))
        return 0
    print(json.dumps(summary))
    print("| path | samples | dropped | CPU per sample | × plain |")
    print("|---|---|---|---|---|")
    for p, r in rows.items():
        print(f"| {p} | {r['samples']} | {r['dropped']} | {r['cpu_us']:.1f} µs | {r['vs_plain']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
