"""A realtime team's bring-up and idle floor over DDS (not a test):

    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_idle.py [--agents 50] [--objects 200]
        [--seconds 30] [--runs 1] [--up-args '--failure-timeout 0'] [--json]

Starts ``ost up --realtime --rtf 0.01 --background`` (a team that stands still: 30 s of wall are
0.3 steps) on the paper's largest scenario, and reads:

- **bring-up**: wall seconds from the start of ``ost up`` to every robot ready (the world's ready
  file, ``bring_up_s``), and to ``ost up`` returning (the run started);
- **idle floor**: the CPU of the world process and of each agent process over ``--seconds`` of
  wall once the run started (``/proc/<pid>/stat``: user + system, every thread: rclpy's and
  Fast DDS's), as cores (CPU seconds per wall second).

Prints one line per run, then the medians (``--json``: the rows as JSON).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

OST = str(Path(sys.executable).parent / "ost")
TICKS = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process (all its threads) so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def one_run(args: argparse.Namespace, scenario: Path, env: dict[str, str]) -> dict:
    with tempfile.TemporaryDirectory(prefix="ost_bench_idle.") as tmp:
        run_dir = Path(tmp) / "run"
        log = open(Path(tmp) / "ost_up.err", "w+")  # noqa: SIM115 (read back below)
        t0 = time.monotonic()
        up = subprocess.run(
            [
                OST,
                "up",
                "--scenario",
                str(scenario),
                "--realtime",
                "--rtf",
                "0.01",
                "--background",
                "--run-dir",
                str(run_dir),
                *args.up_args.split(),
            ],
            env=env,
            # files, not pipes: the supervisor ost up leaves behind holds them for the whole run
            stdout=subprocess.DEVNULL,
            stderr=log,
            timeout=300,
        )
        started_s = time.monotonic() - t0
        try:
            if up.returncode != 0:
                log.seek(0)
                raise SystemExit(f"bench_idle: ost up failed:\n{log.read()[-2000:]}")
            ready = float((run_dir / "ready").read_text().split()[0])
            pids = {
                f.stem: int(f.read_text().split()[0]) for f in run_dir.glob("*.pid") if f.stem != "ost_up"
            }
            before = {name: cpu_s(pid) for name, pid in pids.items()}
            time.sleep(args.seconds)
            cores = {name: (cpu_s(pid) - before[name]) / args.seconds for name, pid in pids.items()}
        finally:
            subprocess.run([OST, "up", "--down", str(run_dir)], env=env, capture_output=True, timeout=120)
            log.close()
    world = [c for name, c in cores.items() if not name.startswith("agent")]
    agents = sorted(c for name, c in cores.items() if name.startswith("agent"))
    return {
        "agents": args.agents,
        "ready_s": ready,
        "started_s": round(started_s, 2),
        "world_core": round(sum(world), 4),
        "agent_core_median": round(statistics.median(agents), 4),
        "agent_core_max": round(agents[-1], 4),
        "total_core": round(sum(cores.values()), 3),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, default=50)
    ap.add_argument("--objects", type=int, default=200)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--up-args", default="", help="more options for ost up (e.g. '--failure-timeout 0')")
    args = ap.parse_args()
    env = dict(os.environ)  # ost up picks a free ROS_DOMAIN_ID and the localhost profile
    rows = []
    with tempfile.TemporaryDirectory(prefix="ost_bench_idle.") as tmp:
        scenario = Path(tmp) / "s.yaml"
        subprocess.run(
            [
                OST,
                "generate",
                "--agents",
                str(args.agents),
                "--objects",
                str(args.objects),
                "--seed",
                "1",
                "-o",
                str(scenario),
            ],
            check=True,
            capture_output=True,
            env=env,
        )
        for _ in range(args.runs):
            row = one_run(args, scenario, env)
            rows.append(row)
            if not args.json:
                print(
                    f"N={row['agents']}: ready {row['ready_s']:.1f} s (ost up returned at "
                    f"{row['started_s']:.1f} s); idle: world {row['world_core']:.3f} core, agent "
                    f"median {row['agent_core_median']:.4f} (max {row['agent_core_max']:.4f}), all "
                    f"{row['total_core']:.2f} cores",
                    flush=True,
                )
    if args.json:
        print(json.dumps(rows, indent=1))
    elif len(rows) > 1:
        med = {
            k: statistics.median(r[k] for r in rows) for k in ("ready_s", "world_core", "agent_core_median")
        }
        print(
            f"median of {len(rows)}: ready {med['ready_s']:.1f} s, world {med['world_core']:.3f} core, "
            f"agent {med['agent_core_median']:.4f} core"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
