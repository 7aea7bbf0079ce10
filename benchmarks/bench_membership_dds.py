"""Who is in the team over DDS: a robot stopped (SIGSTOP) and resumed, or the team cut in two
(a network partition between simulated hosts), against the same run without the fault.

    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_membership_dds.py \\
        [--runs 5] [--stop 5] [--at 100] [--agents 6] [--objects 10] [--rtf 20] [--out DIR]
    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_membership_dds.py --split 10 \\
        --agents 10 [--groups 0,1,2,3,4,5/6,7,8,9] ...          (root, nftables)
    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_membership_dds.py --join --agents 10 ...

Each pair: one ``ost up --realtime`` run of the scenario (``ost generate --agents N --objects M
--seed 919 --width 120 --height 60 --nmax 3``), and one with the fault from sim time --at: robot
2's process stopped for --stop wall seconds, then resumed; or (``--split S``) both runs on three
simulated hosts, the second with ``--split GROUPS:AT:S`` (no traffic between the groups' hosts for
S wall seconds); or (``--join``) the second with ``--join 2:AT``: robot 2's process started only
once the run's sim time reaches --at. Reported: completed runs, disagreements, robots declared out and back, robots out
at the end, the wall time from the resume to the robot being back in the team (its first goal of
the new life reached the world) or from the heal to the last robot taking the last batch stamped
before it (its digest), or from the joining robot's process start to its first goal of its
life in the team, and the makespan against the run without the fault. Writes
``membership_dds.md`` (``split_dds.md``, ``join_dds.md``) into --out (default /tmp/ost_bench_membership_dds);
every figure in it is computed from the runs.
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


def one(
    scenario: Path,
    rtf: float,
    stop: float | None,
    at: float,
    split: list[str] | None = None,
    timeout: float = 600,
) -> dict:
    """One run (with robot 2 stopped ``stop`` s from sim time ``at``, or not; on three hosts
    with ``split``'s options, if given); its result."""
    d = Path(tempfile.mkdtemp(prefix="ost-bench-mem-"))
    cmd = [OST, "up", "--scenario", str(scenario), "--realtime", "--rtf", str(rtf), "--json"]
    cmd += ["--run-dir", str(d / "run"), "--timeout", str(int(timeout)), *(split or [])]
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
    if split and "--join" in split:  # from the joining process's start to back: sim time is wall x rtf
        m = result.get("membership", {})
        started = next((j["started"] for j in m.get("joins", []) if j["agent"] == 2), None)
        back = [t for kind, who, t in m.get("events", []) if kind == "back" and who == 2]
        if started is not None and back:
            back_wall = (back[0] - started) / rtf
    result["back_after_s"] = back_wall
    return result


def pair(base: dict, fault: dict, **extra: object) -> dict:
    """One pair's row: what both runs promise, the fault run's membership figures (``extra``)
    and its makespan against the run without the fault."""
    ratio = fault["makespan"] / base["makespan"] - 1 if base["makespan"] and fault["makespan"] else None
    m = fault.get("membership", {})
    return {
        "completed": bool(base["completed"] and fault["completed"]),
        "disagreements": base["disagreements"] + fault["disagreements"],
        "out_at_end": m.get("out_at_end", []),
        **extra,
        "ratio": ratio,
    }


def table(title: str, what: str, rows: list[dict]) -> list[str]:
    """The report's head: what was run, and what every pair promises."""
    return [
        f"# {title} (benchmarks/bench_membership_dds.py)",
        "",
        what,
        "",
        "| | |",
        "|---|---|",
        f"| both runs completed | {sum(r['completed'] for r in rows)} of {len(rows)} |",
        f"| disagreements | {sum(r['disagreements'] for r in rows)} |",
        f"| robots out at the end | {sum(len(r['out_at_end']) for r in rows)} |",
    ]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--stop", type=float, default=5.0)
    ap.add_argument("--at", type=float, default=100.0)
    ap.add_argument("--agents", type=int, default=6)
    ap.add_argument("--objects", type=int, default=10)
    ap.add_argument("--rtf", type=float, default=20.0)
    ap.add_argument("--split", type=int, default=0, metavar="S", help="cut the team in two for S s instead")
    ap.add_argument(
        "--groups", default="", help="with --split: the groups (default: the first 60 %% / the rest)"
    )
    ap.add_argument("--join", action="store_true", help="robot 2 joins at sim time --at instead")
    ap.add_argument("--out", default="/tmp/ost_bench_membership_dds")
    a = ap.parse_args()
    if a.split:
        return splits(a)
    if a.join:
        return joins(a)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    scenario = generate(a, out)
    rows = []
    for k in range(a.runs):
        base = one(scenario, a.rtf, None, a.at)
        fault = one(scenario, a.rtf, a.stop, a.at)
        m = fault.get("membership", {})
        rows.append(
            pair(
                base,
                fault,
                declared=m.get("declared", 0),
                rejoins=m.get("rejoins", 0),
                back_after_s=fault["back_after_s"],
            )
        )
        print(f"  pair {k + 1}/{a.runs}: {rows[-1]}", file=sys.stderr)
    backs = [r["back_after_s"] for r in rows if r["back_after_s"] is not None]
    ratios = [r["ratio"] for r in rows if r["ratio"] is not None]
    what = (
        f"{a.runs} pairs of runs, N={a.agents}, M={a.objects}, 120×60, rtf {a.rtf:g}; robot 2 stopped "
        f"{a.stop:g} s from sim time {a.at:g} in the second of each pair."
    )
    lines = table("Membership over DDS", what, rows)
    lines.append(
        f"| declared out / back | {sum(r['declared'] for r in rows)} / {sum(r['rejoins'] for r in rows)} |"
    )
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


def generate(a: argparse.Namespace, out: Path) -> Path:
    scenario = out / "scenario.yaml"
    gen = [OST, "generate", "--agents", str(a.agents), "--objects", str(a.objects), "--seed", "919"]
    subprocess.run([*gen, "--width", "120", "--height", "60", "--nmax", "3", "-o", str(scenario)], check=True)
    return scenario


def splits(a: argparse.Namespace) -> int:
    """Pairs of runs on three simulated hosts, the second cut in two for ``a.split`` s."""
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    scenario = generate(a, out)
    k = max(1, round(0.6 * a.agents))
    groups = a.groups or f"{','.join(map(str, range(k)))}/{','.join(map(str, range(k, a.agents)))}"
    hosts = ["--hosts", "3", "--fanout", "direct"]  # (a split cuts robots apart, not the monitor)
    rows = []
    for n in range(a.runs):
        base = one(scenario, a.rtf, None, a.at, hosts)
        fault = one(scenario, a.rtf, None, a.at, [*hosts, "--split", f"{groups}:{int(a.at)}:{a.split}"])
        m = fault.get("membership", {})
        (cut,) = m.get("splits", [{}])
        rows.append(pair(base, fault, declared=m.get("declared", 0), agree_after_s=cut.get("agree_after_s")))
        print(f"  pair {n + 1}/{a.runs}: {rows[-1]}", file=sys.stderr)
    agree = sorted(r["agree_after_s"] for r in rows if r["agree_after_s"] is not None)
    ratios = [r["ratio"] for r in rows if r["ratio"] is not None]
    what = (
        f"{a.runs} pairs of runs, N={a.agents}, M={a.objects}, 120×60, rtf {a.rtf:g}, three simulated hosts; "
        f"in the second of each pair no traffic between robots {groups.replace('/', ' | ')} from sim time "
        f"{a.at:g} for {a.split} s."
    )
    lines = table("A partition over DDS", what, rows)
    lines.append(f"| robots declared out | {sum(r['declared'] for r in rows)} |")
    if agree:
        p99 = agree[min(len(agree) - 1, int(0.99 * len(agree)))]
        lines.append(
            f"| heal → every robot took the batches stamped before it (wall s) | median "
            f"{statistics.median(agree):.2f}, p99 {p99:.2f}, max {max(agree):.2f} |"
        )
    if ratios:
        lines.append(
            f"| makespan vs no partition | median {statistics.median(ratios):+.1%} "
            f"({', '.join(f'{x:+.1%}' for x in ratios)}) |"
        )
    text = "\n".join(lines) + "\n"
    (out / "split_dds.md").write_text(text)
    print(text)
    return 0 if all(r["completed"] and r["disagreements"] == 0 for r in rows) else 1


def joins(a: argparse.Namespace) -> int:
    """Pairs of runs, robot 2 joining the second at sim time ``a.at``."""
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    scenario = generate(a, out)
    rows = []
    for n in range(a.runs):
        base = one(scenario, a.rtf, None, a.at)
        fault = one(scenario, a.rtf, None, a.at, ["--join", f"2:{int(a.at)}"])
        m = fault.get("membership", {})
        ((joined),) = m.get("joins", [{}])
        back = [t for kind, who, t in m.get("events", []) if kind == "back" and who == 2]
        works = any(2 in o["agents"] and back and o["start"] > back[0] for o in fault["objects"])
        rows.append(
            pair(
                base,
                fault,
                started=joined.get("started"),
                back_sim=back[0] if back else None,
                back_after_s=fault["back_after_s"],
                works=works,
            )
        )
        print(f"  pair {n + 1}/{a.runs}: {rows[-1]}", file=sys.stderr)
    backs = [r["back_after_s"] for r in rows if r["back_after_s"] is not None]
    ratios = [r["ratio"] for r in rows if r["ratio"] is not None]
    what = (
        f"{a.runs} pairs of runs, N={a.agents}, M={a.objects}, 120×60, rtf {a.rtf:g}; in the second of "
        f"each pair robot 2's process starts once the run's sim time reaches {a.at:g} (--join 2:{int(a.at)})."
    )
    lines = table("A robot that joins over DDS", what, rows)
    lines.append(
        f"| the joiner carried an object after joining | {sum(r['works'] for r in rows)} of {len(rows)} |"
    )
    if backs:
        lines.append(
            f"| its process start → in the team (wall s) | median {statistics.median(backs):.2f}, "
            f"max {max(backs):.2f} |"
        )
    if ratios:
        lines.append(
            f"| makespan vs all in from the start | median {statistics.median(ratios):+.1%} "
            f"({', '.join(f'{x:+.1%}' for x in ratios)}) |"
        )
    text = "\n".join(lines) + "\n"
    (out / "join_dds.md").write_text(text)
    print(text)
    return 0 if all(r["completed"] and r["disagreements"] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
