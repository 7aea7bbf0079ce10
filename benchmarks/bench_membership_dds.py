"""Who is in the team over DDS: a robot stopped (SIGSTOP) and resumed, against the same run
without the fault.

    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_membership_dds.py \\
        [--runs 5] [--stop 5] [--at 100] [--agents 6] [--objects 10] [--rtf 20] [--out DIR]

Each pair: one ``ost up --realtime`` run of the scenario (``ost generate --agents N --objects M
--seed 919 --width 120 --height 60 --nmax 3``), and one where robot 2's process is stopped at sim
time --at for --stop wall seconds, then resumed. Reported: completed runs, disagreements, robots
declared out and back, robots out at the end, the wall time from the resume to the robot being
back in the team (its first goal of the new life reached the world), and the makespan against
the run without the fault. Writes ``membership_dds.md`` into --out (default
/tmp/ost_bench_membership_dds); every figure in it is computed from the runs.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

OST = str(Path(sys.executable).parent / "ost")


def sim_time(run_dir: Path) -> float:
    try:
        return float((run_dir / "progress").read_text().split()[0])
    except (OSError, IndexError, ValueError):
        return -1.0


def one(scenario: Path, rtf: float, stop: float | None, at: float, timeout: float = 600) -> dict:
    """One run (with robot 2 stopped ``stop`` s from sim time ``at``, or not); its result."""
    d = Path(tempfile.mkdtemp(prefix="ost-bench-mem-"))
    cmd = [OST, "up", "--scenario", str(scenario), "--realtime", "--rtf", str(rtf), "--json"]
    cmd += ["--run-dir", str(d / "run"), "--timeout", str(int(timeout))]
    p = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    resumed = None
    if stop is not None:
        end = time.monotonic() + timeout
        while sim_time(d / "run") < at:
            if p.poll() is not None or time.monotonic() > end:
                raise SystemExit(f"the run ended before sim time {at}")
            time.sleep(0.05)
        pid = int((d / "run" / "agent_2.pid").read_text())
        os.kill(pid, signal.SIGSTOP)
        time.sleep(stop)
        os.kill(pid, signal.SIGCONT)
        resumed = time.time()
    out, err = p.communicate(timeout=timeout + 30)
    if p.returncode not in (0, 1):
        raise SystemExit(f"ost up failed ({p.returncode}): {err[-2000:]}")
    result = json.loads(out)
    back_wall = None
    if resumed is not None:
        # "[INFO] [<epoch>] [ost.world]: agent 2 back (life 1) ..." in the world's log
        for line in (d / "run" / "world.log").read_text().splitlines():
            m = re.search(r"\[(\d+\.\d+)\] \[ost\.world\]: agent 2 back", line)
            if m and float(m.group(1)) >= resumed:
                back_wall = float(m.group(1)) - resumed
                break
    result["back_after_s"] = back_wall
    return result


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--stop", type=float, default=5.0)
    ap.add_argument("--at", type=float, default=100.0)
    ap.add_argument("--agents", type=int, default=6)
    ap.add_argument("--objects", type=int, default=10)
    ap.add_argument("--rtf", type=float, default=20.0)
    ap.add_argument("--out", default="/tmp/ost_bench_membership_dds")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    scenario = out / "scenario.yaml"
    gen = [OST, "generate", "--agents", str(a.agents), "--objects", str(a.objects), "--seed", "919"]
    subprocess.run([*gen, "--width", "120", "--height", "60", "--nmax", "3", "-o", str(scenario)], check=True)
    rows = []
    for k in range(a.runs):
        base = one(scenario, a.rtf, None, a.at)
        fault = one(scenario, a.rtf, a.stop, a.at)
        m = fault.get("membership", {})
        rows.append(
            {
                "completed": bool(base["completed"] and fault["completed"]),
                "disagreements": base["disagreements"] + fault["disagreements"],
                "declared": m.get("declared", 0),
                "rejoins": m.get("rejoins", 0),
                "out_at_end": m.get("out_at_end", []),
                "back_after_s": fault["back_after_s"],
                "ratio": fault["makespan"] / base["makespan"] - 1
                if base["makespan"] and fault["makespan"]
                else None,
            }
        )
        print(f"  pair {k + 1}/{a.runs}: {rows[-1]}", file=sys.stderr)
    backs = [r["back_after_s"] for r in rows if r["back_after_s"] is not None]
    ratios = [r["ratio"] for r in rows if r["ratio"] is not None]
    lines = [
        "# Membership over DDS (benchmarks/bench_membership_dds.py)",
        "",
        f"{a.runs} pairs of runs, N={a.agents}, M={a.objects}, 120×60, rtf {a.rtf:g}; robot 2 stopped "
        f"{a.stop:g} s from sim time {a.at:g} in the second of each pair.",
        "",
        "| | |",
        "|---|---|",
        f"| both runs completed | {sum(r['completed'] for r in rows)} of {len(rows)} |",
        f"| disagreements | {sum(r['disagreements'] for r in rows)} |",
        f"| declared out / back | {sum(r['declared'] for r in rows)} / {sum(r['rejoins'] for r in rows)} |",
        f"| robots out at the end | {sum(len(r['out_at_end']) for r in rows)} |",
    ]
    if backs:
        lines.append(
            f"| resume → back in the team (wall s) | median {statistics.median(backs):.2f}, max {max(backs):.2f} |"
        )
    if ratios:
        lines.append(
            f"| makespan vs no fault | median {statistics.median(ratios):+.1%} ({', '.join(f'{x:+.1%}' for x in ratios)}) |"
        )
    text = "\n".join(lines) + "\n"
    (out / "membership_dds.md").write_text(text)
    print(text)
    return 0 if all(r["completed"] and r["disagreements"] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
