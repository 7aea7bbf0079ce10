"""Robots without a barrier, measured in process (ost_ros.realtime):

    flock /tmp/ost-dds.lock .venv/bin/python benchmarks/bench_realtime.py [--runs 1000] [--out DIR]
        [--docs] [--skip-agreement] [--skip-latency] [--skip-cpu] [--variants LABEL,...]

(a) agreement: random runs of every protocol that runs without a barrier (CCP distributed and
    coordinator with either planner, NCP, the auction, greedy; ``--variants``: only those), latencies up to 50 steps with jitter up to 50, unequal speeds,
    speed noise, stalls and failures — disagreements (must be 0), deliveries, deadlocks; and at
    latency 0 how often the run equals ``ost sim`` (failures included, some close together);
(b) the cost of latency: makespan at latency 0/1/5/20/50 steps (jitter L/2, three seeds) against
    ``ost sim`` for the demo scenario (N=10, M=20, 500×200) and a larger one (N=50, M=200): a
    markdown table and a figure;
(c) CPU: the realtime run in process against ``ost sim`` (its default engine, and the step engine)
    on the same scenarios;
(d) CCP's improved planner without a barrier: its makespan against the paper planner's under
    latency (from (b)).

Writes ``realtime.md`` and ``realtime_latency.png`` into --out (default /tmp/ost_bench_realtime);
--docs also copies the figure to docs/images/.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.protocols.ccp import CcpSettings
from ost_ros.realtime import run as rt
from ost_ros.realtime.net import Latency
from ost_ros.scenario import build_scenario, generate_objects, generate_scenario

REPO = Path(__file__).resolve().parents[1]
IMPROVED = CcpSettings(planner="improved")
VARIANTS = {  # label -> (protocol, policy, settings)
    "ccp CI=1": ("ccp", CoordinationPolicy(ci=1), None),
    "ccp after search": ("ccp", CoordinationPolicy(ci=10**6), None),
    "ccp coordinator": ("ccp", CoordinationPolicy(ci=1, organisation="coordinator"), None),
    "ccp improved CI=1": ("ccp", CoordinationPolicy(ci=1), IMPROVED),
    "ccp improved after search": ("ccp", CoordinationPolicy(ci=10**6), IMPROVED),
    "ncp CI=1": ("ncp", CoordinationPolicy(ci=1), None),
    "ncp after search": ("ncp", CoordinationPolicy(ci=10**6), None),
    "auction": ("auction", CoordinationPolicy(), None),
    "greedy": ("greedy", CoordinationPolicy(), None),
    "hcp": ("hcp", CoordinationPolicy(), None),
}
# in process every robot runs the improved planner at every coordination: at N=50 with CI=1 that
# is hours of CPU for one run (the DDS team spreads it over 50 processes), so (b) leaves it out
HEAVY = {("N=50 M=200", "ccp improved CI=1")}
LATENCIES = (0, 1, 5, 20, 50)


# ----------------------------------------------------------------------------- (a) agreement


def random_run(rng: np.random.Generator, only: Sequence[str] | None = None):
    """A random small scenario, protocol, latency, speeds, noise, stalls and failures."""
    w, h = int(rng.integers(6, 41)), int(rng.integers(4, 21))
    n = int(rng.integers(2, 9))
    cols = max(1, min(n, w // 2))
    rows = max(1, min(n // cols, h // 2))
    n = cols * rows
    grid = Grid(w, h)
    nmax = int(rng.integers(1, n + 1))
    objects = generate_objects(int(rng.integers(0, min(13, w * h))), int(rng.integers(0, 10**6)), grid, nmax)
    agents = None
    if rng.random() < 0.4:  # unequal speeds
        s0 = build_scenario(grid, objects, partition=(cols, rows), nmax=nmax)
        agents = [dataclasses.replace(a, period=int(rng.choice([1, 1, 2, 3]))) for a in s0.agents]
    s = build_scenario(grid, objects, partition=(cols, rows), agents=agents, nmax=nmax)
    labels = list(only or VARIANTS)
    label = labels[int(rng.integers(0, len(labels)))]
    protocol, policy, settings = VARIANTS[label]
    if protocol == "hcp" and agents is not None:  # (HCP's teams are of unit speed)
        s = build_scenario(grid, objects, partition=(cols, rows), nmax=nmax)
    if label.startswith("ccp improved") and rng.random() < 0.5:
        policy = dataclasses.replace(policy, organisation="coordinator")
    if protocol not in ("auction", "greedy", "hcp") and rng.random() < 0.5:
        policy = dataclasses.replace(policy, ci=int(rng.integers(1, 8)))
    latency = Latency(int(rng.integers(0, 51)), int(rng.integers(0, 51)))
    ids = [a.id for a in s.agents]
    failures = {}
    if rng.random() < 0.35 and n > 1:
        for a in rng.permutation(ids)[: int(rng.integers(1, n))]:
            failures[int(a)] = int(rng.integers(0, 300))
    stalls = [
        (int(rng.choice(ids)), float(rng.integers(0, 200)), float(rng.integers(1, 100)))
        for _ in range(int(rng.integers(0, 3)))
    ]
    jitter = float(rng.choice([0.0, 0.0, 0.25, 1.0]))
    return s, label, protocol, policy, settings, latency, failures, stalls, jitter


# the refusals a goal that crosses a network may draw (docs/realtime.md, "Bases across a network")
LATE = ("path starts at", "lies at", "after the lift")


def agreement(runs: int, seed: int, only: Sequence[str] | None = None, base_delay: float = 0.0) -> list[str]:
    """(a): random runs; ``base_delay`` > 0: every robot's base across a network too, up to that
    many steps (plus as much jitter) away, failures declared up to 40 steps late."""
    rng = np.random.default_rng(seed)
    stats = {"runs": 0, "disagreements": 0, "compared": 0, "completed": 0, "impossible": 0, "deadlock": 0}
    bad: list[str] = []
    per: dict[str, int] = {}
    t0 = time.process_time()
    for i in range(runs):
        s, label, protocol, policy, how, latency, failures, stalls, jitter = random_run(rng, only)
        remote: dict = {}
        if base_delay:
            remote = {
                "base_delay": Latency(
                    float(rng.choice([0.0, 0.3, 1.0, base_delay])), float(rng.choice([0.0, 0.5, base_delay]))
                ),
                "declare_after": float(rng.choice([0.0, 5.0, 40.0])),
            }
        r, rep = rt.run_realtime(
            s,
            protocol,
            policy,
            how,
            latency=latency,
            seed=i,
            speed_jitter=jitter,
            stalls=stalls,
            failures=failures,
            **remote,
        )
        if base_delay:
            r.rejections = [x for x in r.rejections if not any(k in x for k in LATE)]
        stats["runs"] += 1
        per[label] = per.get(label, 0) + 1
        stats["disagreements"] += rep.disagreements
        stats["compared"] += rep.coordinations
        survivors = s.n_agents - len(failures)
        ok = all(
            (o.delivered is not None and len(set(o.agents)) == spec.required) or spec.required > survivors
            for o, spec in zip(r.objects, s.objects)
        )
        if r.completed and ok:
            stats["completed"] += 1
        elif r.error and "cannot be delivered" in r.error and ok:
            stats["impossible"] += 1
        else:
            stats["deadlock"] += 1
            bad.append(f"run {i} ({label}, {latency}, failures {failures}): {r.error}")
        if rep.disagreements or r.warnings or r.rejections:
            bad.append(
                f"run {i} ({label}): {rep.disagreements} disagreements, {r.warnings[:2]}, {r.rejections[:2]}"
            )
    cpu = time.process_time() - t0
    # latency 0 against ost sim (step engine), failures included
    eq = {"runs": 0, "equal": 0, "cascade": 0, "moved on": 0}
    for i in range(max(100, runs // 5)):
        s, label, protocol, policy, how, _, failures, _, _ = random_run(rng, only)
        if i % 2 and s.n_agents > 2:  # half of them: two or three robots failing within 6 steps
            t0, ids = int(rng.integers(0, 60)), [a.id for a in s.agents]
            dead = rng.permutation(ids)[: int(rng.integers(2, min(4, len(ids))))]
            failures = {int(a): t0 + int(rng.integers(0, 6)) for a in dead}
        ref = simulate(s, protocol, policy, engine="step", settings=how, failures=failures)
        agents: list = []
        r, _ = rt.run_realtime(s, protocol, policy, how, failures=failures, prepare=agents.extend)
        eq["runs"] += 1
        if r.to_dict() == ref.to_dict():
            eq["equal"] += 1
        elif any(getattr(ra.agent, "moved_on", 0) for ra in agents):
            eq["moved on"] += 1  # an HCP heir routed its inherited sweep from where it went on to
        elif len(failures) > 1:
            eq["cascade"] += 1
        else:
            bad.append(f"latency 0 run {i} ({label}, failures {failures}) differs from ost sim")
    lines = [
        "## (a) Agreement without a barrier",
        "",
        f"{stats['runs']} random runs ({', '.join(f'{k}: {v}' for k, v in sorted(per.items()))}); "
        "latency L + U{0..J} with L, J drawn in 0..50 steps per run, unequal speeds in 40 %, speed "
        "noise, stalls, failures in 35 % (sometimes too many for the heaviest objects)"
        + (
            f"; every robot's base across a network, 0..{base_delay:g} + 0..{base_delay:g} steps away, "
            "failures declared 0, 5 or 40 steps late."
            if base_delay
            else "."
        ),
        "",
        "| runs | coordinations compared | disagreements | completed | objects impossible (too few survive) | deadlocks or lost objects | CPU |",
        "|---:|---:|---:|---:|---:|---:|---:|",
        f"| {stats['runs']} | {stats['compared']} | {stats['disagreements']} | {stats['completed']} | "
        f"{stats['impossible']} | {stats['deadlock']} | {cpu:.0f} s |",
        "",
        f"At latency 0, {eq['runs']} random runs (failures in 35 %, and in every other run two or "
        "three robots failing within 6 steps of each other) against `ost sim --engine step`: "
        f"{eq['equal']} identical; {eq['runs'] - eq['equal']} different "
        f"({eq['cascade']} of them with several failures; {eq['moved on']} where an HCP heir walking "
        "when it read a notice routed the sweep it inherited from where it went on to).",
        "",
    ]
    if bad:
        lines += ["Problems:", "", *[f"- {b}" for b in bad[:20]], ""]
    return lines


# ----------------------------------------------------------------------------- (b) latency


def latency_table(seeds: int, only: set[str] | None = None) -> tuple[list[str], dict]:
    scenarios = {
        "demo N=10 M=20": generate_scenario(10, 20, 1),
        "N=50 M=200": generate_scenario(50, 200, 1),
    }
    data: dict = {}
    lines = [
        "## (b) The cost of latency",
        "",
        "Makespan without a barrier at latency L steps (jitter up to L/2, mean of "
        f"{seeds} seeds; one seed for N=50) against `ost sim` (lockstep); in brackets the change. "
        "Every run: 0 disagreements, every object delivered.",
        "",
    ]
    for name, s in scenarios.items():
        lines += [
            f"**{name}**",
            "",
            "| protocol | ost sim | " + " | ".join(f"L={L}" for L in LATENCIES) + " |",
            "|---|---:|" + "---:|" * len(LATENCIES),
        ]
        for label, (protocol, policy, how) in VARIANTS.items():
            if (name, label) in HEAVY or (only and label not in only):
                continue
            engine = "step" if policy.centralised else "auto"
            ref = simulate(s, protocol, policy, engine=engine, settings=how)
            cells, rel = [], []
            for L in LATENCIES:
                ms = []
                for seed in range(seeds if s.n_agents <= 10 else 1):
                    r, rep = rt.run_realtime(s, protocol, policy, how, latency=Latency(L, L // 2), seed=seed)
                    assert r.completed and rep.disagreements == 0, (name, label, L, r.error)
                    ms.append(r.makespan)
                m = float(np.mean(ms))
                rel.append(100 * (m - ref.makespan) / ref.makespan)
                cells.append(f"{m:.0f} ({rel[-1]:+.1f} %)")
            data[(name, label)] = rel
            data[(name, label, "makespan")] = [ref.makespan] + [float(c.split()[0]) for c in cells]
            lines.append(f"| {label} | {ref.makespan} | " + " | ".join(cells) + " |")
            print(lines[-1], flush=True)
        lines.append("")
    return lines, data


def figure(data: dict, path: Path) -> None:
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = sorted({k[0] for k in data}, key=lambda n: ("N=50" in n, n))
    # one colour per variant in every panel (a panel may lack one: HEAVY)
    labels = list(dict.fromkeys(k[1] for k in data if len(k) == 2))
    colour = {label: f"C{i % 10}" for i, label in enumerate(labels)}
    fig, axes = plt.subplots(1, len(names), figsize=(11, 4.2), sharey=True)
    for ax, name in zip(np.atleast_1d(axes), names):
        for key, rel in data.items():
            if len(key) == 2 and key[0] == name:
                label = key[1]
                ax.plot(LATENCIES, [1 + r / 100 for r in rel], marker="o", label=label, color=colour[label])
        ax.set_title(name)
        ax.set_xlabel("latency L (steps; jitter up to L/2)")
        ax.set_yscale("log")
        ax.set_yticks([0.8, 0.9, 1, 1.25, 1.5, 2, 3, 5])
        ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}×"))
        ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.axhline(1, color="grey", lw=0.8)
        ax.grid(alpha=0.3, which="both")
    np.atleast_1d(axes)[0].set_ylabel("makespan / ost sim's (log scale)")
    handles = {
        h.get_label(): h for ax in np.atleast_1d(axes) for h in ax.get_lines() if h.get_marker() == "o"
    }
    np.atleast_1d(axes)[-1].legend([handles[k] for k in labels], labels, fontsize=8)
    fig.suptitle("The cost of latency without a barrier (0 disagreements in every run)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ----------------------------------------------------------------------------- (c) CPU


def cpu() -> list[str]:
    lines = [
        "## (c) CPU of the realtime run in process",
        "",
        "| scenario | protocol | ost sim (default engine) | ost sim --engine step | realtime, L=0 | realtime, L=20:10 | network copies (L=20) |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for name, s in (
        ("demo N=10 M=20", generate_scenario(10, 20, 1)),
        ("N=50 M=200", generate_scenario(50, 200, 1)),
    ):
        for label in ("ccp CI=1", "ncp CI=1", "auction"):
            protocol, policy, _ = VARIANTS[label]
            t0 = time.process_time()
            simulate(s, protocol, policy, engine="auto")
            t1 = time.process_time()
            simulate(s, protocol, policy, engine="step")
            t2 = time.process_time()
            rt.run_realtime(s, protocol, policy)
            t3 = time.process_time()
            _, rep = rt.run_realtime(s, protocol, policy, latency=Latency(20, 10), seed=1)
            t4 = time.process_time()
            lines.append(
                f"| {name} | {label} | {t1 - t0:.2f} s | {t2 - t1:.2f} s | {t3 - t2:.2f} s | {t4 - t3:.2f} s | "
                f"{rep.copies} |"
            )
            print(lines[-1], flush=True)
    return lines + [""]


# ----------------------------------------------------------------------------- (d) improved


def improved(data: dict) -> list[str]:
    """The improved planner against the paper planner under latency, from (b)'s makespans."""
    lines = [
        "## (d) CCP's improved planner without a barrier",
        "",
        "Makespan of the improved planner against the paper planner's at the same latency (from "
        "(b); negative: the improved planner is faster). A carry waits until no re-plan it has "
        "not read can move it (docs/realtime.md), which costs it more the longer the latency.",
        "",
        "| scenario | CI | ost sim | " + " | ".join(f"L={L}" for L in LATENCIES) + " |",
        "|---|---|---:|" + "---:|" * len(LATENCIES),
    ]
    for name, label, *rest in list(data):
        if not rest or not label.startswith("ccp improved"):
            continue
        paper = data.get((name, label.replace("improved ", ""), "makespan"))
        mine = data[(name, label, "makespan")]
        if paper is None:
            continue
        cells = [f"{100 * (m - p) / p:+.1f} %" for m, p in zip(mine, paper)]
        lines.append(f"| {name} | {label.split('improved ')[1]} | " + " | ".join(cells) + " |")
    return lines + [""]


def tables(md: Path) -> dict:
    """(b)'s changes in % read back from a realtime.md this script wrote (to redraw its figure)."""
    data, name = {}, None
    for line in md.read_text().splitlines():
        if line.startswith("**") and line.endswith("**"):
            name = line.strip("*")
        elif name and line.startswith("| ") and "%" in line:
            cells = [c.strip() for c in line.strip("|").split("|")]
            if "(" in cells[-1]:
                data[(name, cells[0])] = [float(c.split("(")[1].split(" %")[0]) for c in cells[2:]]
    return data


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--redraw", metavar="MD", help="only redraw (b)'s figure from a realtime.md it wrote")
    p.add_argument("--runs", type=int, default=1000, help="random runs for (a) (1000)")
    p.add_argument("--seeds", type=int, default=3, help="latency seeds per cell of (b) (3)")
    p.add_argument(
        "--base-delay",
        type=float,
        default=0.0,
        metavar="D",
        help="(a) with every robot's base across a network, up to D + D steps away (as agent nodes)",
    )
    p.add_argument("--out", default="/tmp/ost_bench_realtime")
    p.add_argument("--docs", action="store_true", help="also write the figure to docs/images/")
    p.add_argument(
        "--variants", help="(a) and (b) only for these labels, comma-separated (default: all of VARIANTS)"
    )
    for part in ("agreement", "latency", "cpu"):
        p.add_argument(f"--skip-{part}", action="store_true")
    a = p.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.redraw:
        figure(tables(Path(a.redraw)), out / "realtime_latency.png")
        if a.docs:
            shutil.copy(out / "realtime_latency.png", REPO / "docs" / "images" / "realtime_latency.png")
        return
    lines = [
        "# Robots without a barrier: measurements",
        "",
        f"`benchmarks/bench_realtime.py`, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}.",
        "",
    ]
    if not a.skip_agreement:
        only = a.variants.split(",") if a.variants else None
        part = agreement(a.runs, seed=1, only=only, base_delay=a.base_delay)
        print("\n".join(part), flush=True)
        lines += part
    if not a.skip_latency:
        table, data = latency_table(a.seeds, set(a.variants.split(",")) if a.variants else None)
        lines += table
        fig = out / "realtime_latency.png"
        figure(data, fig)
        lines += [f"![makespan against latency]({fig.name})", ""]
        if a.docs:
            shutil.copy(fig, REPO / "docs" / "images" / fig.name)
        lines += improved(data)
    if not a.skip_cpu:
        lines += cpu()
    (out / "realtime.md").write_text("\n".join(lines))
    print("\n".join(lines))
    print(f"written: {out / 'realtime.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
