"""A robot's memory over a long realtime run over DDS (``ost up --realtime``):

    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_rss.py [--agents 10] [--objects 200]
        [--rtf 300] [--seed 1] [--every 0.5] [--out DIR]

Starts the run, reads every robot's resident set size (``VmRSS`` in ``/proc/<pid>/status``, the
pids from the run directory) every ``--every`` wall seconds from the moment every robot is up
until the result, and prints the robots' RSS (median and largest, MiB) at a quarter of the run
and at its end (the last sample before the result): what grows with the run's length shows as
the difference. Writes ``rss.md`` into --out (default /tmp/ost_bench_rss).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

OST = str(Path(sys.executable).parent / "ost")


def rss_mib(pid: int) -> float | None:
    """The resident set size of ``pid`` in MiB (None: gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def robot_pids(run: Path, agents: int) -> dict[int, int]:
    pids = {}
    for a in range(agents):
        f = run / f"agent_{a}.pid"
        if f.exists():
            pids[a] = int(f.read_text().strip())
    return pids


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, default=10)
    ap.add_argument("--objects", type=int, default=200)
    ap.add_argument("--width", type=int, default=500)
    ap.add_argument("--height", type=int, default=200)
    ap.add_argument("--nmax", type=int, default=10)
    ap.add_argument("--rtf", type=float, default=300.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--every", type=float, default=0.5)
    ap.add_argument("--out", type=Path, default=Path("/tmp/ost_bench_rss"))
    a = ap.parse_args(argv)
    d = Path(tempfile.mkdtemp(prefix="ost-bench-rss-"))
    run = d / "run"
    cmd = [OST, "up", "--agents", str(a.agents), "--objects", str(a.objects), "--seed", str(a.seed)]
    cmd += ["--width", str(a.width), "--height", str(a.height), "--nmax", str(a.nmax)]
    cmd += ["--realtime", "--rtf", f"{a.rtf:g}", "--run-dir", str(run)]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    samples: list[tuple[float, dict[int, float]]] = []  # (wall since start, agent -> MiB)
    pids: dict[int, int] = {}
    while proc.poll() is None:
        time.sleep(a.every)
        if len(pids) < a.agents:
            pids = robot_pids(run, a.agents)
        if (run / "result.json").exists():
            break
        if len(pids) == a.agents:
            now = {k: m for k, p in pids.items() if (m := rss_mib(p)) is not None}
            if len(now) == a.agents:
                samples.append((time.monotonic() - t0, now))
    out, err = proc.communicate()
    if proc.returncode != 0:
        tail = (err or out).strip().splitlines()[-3:]
        print(f"bench_rss: ost up failed ({' | '.join(tail)}); logs in {run}", file=sys.stderr)
        return 1
    res = json.loads((run / "result.json").read_text())
    if len(samples) < 4:
        print(f"bench_rss: only {len(samples)} samples: a longer run is needed", file=sys.stderr)
        return 1
    start, end = samples[0][0], samples[-1][0]
    quarter = min(samples, key=lambda s: abs(s[0] - (start + (end - start) / 4)))
    last = samples[-1]

    def fig(s: tuple[float, dict[int, float]]) -> str:
        v = list(s[1].values())
        return f"median {statistics.median(v):.1f} MiB, largest {max(v):.1f} MiB (at {s[0]:.0f} s)"

    delivered = sum(o["delivered"] is not None for o in res["objects"])
    lines = [
        f"# A robot's memory over a realtime run (N={a.agents}, M={a.objects}, rtf {a.rtf:g})",
        "",
        f"`{' '.join(['ost'] + cmd[1:-2])}`: {delivered}/{len(res['objects'])} delivered, "
        f"makespan {res['makespan']}, {res.get('disagreements', 0)} disagreements; "
        f"{len(samples)} samples of every robot's RSS from {start:.0f} s to {end:.0f} s of wall.",
        "",
        f"- at a quarter of the run: {fig(quarter)}",
        f"- at its end: {fig(last)}",
        f"- growth from the quarter to the end (median robot): "
        f"{statistics.median(last[1].values()) - statistics.median(quarter[1].values()):+.1f} MiB",
    ]
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "rss.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
