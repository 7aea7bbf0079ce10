"""Behaviour kept, without a barrier: a digest of every output of many seeded in-process runs.

    .venv/bin/python benchmarks/realtime_digests.py [--runs 1000] [--families agreement,remote,membership]
        [--out digests.json] [--against OTHER.json]

The runs are those of ``bench_realtime.py`` (a) — every protocol, latency and jitter up to 50,
unequal speeds, speed noise, stalls, failures —, the same with every robot's base across a
network (``--base-delay 3``: a robot decides on its own picture of its base, failures declared
late), and ``bench_membership.py`` (a) — silences, joins, kills and partitions. Each run's digest
covers the whole result and everything the realtime report says (agreement, lags, the network's
counts of marks, needs, copies and events, membership), and each robot's coordination digests.

A refactor of the realtime runtime must leave every digest unchanged: record with the code
before (``--out before.json``), then run the code after ``--against before.json`` (exit 1 and
the first runs that differ if any does). ``tests/corpus/realtime_digests.json`` keeps a few of
each family for the test suite (``tests/ost_ros/realtime/test_kept.py``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_membership
import bench_realtime

from ost_ros.realtime.net import Latency
from ost_ros.realtime.run import run_realtime

FAMILIES = ("agreement", "remote", "membership")


def case(family: str, i: int) -> tuple[Any, str, Any, dict[str, Any]]:
    """Run ``i`` of ``family``: (scenario, protocol, policy, keyword arguments of run_realtime).
    Each run draws from a generator of its own, so any run can be replayed alone."""
    if family == "membership":
        s, protocol, policy, kw = bench_membership.random_case(i)
        return s, protocol, policy, kw
    rng = np.random.default_rng([i, FAMILIES.index(family)])
    s, _label, protocol, policy, how, latency, failures, stalls, jitter = bench_realtime.random_run(rng)
    kw: dict[str, Any] = {
        "settings": how,
        "latency": latency,
        "seed": i,
        "speed_jitter": jitter,
        "stalls": stalls,
        "failures": failures,
    }
    if family == "remote":
        kw["base_delay"] = Latency(
            float(rng.choice([0.0, 0.3, 1.0, 3.0])), float(rng.choice([0.0, 0.5, 3.0]))
        )
        kw["declare_after"] = float(rng.choice([0.0, 5.0, 40.0]))
    return s, protocol, policy, kw


def _digests(ra: Any) -> dict:
    """A robot's coordination digests (kept in its record; a runtime without one kept them itself)."""
    return (ra.record if hasattr(ra, "record") else ra).digests


def digest_of(family: str, i: int) -> str:
    """The digest of run ``i`` of ``family``: its result, its report and every robot's digests."""
    s, protocol, policy, kw = case(family, i)
    agents: list = []
    try:
        r, rep = run_realtime(s, protocol, policy, prepare=agents.extend, **kw)
        out: Any = {
            "result": r.to_dict(),
            "report": rep.to_dict(),
            "labels": {str(a): v for a, v in sorted(rep.labels.items())},
            "mirror_errors": rep.mirror_errors,
            "digests": [
                [ra.id, sorted((t, d.coordination, d.input, d.output) for t, d in _digests(ra).items())]
                for ra in agents
            ],
        }
    except Exception as exc:  # a crash is an output too: the same crash before and after
        out = {"error": f"{type(exc).__name__}: {exc}"}
    return hashlib.sha256(json.dumps(out, sort_keys=True, default=repr).encode()).hexdigest()[:20]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--families", default=",".join(FAMILIES))
    ap.add_argument("--out", type=Path)
    ap.add_argument("--against", type=Path)
    a = ap.parse_args(argv)
    families = [f for f in a.families.split(",") if f]
    for f in families:
        if f not in FAMILIES:
            print(
                f"realtime_digests: error: no family {f!r} (families: {', '.join(FAMILIES)})", file=sys.stderr
            )
            return 2
    digests: dict[str, str] = {}
    t0 = time.monotonic()
    for f in families:
        for i in range(a.first, a.first + a.runs):
            digests[f"{f}/{i}"] = digest_of(f, i)
        print(f"{f}: {a.runs} runs ({time.monotonic() - t0:.0f} s so far)", file=sys.stderr)
    if a.out is not None:
        a.out.write_text(json.dumps(digests, indent=0, sort_keys=True) + "\n")
    if a.against is not None:
        want = json.loads(a.against.read_text())
        differ = [k for k in digests if k in want and want[k] != digests[k]]
        compared = sum(1 for k in digests if k in want)
        print(f"{compared} runs compared, {len(differ)} differ" + (f": {differ[:10]}" if differ else ""))
        return 1 if differ or not compared else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
