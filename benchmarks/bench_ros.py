"""Wall time, peak memory and DDS traffic of runs over DDS, next to ``ost sim`` (not a test).

    .venv/bin/python benchmarks/bench_ros.py --agents 10 20 --objects 20 --skip on off
    .venv/bin/python benchmarks/bench_ros.py --agents 10 --objects 20 --skip on --auth secure insecure

For each (N, M, skipping): generates the paper's scenario (seed 1, 500x200 unless --width/--height),
runs ``bringup_scripts/ost_up.sh --json`` and ``simulate`` in-process, checks the results are
identical and prints: wall time (bring-up included), summed peak RSS of all node processes
(from /proc status VmHWM, sampled), round trips, skipped steps, protocol messages, and the DDS
samples published (ticks + acted per round trip; one sample per protocol message, on its kind's topic).
``--auth secure insecure`` runs each case both ways (signed messages, the default, and
``ost_up.sh --insecure``), interleaved: the signing overhead; ``--executor events single`` the
same for the nodes' executor.

``--floor`` also measures the transport's floor at each N in the same run
(``bench_floor.py``: plain rclpy, EventsExecutor, star and all-to-all) and prints our median
quiet round trip, round trip with protocol messages and bring-up as ratios to it, with the
machine's load.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
import bench_floor  # noqa: E402  (the floor, measured in the same run)


def peak_rss_mb(run_dir: Path) -> float:
    total = 0
    for pid_file in run_dir.glob("*.pid"):
        if pid_file.name == "ost_up.pid":
            continue
        try:
            status = Path(f"/proc/{pid_file.read_text().strip()}/status").read_text()
        except OSError:
            continue
        for line in status.splitlines():
            if line.startswith("VmHWM:"):
                total += int(line.split()[1])
    return total / 1024


def bench(
    n: int,
    m: int,
    skip: bool,
    width: int,
    height: int,
    tmp: Path,
    secure: bool = True,
    executor: str = "events",
) -> dict:
    scenario = generate_scenario(n, m, 1, Grid(width, height))
    path = tmp / f"s_{n}_{m}.yaml"
    path.write_text(dump_scenario(scenario))
    t0 = time.perf_counter()
    ref = simulate(scenario, "ccp", CoordinationPolicy()).to_dict()
    sim_s = time.perf_counter() - t0
    ref["lower_bound"] = lower_bound(scenario).value  # `ost sim` and the world node print it
    run_dir = tmp / f"run_{n}_{m}_{int(skip)}_{'secure' if secure else 'insecure'}_{executor}"
    args = (
        [
            "bash",
            str(REPO / "bringup_scripts/ost_up.sh"),
            "--scenario",
            str(path),
            "--json",
            "--run-dir",
            str(run_dir),
            "--executor",
            executor,
        ]
        + ([] if skip else ["--no-skip"])
        + ([] if secure else ["--insecure"])
    )
    t0 = time.perf_counter()
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak = 0.0
    while proc.poll() is None:  # sample the processes' high-water marks while they live
        peak = max(peak, peak_rss_mb(run_dir))
        time.sleep(0.5)
    out, err = proc.communicate()
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return {"N": n, "M": m, "skip": skip, "secure": secure, "error": err.strip().splitlines()[-1:]}
    stats = json.loads((run_dir / "result.json.transport.json").read_text())
    same = json.loads(out) == ref
    dds = stats["round_trips"] * 2 * n
    rt = stats.get("round_trip_ms", {})
    return {
        "N": n,
        "M": m,
        "skip": skip,
        "executor": executor,
        "secure": stats.get("auth", {}).get("secure", False),
        "identical": same,
        "wall_s": round(wall, 1),
        "run_s": stats["wall_s"],
        "peak_rss_mb": round(peak),
        "steps": stats["steps"],
        "round_trips": stats["round_trips"],
        "skipped": stats["skipped_steps"],
        "protocol_messages": stats["protocol_messages"],
        "dds_samples_lockstep": dds,
        "dds_samples_protocol": stats["protocol_messages"],  # one per message (each to N readers)
        "sim_s": round(sim_s, 2),
        "round_trip_quiet_ms": rt.get("quiet", {}).get("median"),
        "round_trip_messages_ms": rt.get("messages", {}).get("median"),
        "bring_up_s": stats.get("bring_up_s"),
        # the rest of the wall time: ost_up.sh's preparation before launch, the exit after the result
        "outside_s": round(wall - stats["wall_s"] - (stats.get("bring_up_s") or 0), 1),
        "load": round(os.getloadavg()[0], 2),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--agents", type=int, nargs="+", default=[10, 20, 50])
    p.add_argument("--objects", type=int, nargs="+", default=[20, 200])
    p.add_argument("--skip", choices=("on", "off"), nargs="+", default=["on", "off"])
    p.add_argument("--width", type=int, default=500)
    p.add_argument("--height", type=int, default=200)
    p.add_argument("--auth", choices=("secure", "insecure"), nargs="+", default=["secure"])
    p.add_argument("--executor", choices=("events", "single"), nargs="+", default=["events"])
    p.add_argument("--repeat", type=int, default=1, help="runs of each case (interleaved)")
    p.add_argument("--floor", action="store_true", help="also the floor at each N, and the ratios")
    p.add_argument("--floor-rounds", type=int, default=200)
    a = p.parse_args()
    tmp = Path(os.environ.get("TMPDIR", "/tmp")) / f"bench_ros_{os.getpid()}"
    tmp.mkdir(parents=True, exist_ok=True)
    for n in a.agents:
        floor = {}
        if a.floor:
            for pattern in ("star", "all"):
                floor[pattern] = bench_floor.measure(n, a.floor_rounds, pattern, "events")
                print(json.dumps({"floor": floor[pattern]}), flush=True)
        for m in a.objects:
            for s in a.skip:
                for _ in range(a.repeat):
                    for auth in a.auth:
                        for ex in a.executor:
                            row = bench(n, m, s == "on", a.width, a.height, tmp, auth == "secure", ex)
                            if floor and "error" not in row:
                                row["ratios"] = ratios(row, floor)
                            print(json.dumps(row), flush=True)
    return 0


def ratios(row: dict, floor: dict) -> dict:
    """Our round trips and bring-up over the floor's at the same N (None where not measured)."""

    def r(a, b):
        return None if a is None or not b else round(a / b, 2)

    return {
        "quiet_vs_star": r(row["round_trip_quiet_ms"], floor["star"]["median_ms"]),
        "messages_vs_all": r(row["round_trip_messages_ms"], floor["all"]["median_ms"]),
        "bring_up_vs_floor": r(row["bring_up_s"], min(f["bring_up_s"] for f in floor.values())),
    }


if __name__ == "__main__":
    sys.exit(main())
