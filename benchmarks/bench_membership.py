"""Who is in the team, measured in process (ost_ros.realtime.membership):

    .venv/bin/python benchmarks/bench_membership.py [--runs 1000] [--seed0 0] [--out DIR]

(a) promises: ``--runs`` random small runs mixing every protocol that runs without a barrier,
    latencies and jitter up to 50 steps, unequal speeds (speed noise), stalls, kills, silences
    shorter and longer than the failure timeout (5, 20 or 60 steps), joins and partitions — disagreements
    (must be 0), objects not delivered by their n_i robots while enough robots live, deadlocks,
    robots out at the end that had work left (must be 0: nobody leaves);
(b) cost: the demo scenario (N=10, M=20, 500×200) at latency 5:5 — the makespan with one robot
    silent for less than the timeout, silent past it (declared out, back when it runs again),
    joining late, the team split in halves, against the same run without the fault (three
    latency seeds each).

Writes ``membership.md`` into --out (default /tmp/ost_bench_membership); every figure in it is
computed from the runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import random
import statistics
import sys
import time
from pathlib import Path

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.protocols.ccp import CcpSettings
from ost_ros.realtime.net import Latency, Split
from ost_ros.realtime.run import run_realtime
from ost_ros.scenario import generate_scenario


def random_case(seed: int):
    """One random run: a small scenario, a protocol and a mix of faults on all robots but one."""
    rnd = random.Random(seed)
    n, m = rnd.randint(2, 6), rnd.randint(0, 7)
    grid = Grid(rnd.randint(max(4, n), 30), rnd.randint(max(3, n), 20))  # (room for n search areas)
    s = generate_scenario(n, m, seed, grid, nmax=min(n, 3))
    protocol = rnd.choice(["ccp", "ccp", "ccp-coordinator", "ncp", "auction", "ccp-improved", "greedy"])
    policy = CoordinationPolicy(ci=rnd.choice([1, 2, 5]))
    settings = None
    if protocol == "ccp-coordinator":
        protocol, policy = "ccp", dataclasses.replace(policy, organisation="coordinator")
    if protocol == "ccp-improved":
        organisation = rnd.choice(["distributed", "coordinator"])
        protocol, policy = "ccp", dataclasses.replace(policy, organisation=organisation)
        settings = CcpSettings(planner="improved")
    if protocol == "auction":
        policy = CoordinationPolicy()
    ids = [a.id for a in s.agents]
    rnd.shuffle(ids)
    kills: dict[int, int] = {}
    silences: list[tuple[int, float, float]] = []
    joins: dict[int, float] = {}
    for a in ids[1:]:
        kind = rnd.choice(["none", "kill", "silence", "silence", "join"])
        if kind == "kill":
            kills[a] = rnd.randint(0, 200)
        elif kind == "silence":
            for _ in range(rnd.randint(1, 2)):
                silences.append((a, float(rnd.randint(0, 300)), float(rnd.randint(1, 120))))
        elif kind == "join":
            joins[a] = float(rnd.randint(1, 300))
    kw = {
        "settings": settings,
        "latency": Latency(rnd.randint(0, 50), rnd.randint(0, 50)),
        "seed": rnd.randint(0, 10**6),
        "speed_jitter": rnd.choice([0.0, 0.3]),
        "failures": kills,
        "silences": silences,
        "joins": joins,
        "failure_timeout": float(rnd.choice([5, 20, 60])),
    }
    if rnd.random() < 0.3:
        kw["stalls"] = [(rnd.choice([a.id for a in s.agents]), rnd.randint(0, 150), rnd.randint(1, 80))]
    if rnd.random() < 0.3 and n >= 2:  # a partition: robots shuffled into two groups
        cut = rnd.randint(1, n - 1)
        order = [a.id for a in s.agents]
        rnd.shuffle(order)
        groups = (frozenset(order[:cut]), frozenset(order[cut:]))
        start, steps = float(rnd.randint(0, 300)), float(rnd.randint(1, 300))
        kw["splits"] = [Split(groups, start, steps, lost=rnd.random() < 0.5)]  # held or lost
    return s, protocol, policy, kw


def judge(s, r, report, dead) -> list[str]:
    """What broke a promise in one run (empty: none)."""
    bad = []
    survivors = s.n_agents - len(dead)
    if report.disagreements or not r.agreement:
        bad.append("disagreement")
    for o, spec in zip(r.objects, s.objects):
        if spec.required <= survivors and o.delivered is None:
            bad.append(f"object {spec.id} not delivered ({r.error})")
        if o.delivered is not None and len(set(o.agents)) != spec.required:
            bad.append(f"object {spec.id} carried by {o.agents}")
    if r.error and "deadlock" in r.error:
        bad.append("deadlock")
    if any(r.agents[a].finished is None for a in report.out_at_end):
        bad.append(f"robots {report.out_at_end} out at the end with work left")
    if r.warnings or r.rejections:
        bad.append(f"warnings {r.warnings[:2]} {r.rejections[:2]}")
    return bad


def promises(runs: int, seed0: int) -> dict:
    tally = {"runs": 0, "broken": 0, "declared": 0, "rejoins": 0, "joins": 0, "kills": 0, "silences": 0}
    tally["splits"] = tally["lost"] = 0
    by_protocol: dict[str, int] = {}
    failures = []
    heals: list[float] = []
    t0 = time.monotonic()
    for k, seed in enumerate(range(seed0, seed0 + runs)):
        s, protocol, policy, kw = random_case(seed)
        name = f"{protocol}-{policy.organisation}" if protocol == "ccp" else protocol
        by_protocol[name] = by_protocol.get(name, 0) + 1
        try:
            r, report = run_realtime(s, protocol, policy, **kw)
            bad = judge(s, r, report, kw["failures"])
        except Exception as exc:  # a crash is a broken promise too: say which run
            bad, report = [f"{type(exc).__name__}: {str(exc)[:200]}"], None
        if report is not None:
            tally["declared"] += report.declared
            tally["rejoins"] += report.rejoins
            heals.extend(h for h in report.healed if h is not None)
        tally["runs"] += 1
        tally["joins"] += len(kw["joins"])
        tally["kills"] += len(kw["failures"])
        tally["silences"] += len(kw["silences"])
        tally["splits"] += len(kw.get("splits", ()))
        tally["lost"] += sum(sp.lost for sp in kw.get("splits", ()))
        if bad:
            tally["broken"] += 1
            failures.append(f"seed {seed} ({name}): {'; '.join(bad)}")
            print(f"  {failures[-1]}", file=sys.stderr)
        if (k + 1) % 50 == 0:
            print(
                f"  {k + 1}/{runs} runs, {tally['broken']} broken, {time.monotonic() - t0:.0f} s",
                file=sys.stderr,
            )
    return {"tally": tally, "protocols": by_protocol, "failures": failures, "heals": sorted(heals)}


HALVES = (frozenset(range(5)), frozenset(range(5, 10)))


def costs(seeds=(1, 2, 3)) -> list[tuple[str, list[float]]]:
    """Makespan of the demo at latency 5:5 with one fault, relative to the run without it."""
    s = generate_scenario(10, 20, 1)  # the demo's scenario
    policy = CoordinationPolicy()
    faults = [
        ("silent 5 steps (timeout 10)", {"silences": [(3, 200.0, 5.0)]}),
        ("silent 50 steps: out and back", {"silences": [(3, 200.0, 50.0)]}),
        ("silent 300 steps: out and back", {"silences": [(3, 200.0, 300.0)]}),
        ("joins at step 300", {"joins": {3: 300.0}}),
        ("partition 0–4 / 5–9 for 100 steps (held)", {"splits": [Split(HALVES, 200.0, 100.0)]}),
        ("partition 0–4 / 5–9 for 1000 steps (held)", {"splits": [Split(HALVES, 200.0, 1000.0)]}),
        ("partition 0–4 / 5–9 for 5000 steps (held)", {"splits": [Split(HALVES, 200.0, 5000.0)]}),
        ("partition 0–4 / 5–9 for 1000 steps (lost)", {"splits": [Split(HALVES, 200.0, 1000.0, lost=True)]}),
    ]
    rows = []
    for label, kw in faults:
        ratios = []
        for seed in seeds:
            base, _ = run_realtime(s, "ccp", policy, latency=Latency(5, 5), seed=seed)
            r, rep = run_realtime(s, "ccp", policy, latency=Latency(5, 5), seed=seed, **kw)
            if not (r.completed and base.completed and rep.disagreements == 0):
                raise SystemExit(f"{label}, seed {seed}: not completed or disagreed ({r.error})")
            ratios.append(r.makespan / base.makespan - 1)
        rows.append((label, ratios))
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--out", default="/tmp/ost_bench_membership")
    ap.add_argument("--skip-cost", action="store_true")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    p = promises(a.runs, a.seed0)
    t = p["tally"]
    lines = [
        "# Membership in process (benchmarks/bench_membership.py)",
        "",
        f"{t['runs']} random runs (seeds {a.seed0}..{a.seed0 + a.runs - 1}; "
        + ", ".join(f"{k} {v}" for k, v in sorted(p["protocols"].items()))
        + f"): {t['silences']} silences, {t['kills']} kills, {t['joins']} joins, "
        f"{t['splits']} partitions ({t['lost']} of them losing what crossed them; 1–300 steps); "
        f"{t['declared']} robots declared out, {t['rejoins']} readmissions. "
        f"Runs that broke a promise: {t['broken']}.",
        "",
    ]
    heals = p["heals"]
    if heals:
        p99 = heals[min(len(heals) - 1, int(0.99 * len(heals)))]
        lines.append(
            f"From a partition's heal until every robot had taken the last batch stamped before it: median "
            f"{statistics.median(heals):g} steps, p99 {p99:g}, max {heals[-1]:g} ({len(heals)} partitions; "
            "latency and jitter up to 50 steps each)."
        )
        lines.append("")
    lines += [f"- {f}" for f in p["failures"][:20]]
    if not a.skip_cost:
        lines += [
            "",
            "| demo (N=10, M=20), latency 5:5, robot 3 | makespan vs no fault, 3 seeds |",
            "|---|---|",
        ]
        for label, ratios in costs():
            lines.append(
                f"| {label} | {statistics.mean(ratios):+.1%} ("
                + ", ".join(f"{x:+.1%}" for x in ratios)
                + ") |"
            )
    text = "\n".join(lines) + "\n"
    (out / "membership.md").write_text(text)
    print(text)
    return 1 if t["broken"] else 0


if __name__ == "__main__":
    sys.exit(main())
