"""Time ``ost reproduce`` (quick and full) and the event engine against the step engine.

    .venv/bin/python benchmarks/bench_reproduce.py [--skip-full] [--skip-engines]

Targets (issue [repro]): --quick under 20 s, the full study under 120 s on a 2-core machine.
Prints wall time, the workers' CPU seconds and the load average (a busy shared machine inflates
wall time; CPU seconds / cores is what an idle machine would take). Output goes to /tmp.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate, simulate_events
from ost_ros.scenario import generate_scenario


def reproduce(quick: bool) -> None:
    with tempfile.TemporaryDirectory(prefix="ost_bench_") as out:
        cmd = [sys.executable, "-m", "ost_ros", "reproduce", "--out", out, "--no-progress"]
        t0 = time.perf_counter()
        r = subprocess.run(cmd + (["--quick"] if quick else []), capture_output=True, text=True, check=True)
        wall = time.perf_counter() - t0
    target = 20 if quick else 120
    print(
        f"reproduce {'--quick' if quick else '(full)'}: {wall:.1f} s end to end "
        f"(target < {target} s: {'met' if wall < target else 'MISSED'}); {r.stderr.strip()}"
    )


def engines() -> None:
    for n, m, proto, policy in (
        (10, 50, "ccp", CoordinationPolicy(ci=1)),
        (50, 50, "ccp", CoordinationPolicy(ci=50)),
        (10, 50, "hcp", CoordinationPolicy()),
        (50, 50, "hcp", CoordinationPolicy()),
    ):
        s = generate_scenario(n, m, 1)
        t0 = time.perf_counter()
        a = simulate(s, proto, policy)
        t1 = time.perf_counter()
        b = simulate_events(s, proto, policy)
        t2 = time.perf_counter()
        same = a.to_dict() == b.to_dict()
        print(
            f"{proto} N={n} M={m} makespan {a.makespan}: step {t1 - t0:.2f} s, event "
            f"{t2 - t1:.3f} s ({(t1 - t0) / (t2 - t1):.0f}x), identical: {same}"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--skip-full", action="store_true")
    p.add_argument("--skip-engines", action="store_true")
    a = p.parse_args()
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    if not a.skip_engines:
        engines()
    reproduce(quick=True)
    if not a.skip_full:
        reproduce(quick=False)


if __name__ == "__main__":
    main()
