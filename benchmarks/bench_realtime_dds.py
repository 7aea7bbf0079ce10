"""Realtime runs over DDS (``ost up --realtime``), measured against the lockstep and ``ost sim``:

    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_realtime_dds.py \\
        [--rtf 100,300,1000,3000] [--agents 10] [--objects 20] [--width 500] [--height 200]
        [--seeds 1] [--repeat 5] [--clock-hz HZ] [--membership node|world] [--fanout direct,monitor]
        [--large] [--large-rtf 20,100] [--out DIR]

For each real-time factor (sim steps per wall second) it starts one world node and one process
per robot with ``ost up --realtime --rtf R`` and reads the run's ``result.json``: every object
delivered, disagreements between the robots' coordination digests (must be 0), the makespan
against ``ost sim``'s on the same scenario, the largest lag (how many sim steps after its stamp a
batch of messages was processed; ≤ 1 means the network keeps up with the pace), the wall time of
the run and of the bring-up, and the CPU seconds of every process (the children's rusage). The
lockstep over DDS (``ost up`` without --realtime) is measured on the same scenario for reference
(up to --lockstep-max agents: at N=50 it takes minutes).
--large adds N=50, M=200 at the --large-rtf factors (the paper's largest team; figures for
both fan-outs in docs/benchmarks.md).
--fanout takes a comma-separated list: each real-time factor's runs alternate between them (an
A/B in one run of the script), each row labelled with its fan-out.

Writes ``realtime_dds.md`` (a markdown table) into --out (default /tmp/ost_bench_realtime_dds).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OST = str(Path(sys.executable).parent / "ost")


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def sim_makespan(scenario: Path) -> float:
    out = subprocess.run([OST, "sim", str(scenario), "--json"], check=True, capture_output=True, text=True)
    return float(json.loads(out.stdout)["makespan"])


def run_up(
    agents: int,
    objects: int,
    seed: int,
    rtf: float | None,
    nmax: int,
    clock_hz: float | None = None,
    size: tuple[int, int] = (500, 200),
    membership: str | None = None,
    fanout: str | None = None,
) -> dict:
    """One ``ost up`` run; its result with the wall and CPU seconds it took."""
    d = Path(tempfile.mkdtemp(prefix="ost-bench-rt-"))
    cmd = [OST, "up", "--agents", str(agents), "--objects", str(objects), "--seed", str(seed)]
    cmd += ["--width", str(size[0]), "--height", str(size[1])]
    cmd += ["--nmax", str(nmax), "--run-dir", str(d / "run")]
    if rtf is not None:
        cmd += ["--realtime", "--rtf", f"{rtf:g}"]
        if clock_hz is not None:
            cmd += ["--clock-hz", f"{clock_hz:g}"]
        if membership is not None:
            cmd += ["--membership", membership]
        if fanout is not None:
            cmd += ["--fanout", fanout]
    cpu0, t0 = children_cpu(), time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall, cpu = time.monotonic() - t0, children_cpu() - cpu0
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        raise SystemExit(f"bench_realtime_dds: ost up failed ({' | '.join(tail)}); logs in {d}")
    res = json.loads((d / "run" / "result.json").read_text())
    res["_wall"], res["_cpu"], res["_scenario"] = wall, cpu, d / "run" / "scenario.yaml"
    return res


def row(label: str, res: dict, ref: float) -> str:
    delivered = sum(o["delivered"] is not None for o in res["objects"])
    lag = max(res.get("lag", {}).values(), default=0.0)
    dis = res.get("disagreements", 0)
    comp = res.get("coordinations_compared", 0)
    return (
        f"| {label} | {delivered}/{len(res['objects'])} | {dis} / {comp} | {res['makespan']:.0f} "
        f"| {100 * (res['makespan'] / ref - 1):+.1f} % | {lag:.1f} | {res['_wall']:.1f} "
        f"| {res.get('bring_up_s', float('nan')):.1f} | {res['_cpu']:.1f} |"
    )


def keeps_up(lags: dict[float, list[float]]) -> list[str]:
    """The highest real-time factor run at which no robot lagged more than one step, and the
    factor the slowest run's lag points to: a lag of L steps at rtf R is L / R wall seconds, and
    the pace a team keeps within one step is about R / L (the wall lag is the robots' own work)."""
    if not lags:
        return []
    ok = [r for r, ls in lags.items() if max(ls) <= 1.0]
    best = f"rtf {max(ok):g}" if ok else f"none of {', '.join(f'{r:g}' for r in lags)}"
    r0 = min(lags)
    worst = max(lags[r0])
    wall = f"{worst / r0:.3f} s of wall" if worst > 0 else "0 s"
    bound = f"; about rtf {r0 / worst:.3g} keeps it within one step" if worst > 0 else ""
    return [
        f"highest rtf run with every robot's largest lag at most 1 step: {best}",
        f"at rtf {r0:g} the largest lag is {worst:.1f} steps = {wall}{bound}",
    ]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rtf", default="100,300,1000,3000", help="real-time factors, comma-separated")
    ap.add_argument("--agents", type=int, default=10)
    ap.add_argument("--objects", type=int, default=20)
    ap.add_argument("--width", type=int, default=500, help="grid width (of the --agents runs)")
    ap.add_argument("--height", type=int, default=200, help="grid height (of the --agents runs)")
    ap.add_argument("--nmax", type=int, default=10)
    ap.add_argument("--seeds", type=int, default=1, help="scenario seeds 1..K")
    ap.add_argument("--repeat", type=int, default=1, help="runs per real-time factor (then their median)")
    ap.add_argument("--clock-hz", type=float, default=None, help="the world's clock rate (ost up's default)")
    ap.add_argument("--large", action="store_true", help="also N=50, M=200 (at --large-rtf)")
    ap.add_argument("--large-rtf", default="20,100", help="real-time factors of the N=50 runs")
    ap.add_argument(
        "--lockstep-max", type=int, default=10, help="the lockstep reference only up to this many agents"
    )
    ap.add_argument(
        "--membership",
        choices=("node", "world"),
        default=None,
        help="who runs the monitor (ost up's default)",
    )
    ap.add_argument(
        "--fanout",
        default=None,
        help="how robots' messages reach their peers: direct, monitor, or both comma-separated "
        "(alternating; ost up's default)",
    )
    ap.add_argument("--out", type=Path, default=Path("/tmp/ost_bench_realtime_dds"))
    a = ap.parse_args(argv)
    fanouts: list[str | None] = [None] if a.fanout is None else a.fanout.split(",")
    if not all(f in ("direct", "monitor") for f in fanouts):
        print(f"bench_realtime_dds: error: --fanout: {a.fanout!r} is not a list of direct, monitor", file=sys.stderr)  # fmt: skip
        return 2
    try:
        rtfs = [float(x) for x in a.rtf.split(",")]
        large = [float(x) for x in a.large_rtf.split(",")]
    except ValueError:
        print(f"bench_realtime_dds: error: --rtf/--large-rtf: not a list of numbers: {a.rtf!r}, {a.large_rtf!r}", file=sys.stderr)  # fmt: skip
        return 2
    head = [
        "| run | delivered | disagreements / coordinations | makespan | vs ost sim | largest lag "
        "(steps) | wall (s) | bring-up (s) | CPU (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    cases = [(a.agents, a.objects, a.nmax, rtfs, (a.width, a.height))]
    if a.large:
        cases.append((50, 200, 10, large, (500, 200)))
    clock = "ost up's default" if a.clock_hz is None else f"{a.clock_hz:g} Hz"
    monitor = f"; membership monitor: {a.membership or 'ost up default'}"
    lines = [
        f"machine: {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f} at start; clock {clock}{monitor}",
        "",
    ]
    for n, m, nmax, rs, size in cases:
        for seed in range(1, a.seeds + 1):
            lines += [f"N={n}, M={m}, seed {seed}, {size[0]}x{size[1]}, CCP CI=1", "", *head]
            ref = None
            if n <= a.lockstep_max:
                lock = run_up(n, m, seed, None, nmax, size=size)
                ref = sim_makespan(lock["_scenario"])
                lines.append(row("lockstep", lock, ref))
                print(lines[-1], flush=True)
            lags: dict[str | None, dict[float, list[float]]] = {f: {} for f in fanouts}
            for r in rs:
                spans: dict[str | None, list[float]] = {f: [] for f in fanouts}
                for _ in range(a.repeat):
                    for f in fanouts:
                        res = run_up(n, m, seed, r, nmax, a.clock_hz, size, a.membership, f)
                        ref = ref if ref is not None else sim_makespan(res["_scenario"])
                        spans[f].append(res["makespan"])
                        lags[f].setdefault(r, []).append(max(res.get("lag", {}).values(), default=0.0))
                        how = f", fanout {f}" if f else ""
                        lines.append(row(f"realtime rtf {r:g}{how}", res, ref))
                        print(lines[-1], flush=True)
                if a.repeat > 1 and ref is not None:
                    for f in fanouts:
                        med = statistics.median(spans[f])
                        how = f", fanout {f}" if f else ""
                        lines.append(f"| rtf {r:g}{how}: median of {a.repeat} | | | {med:.0f} | {100 * (med / ref - 1):+.1f} % | | | | |")  # fmt: skip
                        print(lines[-1], flush=True)
            for f in fanouts:
                how = [f"fanout {f}:"] if f else []
                lines += ["", *how, *keeps_up(lags[f]), ""]
                print("\n".join(lines[-4:-1]), flush=True)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "realtime_dds.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {a.out / 'realtime_dds.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
