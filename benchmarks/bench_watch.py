"""What watching a run costs (not a test): animations, recordings, replays.

    .venv/bin/python benchmarks/bench_watch.py [--repeat 3] [--no-dds]

1. The demo scenario (500x200, N=10, M=20, seed 1), in-process: the step engine bare and with
   the frame recorder, then the GIF and the MP4 drawn from the frames (time, frames, size).
2. A long run (one robot sweeping 1000x320 alone, M=5: over 10^5 steps): frames kept and render time —
   the frame count stays near the recorder's target however long the run.
3. Over DDS (ost_up.sh, the demo scenario): wall time without and with ``--record``, run-to-run
   interleaved; the recording's size and message count; ``ost replay`` time; the replay's result
   identical to the run's.
Medians of ``--repeat`` runs; every figure printed is measured here.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from ost_ros.watch.animate import animate
from ost_ros.watch.frames import FrameRecorder

REPO = Path(__file__).resolve().parents[1]
OST = [sys.executable, "-m", "ost_ros"]


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def in_process(scenario, label: str, tmp: Path, repeat: int) -> None:
    bare = statistics.median(
        timed(lambda: simulate(scenario, "ccp", CoordinationPolicy(), engine="step"))[0]
        for _ in range(repeat)
    )
    recs = []
    for _ in range(repeat):
        rec = FrameRecorder(scenario)
        t, result = timed(
            lambda rec=rec: simulate(scenario, "ccp", CoordinationPolicy(), on_step=rec, engine="step")
        )
        recs.append(t)
    frames = rec.finish()
    print(
        f"{label}: {result.steps} steps; step engine {bare:.2f} s bare, {statistics.median(recs):.2f} s with the frame recorder"
    )
    print(
        f"  frames kept: {len(frames)} ({sum(f.event for f in frames)} at decision points, spacing {rec.spacing} steps)"
    )
    for suffix in (".gif", ".mp4"):
        times, size = [], 0
        for _ in range(repeat):
            t, written = timed(lambda suffix=suffix: animate(scenario, result, frames, tmp / f"run{suffix}"))
            times.append(t)
            size = written.bytes
        print(f"  {suffix[1:].upper()}: {statistics.median(times):.1f} s to draw, {size / 1e6:.2f} MB")


def dds(tmp: Path, repeat: int) -> None:
    scenario = generate_scenario(10, 20, 1, Grid(500, 200), 10)
    path = tmp / "demo.yaml"
    path.write_text(dump_scenario(scenario))
    walls: dict[str, list[float]] = {"plain": [], "record": []}
    bag, out = tmp / "run.mcap", ""
    for k in range(repeat):
        for mode in ("plain", "record"):
            extra = ["--record", str(bag)] if mode == "record" else []
            run_dir = tmp / f"run_{mode}_{k}"
            t, p = timed(
                lambda extra=extra, run_dir=run_dir: subprocess.run(
                    ["bash", str(REPO / "bringup_scripts/ost_up.sh"), "--scenario", str(path), "--json",
                     "--run-dir", str(run_dir), *extra],
                    capture_output=True, text=True,
                )
            )  # fmt: skip
            assert p.returncode == 0, p.stderr[-2000:]
            walls[mode].append(t)
            out = p.stdout if mode == "record" else out
    info = subprocess.run([*OST, "record", "info", str(bag)], capture_output=True, text=True).stdout
    messages = next(line.split()[-1] for line in info.splitlines() if line.startswith("Messages:"))
    t, rep = timed(
        lambda: subprocess.run([*OST, "replay", str(bag), "--json"], capture_output=True, text=True)
    )
    same = rep.returncode == 0 and rep.stdout == out
    plain, rec = statistics.median(walls["plain"]), statistics.median(walls["record"])
    print(f"DDS, demo scenario (N=10, M=20, 500x200), {repeat} interleaved runs each:")
    print(f"  wall {plain:.1f} s without, {rec:.1f} s with --record ({rec / plain:.2f}x)")
    print(f"  recording: {bag.stat().st_size / 1e3:.0f} kB, {messages} messages")
    print(f"  ost replay: {t:.1f} s; result identical to the run's: {same}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-dds", action="store_true", help="skip the DDS part")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        in_process(
            generate_scenario(10, 20, 1, Grid(500, 200), 10),
            "demo scenario (N=10, M=20, 500x200)",
            tmp,
            args.repeat,
        )
        in_process(generate_scenario(1, 5, 1, Grid(1000, 320), 1), "long run (N=1, M=5, 1000x320)", tmp, 1)
        if not args.no_dds:
            dds(tmp, args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
