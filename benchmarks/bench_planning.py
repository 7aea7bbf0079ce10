"""Event skipping's cost and effect, without DDS: the world's and every agent's runtime wired in
one process (every message through the codec, as the nodes exchange them), per protocol.

    .venv/bin/python benchmarks/bench_planning.py [--quick]

Prints, per run: steps, lockstep round trips, steps the world skipped on the agents' plans, and
the CPU seconds of the whole run (world + all agents' planning and acting). The result of every
run is checked against ``ost sim`` (identical). Figures: docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import sys
import time

from ost_msgs_py.wire import round_trip
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.lockstep.inprocess import run_lockstep
from ost_ros.model import Grid
from ost_ros.scenario import generate_scenario

RUNS = [
    ("ccp", 10, 20, 1, (500, 200), 10, 1),
    ("ccp", 10, 20, 1, (500, 200), 10, 20),
    ("ncp", 10, 20, 1, (500, 200), 10, 1),
    ("hcp", 10, 20, 1, (500, 200), 10, 1),
    ("hcp", 10, 15, 2, (40, 20), 4, 1),
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the small run only")
    args = ap.parse_args()
    print("| run (seed, CI) | steps | round trips | skipped | CPU s | = ost sim |")
    print("|---|---|---|---|---|---|")
    for protocol, n, m, seed, (w, h), nmax, ci in RUNS[-1:] if args.quick else RUNS:
        scenario = generate_scenario(n, m, seed, Grid(w, h), nmax)
        policy = CoordinationPolicy(ci=ci)
        cpu = time.process_time()
        got, world = run_lockstep(scenario, protocol, policy, 64, True, carry=round_trip)
        cpu = time.process_time() - cpu
        same = got.to_dict() == simulate(scenario, protocol, policy).to_dict()
        label = f"{protocol.upper()} N={n} M={m} {w}×{h}" + (f", CI={ci}" if protocol != "hcp" else "")
        print(
            f"| {label} | {world.world.t} | {world.round_trips} | {world.skipped} | {cpu:.1f} | "
            f"{'yes' if same else 'NO'} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
