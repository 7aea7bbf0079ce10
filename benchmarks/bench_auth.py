"""The cost of signed messages per message, in-process (not a test): sealing and checking every
interface's typical message, as a ratio to converting it (``wire.to_ros``/``wire.from_ros``),
which every message pays anyway.

    .venv/bin/python benchmarks/bench_auth.py [--runs-of 2000]

Messages are taken from a real lockstep run (N=10, M=20, 100x40: ticks with observations,
actions with plans, every protocol message), so their sizes are a run's sizes.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import defaultdict

from ost_msgs_py import auth, wire
from ost_ros.coordination import CoordinationPolicy
from ost_ros.lockstep import inprocess
from ost_ros.lockstep.agent import AgentRuntime
from ost_ros.lockstep.messages import Sample
from ost_ros.model import Grid
from ost_ros.scenario import generate_scenario


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


def per_message_us(fn, items: list, runs: int) -> float:
    t0 = time.perf_counter()
    for _ in range(runs):
        for x in items:
            fn(x)
    return (time.perf_counter() - t0) / (runs * len(items)) * 1e6


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs-of", type=int, default=200, help="passes over the sampled messages")
    a = p.parse_args()
    team = auth.make_keys(tempfile.mkdtemp(prefix="bench_auth_"), range(10), run="bench")
    signer = auth.Signer(team, 0, auth.Ed25519PrivateKey.generate())
    world = auth.Signer(team, auth.WORLD, auth.Ed25519PrivateKey.generate())
    # the verifier knows these two keys
    keys = {0: signer.key.public_key(), auth.WORLD: world.key.public_key()}
    rows = []
    for name, values in sorted(sample_messages(20).items()):
        msgs = [wire.to_ros(v) for v in values]
        s = world if name in auth.WORLD_TYPES else signer
        for m in msgs:  # every message "from" the signer (the verifier's key for it)
            if hasattr(m, "sender"):
                m.sender = 0
            elif hasattr(m, "agent"):
                m.agent = 0
            elif hasattr(m, "action"):
                m.action.agent = 0
        convert = per_message_us(wire.to_ros, values, a.runs_of) + per_message_us(
            wire.from_ros, msgs, a.runs_of
        )
        seal = per_message_us(lambda m, s=s: s.seal(m, "/ost/topic"), msgs, a.runs_of)

        v = auth.Verifier(auth.Team("bench", keys))

        def check(m, v=v) -> None:
            v.windows.clear()  # the same message again is not a replay here
            assert v.check(m, "/ost/topic") is None

        for m in msgs:
            s.seal(m, "/ost/topic")
        verify = per_message_us(check, msgs, max(1, a.runs_of // 4))
        rows.append(
            {
                "interface": name,
                "bytes_signed": round(sum(len(auth.canonical(m)) for m in msgs) / len(msgs)),
                "convert_us": round(convert, 1),
                "seal_us": round(seal, 1),
                "check_us": round(verify, 1),
                "ratio_to_convert": round((seal + verify) / convert, 2),
            }
        )
        print(json.dumps(rows[-1]), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
