"""What authenticating a message costs, in-process (not a test): the receiver-specific MACs of
``ost_msgs_py/auth.py`` against the Ed25519 signatures they replaced, on the same bytes, in the
same run; and decoding, this repository's CDR codec against rclpy's.

    .venv/bin/python benchmarks/bench_auth.py [--runs-of 200] [--team 50] [--json]

Messages are taken from a real lockstep run (N=10, M=20, 100x40: ticks with observations,
actions with plans, every protocol message) and encoded as the nodes send them, with a tag
vector for a team of ``--team`` agents and the world (51 slots by default). Per interface:

- ``tags_us``: the sender — the digest of the message and a tag for every member (precomputed
  keyed BLAKE2b states, copied per tag); ``sign_us``: one Ed25519 signature of the same bytes
  (libsodium through PyNaCl, the faster of the two Python bindings here);
- ``check_us``: one receiver — its tag (the digest and one keyed BLAKE2b) and its replay window;
  ``verify_us``: one Ed25519 verification of the same bytes; ``old_check_us``: what a receiver
  did before, re-encoding every field canonically, verifying, shifting a 65 536-bit integer
  window (benchmarks/ed25519_reference.py);
- ``decode_us``: the bytes to the message dataclass here (``wire.from_cdr``); ``rclpy_us``:
  ``deserialize_message`` into the generated class and the conversion from it.

And once: a tag with a copied keyed state against keying BLAKE2b afresh (the design's choice),
and deriving one pairwise key (X25519 and the KDF) at start.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from rclpy.serialization import deserialize_message

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ed25519_reference as ed

from ost_msgs_py import auth, wire
from ost_ros.coordination import CoordinationPolicy
from ost_ros.lockstep import inprocess
from ost_ros.lockstep.agent import AgentRuntime
from ost_ros.lockstep.messages import Sample
from ost_ros.model import Grid
from ost_ros.scenario import generate_scenario

TOPIC = "/ost/topic"


def sample_messages(per_type: int) -> dict[str, list]:
    """Up to ``per_type`` messages of each interface from one in-process lockstep run."""
    seen: dict[str, list] = defaultdict(list)

    def tap(value) -> None:
        name = type(value.message if hasattr(value, "message") else value).__name__
        if len(seen[name]) < per_type:
            seen[name].append(value)

    progress = AgentRuntime.progress

    def tapped(self):  # the agents' samples too (the tap sees what the world sends and takes)
        out = progress(self)
        for m in out:
            if isinstance(m, Sample):
                tap(m)
        return out

    AgentRuntime.progress = tapped  # type: ignore[method-assign]
    try:
        scenario = generate_scenario(10, 20, 1, Grid(100, 40))
        inprocess.run_lockstep(
            scenario, "ccp", CoordinationPolicy(), 64, True, tap=tap, carry=wire.round_trip
        )
    finally:
        AgentRuntime.progress = progress  # type: ignore[method-assign]
    return seen


def per_item_us(fn, items: list, runs: int) -> float:
    """Median over 5 rounds of the µs per call of ``fn`` over ``items``."""
    rounds = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(runs):
            for x in items:
                fn(x)
        rounds.append((time.perf_counter() - t0) / (runs * len(items)) * 1e6)
    return statistics.median(rounds)


def signer_of(value) -> int:
    msg = value.message if isinstance(value, Sample) else value
    name = type(msg).__name__
    return auth.WORLD if name in auth.WORLD_TYPES else 0


def measure(name: str, values: list, keys: dict[int, auth.Keys], signing, runs: int) -> dict:
    """One interface's row (see the module docstring)."""
    signer = signer_of(values[0])
    sealer = auth.Sealer(keys[signer])
    receiver = auth.Checker(keys[1])  # agent 1 receives
    kind = type(values[0].message) if isinstance(values[0], Sample) else type(values[0])
    ros_type = wire.ros_type(kind)
    datas = []
    for v in values:
        data = wire.to_cdr(v, counter=sealer.next(), signer=signer, tags=sealer.size)
        sealer.seal(data, TOPIC)
        datas.append(bytes(data))
    bodies = [x[: -sealer.size] for x in datas]
    sigs = {b: signing.sign(b).signature for b in bodies}
    generated = [deserialize_message(x, ros_type) for x in datas]
    old_sigs = {
        id(m): signing.sign(ed.signed_bytes("bench", TOPIC, m, signer, 7)).signature for m in generated
    }
    verifying = signing.verify_key
    counters = iter(range(1, 10**12))
    window = ed.BigWindow()

    def tags(data: bytes) -> None:
        sealer.seal(bytearray(data), TOPIC)

    def check(data: bytes) -> None:
        assert receiver.check(data, TOPIC) is None
        receiver.fresh(signer, next(counters))  # the window, with counters that are new

    def verify(body: bytes) -> None:
        verifying.verify(body, sigs[body])

    def old_check(m) -> None:
        verifying.verify(ed.signed_bytes("bench", TOPIC, m, signer, 7), old_sigs[id(m)])
        window.fresh(next(counters))

    slow = max(1, runs // 4)
    row = {
        "interface": name,
        "bytes": round(statistics.mean(len(x) for x in datas)),
        "tags_us": per_item_us(tags, datas, runs),
        "sign_us": per_item_us(signing.sign, bodies, runs),
        "check_us": per_item_us(check, datas, runs),
        "verify_us": per_item_us(verify, bodies, slow),
        "old_check_us": per_item_us(old_check, generated, slow),
        "decode_us": per_item_us(lambda x: wire.from_cdr(kind, x), datas, runs),
        "rclpy_us": per_item_us(lambda x: wire.from_ros(deserialize_message(x, ros_type)), datas, slow),
    }
    return {k: round(v, 2) if isinstance(v, float) else v for k, v in row.items()}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs-of", type=int, default=200, help="passes over the sampled messages")
    p.add_argument("--team", type=int, default=50, help="agents in the team (tags: this + 1)")
    p.add_argument("--json", action="store_true", help="rows as JSON lines")
    a = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_auth_") as d:
        team = auth.make_keys(d, range(a.team), run="bench")
        keys = {m: auth.Keys(team, m, auth.load_private(d, m)) for m in (auth.WORLD, 0, 1)}
    signing = ed.signing_key()
    rows = [measure(n, v, keys, signing, a.runs_of) for n, v in sorted(sample_messages(20).items())]
    summary = once(team, a.runs_of)
    if a.json:
        for row in rows:
            print(json.dumps(row))
        print(json.dumps(summary))
        return 0
    cols = list(rows[0])
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for row in rows:
        print("| " + " | ".join(str(row[c]) for c in cols) + " |")
    print(json.dumps(summary))
    return 0


def once(team: auth.Team, runs: int) -> dict:
    d = hashlib.blake2b(b"x" * 200, digest_size=32).digest()
    key = bytes(32)
    state = hashlib.blake2b(key=key, digest_size=auth.TAG)

    def copied(_: int) -> None:
        t = state.copy()
        t.update(d)
        t.digest()

    def fresh(_: int) -> None:
        hashlib.blake2b(d, key=key, digest_size=auth.TAG).digest()

    n = list(range(1000))
    private = auth.X25519PrivateKey.generate()
    peer = team.keys[0]
    return {
        "tag_copied_state_us": round(per_item_us(copied, n, runs // 10 or 1), 3),
        "tag_keyed_afresh_us": round(per_item_us(fresh, n, runs // 10 or 1), 3),
        "pair_key_us": round(
            per_item_us(lambda _: auth.pair_key(private.exchange(peer), "bench", 0, 1), n[:100], 2), 1
        ),
        "members": len(team.members),
    }


if __name__ == "__main__":
    sys.exit(main())
