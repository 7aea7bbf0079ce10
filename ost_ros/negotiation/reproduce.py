"""``ost negotiate reproduce``: Fig. 4, Table 2, Tables 3–4, the §2.2 no-fly zone and the §5.1
mission, ours next to the paper's, written as CSVs, PNG plots and ``report.md``.

Runs are independent and seeded, so they are spread over a process pool; the result does not
depend on the number of workers or on completion order. Every number in the report is computed
from these runs (or from the paper's printed values, said so where it is).
"""

from __future__ import annotations

import csv
import math
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from .protocol import rubinstein_share
from .scenarios import (
    AREA_DELTA,
    FIG4_DELTAS,
    MISSION_DELTAS,
    TARGET_DELTA,
    PaperValues,
    claim_schedule,
    fig4,
    mission_run,
    nfz_run,
    offer_ratios,
    table2_run,
    target_run,
)
from .tasks import AreaTask

T2_METRICS = ("overlap_pct", "G", "covered_pct", "out_pct", "rounds")
T2_NAMES = ("overlap %", "G", "covered %", "out %", "rounds")
STOPPING_LABELS = {
    "paper": "paper: Eq. 3 test, exit option",
    "overlap": "overlap: ours before (2 % overlap exit, clipped claims)",
}
RULE_LABELS = {
    "furthest": "furthest (§4.2, the paper's)",
    "path": "path (§5.1)",
    "reward": "reward (ours before)",
}
TGT_R = TGT_N = tuple(range(2, 8))
AREA_R = (2, 3, 4, 5)


@dataclass(frozen=True)
class Plan:
    """How many runs of what: runs per Table 2 row and per Table 3/4 cell, no-fly-zone seeds,
    §5.1 layouts, the stopping rules (areas) and drop rules (targets) to compare."""

    area_runs: int
    target_runs: int
    nfz_runs: int
    layouts: int
    stoppings: tuple[str, ...]
    rules: tuple[str, ...]

    @classmethod
    def make(cls, quick: bool, runs: int | None) -> Plan:
        return cls(
            area_runs=runs if runs is not None else (2 if quick else 10),
            target_runs=runs if runs is not None else (3 if quick else 10),
            nfz_runs=3 if quick else 10,
            layouts=4 if quick else 20,
            stoppings=("paper",) if quick else ("paper", "overlap"),
            rules=("furthest",) if quick else ("furthest", "path", "reward"),
        )


def _job(kind: str, args: tuple) -> tuple[str, tuple, Any]:
    """Worker entry point (top level so it pickles)."""
    if kind == "t2":
        robots, stopping, seed = args
        return kind, args, table2_run(robots, seed, stopping=stopping)
    if kind == "tgt":
        n, robots, run, strategy, rule, seed = args
        return kind, args, target_run(n, robots, run, strategy=strategy, rule=rule, seed=seed)
    if kind == "nfz":
        return kind, args, nfz_run(args[0])
    if kind == "mission":
        layout, variant, seed = args
        return kind, args, mission_run(layout, MISSION_DELTAS[variant], seed)
    if kind == "fig4":
        res = fig4(args[0])
        task = res.task
        assert isinstance(task, AreaTask)
        return (
            kind,
            args,
            {
                "trace": res.trace,
                "shares": [list(res.task.encode(s)) for s in res.shares],
                "metrics": res.metrics(),
                "rounds": res.rounds,
                "status": res.status,
                "ratios": offer_ratios(task, res),
            },
        )
    raise ValueError(kind)


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    if not rows:
        return
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)


def run_jobs(jobs: list[tuple[str, tuple]], workers: int, progress: bool) -> dict:
    """Run every job; returns {(kind, args): result}. tqdm on stderr when asked."""
    from tqdm import tqdm

    results: dict = {}
    bar = tqdm(total=len(jobs), desc="negotiate reproduce", file=sys.stderr, disable=not progress)
    if workers <= 1:
        for kind, args in jobs:
            k, a, r = _job(kind, args)
            results[(k, a)] = r
            bar.update()
    else:
        # forkserver: the calling process may hold threads (tqdm, rclpy), so plain fork is unsafe
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("forkserver")) as pool:
            futs = [pool.submit(_job, kind, args) for kind, args in jobs]
            for f in as_completed(futs):
                k, a, r = f.result()
                results[(k, a)] = r
                bar.update()
    bar.close()
    return results


def reproduce(
    out: Path,
    quick: bool = False,
    seed: int = 0,
    runs: int | None = None,
    workers: int | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Run everything and write the report into ``out``. Returns a summary dict."""
    import matplotlib

    matplotlib.use("Agg")
    t_start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    cfg = Plan.make(quick, runs)
    workers = workers or min(2, os.cpu_count() or 1)

    jobs: list[tuple[str, tuple]] = []
    # longest first, so the pool stays busy to the end
    for r in sorted(AREA_R, reverse=True):
        for stop in cfg.stoppings:
            jobs += [("t2", (r, stop, seed + k)) for k in range(cfg.area_runs)]
    jobs.append(("fig4", (seed,)))
    jobs += [("nfz", (seed + k,)) for k in range(cfg.nfz_runs)]
    combos = [("rounds", rule) for rule in cfg.rules] + [("all-against-all", "furthest")]
    for strategy, rule in combos:
        jobs += [
            ("tgt", (n, r, k, strategy, rule, seed))
            for r in TGT_R
            for n in TGT_N
            for k in range(cfg.target_runs)
        ]
    jobs += [("mission", (lay, v, seed)) for lay in range(cfg.layouts) for v in range(2)]
    results = run_jobs(jobs, workers, progress)

    summary: dict[str, Any] = {"quick": quick, "seed": seed, "workers": workers, **asdict(cfg)}
    t2 = _table2(out, results, cfg, seed)
    t34 = _tables34(out, results, cfg, combos, seed)
    nfz = _nfz(out, results, cfg.nfz_runs, seed)
    missions = _missions(out, results, cfg.layouts, seed)
    fig4_res = results[("fig4", (seed,))]
    _fig4(out, fig4_res)
    _partitions(out, results, seed)
    summary["elapsed_s"] = time.perf_counter() - t_start
    summary["mad"] = {**t2["mad"], **t34["mad"]}
    _report(out, summary, fig4_res, t2, t34, nfz, missions)
    return summary


def _mean_sd_range(values: list[float]) -> tuple[float, float, float, float]:
    a = np.asarray(values, dtype=float)
    return float(a.mean()), float(a.std()), float(a.min()), float(a.max())


# ---------------------------------------------------------------- Table 2 ---------------------
def _table2(out: Path, results: dict, cfg: Plan, seed: int) -> dict:
    rows, cells = [], {}
    for stop in cfg.stoppings:
        for r in AREA_R:
            runs = [results[("t2", (r, stop, seed + k))] for k in range(cfg.area_runs)]
            rows += [{k: x[k] for k in x if k != "shares"} for x in runs]
            cell = {
                m: _mean_sd_range([x[m] for x in runs]) for m in (*T2_METRICS, "offer_ratio", "max_share")
            }
            cell["timeouts"] = sum(x["status"] != "agreed" for x in runs)
            cells[(stop, r)] = cell
    _write_csv(out / "table2_runs.csv", rows)
    table = []
    for (stop, r), c in cells.items():
        p = PaperValues.table2[r]
        table.append(
            {
                "stopping": stop,
                "R": r,
                **{f"{m}_mean": round(c[m][0], 4) for m in T2_METRICS},
                **{f"{m}_sd": round(c[m][1], 4) for m in T2_METRICS},
                **{f"{m}_paper": p[i] for i, m in enumerate(T2_METRICS)},
                "offer_ratio": round(c["offer_ratio"][0], 4),
                "timeouts": c["timeouts"],
            }
        )
    _write_csv(out / "table2.csv", table)
    mad = {}
    for stop in cfg.stoppings:
        for i, m in enumerate(T2_METRICS):
            diffs = [abs(cells[(stop, r)][m][0] - PaperValues.table2[r][i]) for r in AREA_R]
            mad[f"table2_{stop}_{m}"] = float(np.mean(diffs))
    return {"cells": cells, "table": table, "mad": mad}


# ---------------------------------------------------------------- Tables 3/4 ------------------
TGT_KEYS = ("excess_total_pct", "excess_max_pct", "excess_minmax_pct", "rounds", "messages")


def _tables34(out: Path, results: dict, cfg: Plan, combos: list, seed: int) -> dict:
    rows, cells = [], {}
    for strategy, rule in combos:
        for r in TGT_R:
            for n in TGT_N:
                runs = [results[("tgt", (n, r, k, strategy, rule, seed))] for k in range(cfg.target_runs)]
                rows += runs
                cell = {k: float(np.mean([x[k] for x in runs])) for k in TGT_KEYS}
                cell |= {f"{k}_sd": float(np.std([x[k] for x in runs])) for k in TGT_KEYS[:3]}
                cell["ok"] = all(
                    abs(x["G"] - n) < 1e-9 and x["overlap"] == 0 and x["status"] == "agreed" for x in runs
                )
                cells[(strategy, rule, r, n)] = cell
    _write_csv(out / "targets_runs.csv", rows)
    p3 = np.array([PaperValues.table3[r] for r in TGT_R])
    p4 = np.array([PaperValues.table4[r] for r in TGT_R])

    def grid(strategy: str, rule: str, key: str) -> np.ndarray:
        return np.array([[cells[(strategy, rule, r, n)][key] for n in TGT_N] for r in TGT_R])

    for name, key, paper in (
        ("table3", "excess_total_pct", p3),
        ("table4", "excess_max_pct", -p4),
        ("table4_minmax", "excess_minmax_pct", p4),
    ):
        g = grid("rounds", "furthest", key)
        _write_csv(
            out / f"{name}.csv",
            [
                {"R": r, **{f"N{n}_ours": round(g[i, j], 1) for j, n in enumerate(TGT_N)}}
                | {f"N{n}_paper": float(paper[i, j]) for j, n in enumerate(TGT_N)}
                for i, r in enumerate(TGT_R)
            ],
        )
    comp = []
    for strategy, rule in combos:
        t3, t4, t4m = (grid(strategy, rule, k) for k in TGT_KEYS[:3])
        comp.append(
            {
                "strategy": strategy,
                "rule": rule,
                "excess_total_pct": round(float(t3.mean()), 1),
                "excess_max_pct": round(float(t4.mean()), 1),
                "excess_minmax_pct": round(float(t4m.mean()), 1),
                "mad_table3": round(float(np.abs(t3 - p3).mean()), 1),
                "mad_table4": round(float(np.abs(t4 + p4).mean()), 1),
                "mad_table4_minmax": round(float(np.abs(t4m - p4).mean()), 1),
                "rounds": round(float(grid(strategy, rule, "rounds").mean()), 1),
                "messages": round(float(grid(strategy, rule, "messages").mean()), 1),
            }
        )
    _write_csv(out / "targets_rules.csv", comp)
    main = next(c for c in comp if c["strategy"] == "rounds" and c["rule"] == "furthest")
    mad = {
        "table3": main["mad_table3"],
        "table4": main["mad_table4"],
        "table4_minmax": main["mad_table4_minmax"],
    }
    return {"cells": cells, "comp": comp, "grid": grid, "p3": p3, "p4": p4, "mad": mad}


# ---------------------------------------------------------------- NFZ ---------------------------
def _nfz(out: Path, results: dict, n_nfz: int, seed: int) -> dict:
    runs = [results[("nfz", (seed + k,))] for k in range(n_nfz)]
    _write_csv(out / "nfz.csv", [{k: v for k, v in x.items() if k not in ("shares", "nfz")} for x in runs])
    import matplotlib.pyplot as plt

    from .scenarios import make_task_polygon

    fig, ax = plt.subplots(figsize=(5, 5.6))
    t0 = np.asarray(make_task_polygon(0.673).exterior.coords)
    ax.plot(t0[:, 0], t0[:, 1], "k-", lw=1, label="T0")
    for i, (sh, col) in enumerate(zip(runs[0]["shares"], ("tab:red", "tab:green"))):
        c = np.asarray(sh).reshape(-1, 2)
        ax.fill(c[:, 0], c[:, 1], color=col, alpha=0.45, label=f"S{i + 1} (robot {i + 1})")
    z = np.asarray(runs[0]["nfz"]).reshape(-1, 2)
    ax.fill(z[:, 0], z[:, 1], color="tab:blue", alpha=0.8, label="NFZ (robot 2 only)")
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    ax.set_title(f"§2.2 no-fly zone, seed {runs[0]['seed']:d}", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "nfz.png", dpi=120)
    plt.close(fig)
    return {"runs": runs}


# ---------------------------------------------------------------- §5.1 ---------------------------
def _missions(out: Path, results: dict, layouts: int, seed: int) -> dict:
    runs = [[results[("mission", (lay, v, seed))] for lay in range(layouts)] for v in range(2)]
    _write_csv(
        out / "missions.csv",
        [{k: (str(v) if isinstance(v, list) else v) for k, v in x.items()} for rs in runs for x in rs],
    )
    return {"runs": runs}


# ---------------------------------------------------------------- Fig. 4 ------------------------
def _fig4(out: Path, res: dict) -> None:
    import matplotlib.pyplot as plt

    trace = res["trace"]
    p1 = rubinstein_share(*FIG4_DELTAS)
    rows = [
        {
            "period": s["period"],
            "round": s["round"],
            "agent": s["agent"] + 1,
            "kind": s["kind"],
            "share_1": s["shares"][0],
            "share_2": s["shares"][1],
            "pred_1": s["predictions"][0],
            "pred_2": s["predictions"][1],
            "rubinstein_1": p1,
            "rubinstein_2": 1 - p1,
            "overlap": s["overlap"],
            "G": s["G"],
            "total_area": 0.74,
        }
        for s in trace
    ]
    _write_csv(out / "fig4_trace.csv", rows)
    per = [r["period"] for r in rows]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
    a.plot(per, [r["share_1"] for r in rows], "r-", label=f"agent 1 claim (δ={FIG4_DELTAS[0]})")
    a.plot(per, [r["share_2"] for r in rows], "b-", label=f"agent 2 claim (δ={FIG4_DELTAS[1]})")
    a.plot(
        per,
        [r["pred_1"] if r["pred_1"] is not None else np.nan for r in rows],
        "r:",
        label="agent 1 p̂ (Eq. 3)",
    )
    a.plot(per, [r["pred_2"] if r["pred_2"] is not None else np.nan for r in rows], "b:", label="agent 2 p̂")
    a.axhline(p1, color="r", ls="--", lw=0.8, label=f"Rubinstein p1={p1:.3f}")
    a.axhline(1 - p1, color="b", ls="--", lw=0.8, label=f"Rubinstein p2={1 - p1:.3f}")
    a.set_xlabel("period (offers)")
    a.set_ylabel("share of T0")
    a.legend(fontsize=7)
    b.plot(per, [r["overlap"] * 0.74 for r in rows], "m-", label="overlap dim(S1∩S2)")
    b.plot(per, [r["G"] for r in rows], "g-", label="global coverage G")
    b.axhline(0.74, color="k", ls="--", lw=0.8, label="dim(T0) = 0.74")
    b.set_xlabel("period (offers)")
    b.set_ylabel("area (task units)")
    b.legend(fontsize=7)
    fig.suptitle("Fig. 4 reproduced: two agents partition an area of 0.74", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "fig4.png", dpi=120)
    plt.close(fig)


def _partitions(out: Path, results: dict, seed: int) -> None:
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    from .scenarios import make_task_polygon

    t0 = np.asarray(make_task_polygon(0.673).exterior.coords)
    fig, axes = plt.subplots(1, len(AREA_R), figsize=(3.6 * len(AREA_R), 4.4))
    colours = [plt.get_cmap("tab10")(i) for i in range(10)]
    for ax, r in zip(axes, AREA_R):
        res = results[("t2", (r, "paper", seed))]
        ax.plot(t0[:, 0], t0[:, 1], "k-", lw=1.2)
        for i, sh in enumerate(res["shares"]):
            c = np.asarray(sh).reshape(-1, 2)
            if len(c):
                ax.fill(c[:, 0], c[:, 1], color=colours[i], alpha=0.5)
        ax.set_title(
            f"R = {r}: {res['rounds']} rounds\ncovered {res['covered_pct']:.1f} %, "
            f"overlap {res['overlap_pct']:.2f} %, out {res['out_pct']:.2f} %",
            fontsize=8,
        )
        ax.set_aspect("equal")
        ax.set_xlim(-0.05, 1.05)
        ax.set_ylim(-0.05, 1.05)
        ax.set_xlabel("x", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0].set_ylabel("y", fontsize=8)
    handles = [Patch(facecolor="none", edgecolor="k", label="T0")]
    handles += [Patch(color=colours[i], alpha=0.5, label=f"robot {i + 1}") for i in range(max(AREA_R))]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8)
    fig.suptitle(f"Table 2 runs, seed {seed}, paper stopping rule", fontsize=10)
    fig.tight_layout(rect=(0, 0.1, 1, 0.95))
    fig.savefig(out / "table2_partitions.png", dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------- report ------------------------
def _report(out: Path, summary: dict, fig4_res: dict, t2: dict, t34: dict, nfz: dict, missions: dict) -> None:
    L: list[str] = []
    add = L.append
    add("# Negotiation-based task subdivision and allocation — reproduction report\n")
    add(
        f"Rossi, Aldama, Barrientos (2015). Seed {summary['seed']}, "
        f"{'quick' if summary['quick'] else 'full'} run: {summary['area_runs']} runs per Table 2 row, "
        f"{summary['target_runs']} runs per Table 3/4 cell, {summary['nfz_runs']} no-fly-zone runs, "
        f"{summary['layouts']} §5.1 layouts, {summary['workers']} worker processes."
    )
    add(
        f"Wall time: **{summary['elapsed_s']:.1f} s** on {os.cpu_count()} cores "
        f"({platform.machine()}, Python {platform.python_version()}).\n"
    )
    _report_summary(add, summary)
    _report_fig4(add, fig4_res)
    _report_table2(add, t2, summary)
    _report_tables34(add, t34, summary)
    _report_nfz(add, nfz)
    _report_missions(add, missions, summary)
    (out / "report.md").write_text("\n".join(L) + "\n")


def _report_summary(add, summary: dict) -> None:
    mad = summary["mad"]
    add("## Ours vs the paper, in one line per table\n")
    add("Mean absolute difference between our cell means and the paper's printed values.\n")
    add("| table | reading | mean abs difference |")
    add("|---|---|---|")
    for stop in summary["stoppings"]:
        cols = ", ".join(f"{n} {mad[f'table2_{stop}_{m}']:.2f}" for m, n in zip(T2_METRICS, T2_NAMES))
        add(f"| 2 | stopping {STOPPING_LABELS[stop]} | {cols} |")
    add(f"| 3 | excess total distance, drop the furthest | {mad['table3']:.1f} points |")
    add(
        f"| 4 | negotiated longest route vs the minimum-total optimum's (paper's values read as negative) "
        f"| {mad['table4']:.1f} points |"
    )
    add(f"| 4 | other reading: vs the optimum of the longest route | {mad['table4_minmax']:.1f} points |")
    add("")


def _report_fig4(add, res: dict) -> None:
    p1 = rubinstein_share(*FIG4_DELTAS)
    fin = res["trace"][-1]
    ratios = res["ratios"]
    add(f"## Fig. 4 — two agents, δ1 = {FIG4_DELTAS[0]}, δ2 = {FIG4_DELTAS[1]}, area 0.74\n")
    add(
        f"Both open with the whole area. Final shares: agent 1 **{fin['shares'][0]:.3f}**, agent 2 "
        f"**{fin['shares'][1]:.3f}** of T0 after {res['rounds']} rounds (status {res['status']}); "
        f"Rubinstein (Eq. 2): {p1:.3f} / {1 - p1:.3f} (agent 1 {100 * (fin['shares'][0] - p1) / p1:+.1f} %). "
        f"Final overlap {100 * res['metrics']['overlap']:.2f} %, area out {100 * res['metrics']['out']:.2f} %, "
        f"G = {res['metrics']['G']:.3f} (dim T0 = 0.74); lowest G during the negotiation "
        f"{min(s['G'] for s in res['trace']):.3f}. Each offer was on average "
        f"{np.mean(ratios):.4f} × the same agent's previous one (δ = {FIG4_DELTAS[0]} / {FIG4_DELTAS[1]}; "
        f"range {min(ratios):.4f}–{max(ratios):.4f}).\n"
    )
    add("![Fig. 4](fig4.png)\n")
    add("Data: `fig4_trace.csv` (one row per offer).\n")


def _report_table2(add, t2: dict, summary: dict) -> None:
    add(f"## Table 2 — areas (dim T0 = 0.673, δ = {AREA_DELTA}, mean ± sd [min–max] over runs)\n")
    add(
        "Stopping rules: **paper** — each agent estimates δ̂ from the shrinking union of its negotiating "
        "partners' offers and is satisfied when the share they leave it reaches p̂ (Eq. 3), both as "
        "fractions of what is still being negotiated; satisfied, it accepts (two left) or leaves with that "
        "share (exit option); offers are polygons as the search makes them, so overlap and area outside "
        "T0 are measured, not excluded. "
        + (
            "**overlap** — our earlier rule, kept for the OST search areas: also leave once the own claim "
            "overlaps the others' by at most 2 % of T0, claims clipped to T0 (overlap and area out are 0 by "
            "construction).\n"
            if "overlap" in summary["stoppings"]
            else "\n"
        )
    )
    add(
        "| stopping | R | "
        + " | ".join(f"{n} (paper)" for n in T2_NAMES)
        + " | offer / previous | timeouts |"
    )
    add("|---|---|" + "---|" * (len(T2_NAMES) + 2))
    for (stop, r), c in t2["cells"].items():
        p = PaperValues.table2[r]
        fmt = ("{:.2f}", "{:.3f}", "{:.1f}", "{:.2f}", "{:.1f}")
        parts = [
            f"{fmt[i].format(c[m][0])} ± {fmt[i].format(c[m][1])} [{fmt[i].format(c[m][2])}–{fmt[i].format(c[m][3])}] ({p[i]})"
            for i, m in enumerate(T2_METRICS)
        ]
        add(f"| {stop} | {r} | " + " | ".join(parts) + f" | {c['offer_ratio'][0]:.4f} | {c['timeouts']} |")
    add("")
    paper_cells = [t2["cells"][("paper", r)] for r in AREA_R]
    # The offer that is finally accepted stays its proposer's share, so some claim shrank from the
    # whole task to at most the largest final share: at the measured ratio per own offer (one per
    # round) that takes at least ln(share)/ln(ratio) rounds.
    need = [
        math.ceil(math.log(c["max_share"][0]) / math.log(c["offer_ratio"][0]) - 1e-9) for c in paper_cells
    ]
    below = [r for r, n in zip(AREA_R, need) if PaperValues.table2[r][4] < n]
    add(
        f"Rounds: each offer is about δ = {AREA_DELTA} times the same agent's previous one (measured "
        + ", ".join(f"R = {r}: {c['offer_ratio'][0]:.4f}" for r, c in zip(AREA_R, paper_cells))
        + "). The accepted offer stays its proposer's share, so some claim shrank from the whole task to at "
        "most the largest final share (mean "
        + ", ".join(f"{c['max_share'][0]:.3f}" for c in paper_cells)
        + " of T0): at that ratio, at least "
        + ", ".join(str(n) for n in need)
        + " rounds."
        + (
            f" The paper's {', '.join(str(PaperValues.table2[r][4]) for r in below)} rounds for "
            f"R = {', '.join(str(r) for r in below)} are fewer than that."
            if below
            else ""
        )
        + "\n"
    )
    lower = sum(c["overlap_pct"][0] <= PaperValues.table2[r][0] for r, c in zip(AREA_R, paper_cells))
    out_ok = sum(c["out_pct"][0] <= 1.0 for c in paper_cells)
    add(
        f"With the paper's rule, overlap is at or below the paper's in {lower} of {len(AREA_R)} rows and area "
        f'out below the paper\'s "less than 1 %" in {out_ok} of {len(AREA_R)}; covered '
        + ", ".join(f"{c['covered_pct'][0]:.1f}" for c in paper_cells)
        + " % (paper "
        + ", ".join(str(PaperValues.table2[r][2]) for r in AREA_R)
        + ").\n"
    )
    add("![Table 2 partitions](table2_partitions.png)\n")


def _report_tables34(add, t34: dict, summary: dict) -> None:
    grid, p3, p4 = t34["grid"], t34["p3"], t34["p4"]
    t3 = grid("rounds", "furthest", "excess_total_pct")
    t4 = grid("rounds", "furthest", "excess_max_pct")
    t4m = grid("rounds", "furthest", "excess_minmax_pct")
    t3sd, t4sd, t4msd = (grid("rounds", "furthest", f"{k}_sd") for k in TGT_KEYS[:3])
    ok = all(t34["cells"][("rounds", "furthest", r, n)]["ok"] for r in TGT_R for n in TGT_N)
    head = "| R \\ N | " + " | ".join(str(n) for n in TGT_N) + " |"
    sep = "|---|" + "---|" * len(TGT_N)
    setup = (
        f"R robots at (0.5, 0), N random targets, rounds strategy, δ = {TARGET_DELTA}; each robot drops the "
        "furthest of the points it shares with someone (§4.2) when its claim passes the next integer. "
        "Distances are open routes; the optimum is exact (branch and bound over assignments, Held–Karp "
        "routes)."
    )
    add(
        "## Table 3 — targets, excess total distance vs the minimum-total optimum (%), ours "
        "(mean ± sd over runs) and the paper's\n"
    )
    add(setup + "\n")
    add(head)
    add(sep)
    for i, r in enumerate(TGT_R):
        add(
            f"| {r} | "
            + " | ".join(f"{t3[i, j]:.1f} ± {t3sd[i, j]:.1f} ({p3[i, j]})" for j in range(len(TGT_N)))
            + " |"
        )
    add(
        f"\nOurs ≤ paper in {int((t3 <= p3).sum())} of {t3.size} cells; every run ends with G = N, no point "
        f"claimed twice and every robot agreed: {'yes' if ok else '**no**'}."
    )
    over = [(r, TGT_N[0], p3[i, 0]) for i, r in enumerate(TGT_R) if p3[i, 0] > 100]
    if over:
        add(
            "\nWith every robot at one start, splitting N = 2 targets costs at most twice the optimum (each "
            "robot's route is at most the distance to the further point, which the optimum covers too), so an "
            "excess above 100 % cannot occur there; the paper prints "
            + ", ".join(f"{v} (R = {r})" for r, _, v in over)
            + " for N = 2 — its robots cannot all have started at one point, or its distances were measured "
            "otherwise."
        )
    add("")
    add(
        "## Table 4 — targets, maximum individual distance (%), ours (mean ± sd over runs) and the paper's\n\n"
        'The paper: "Table 4 shows how the maximum individual distance travelled improves in the case of '
        'the distributed solution" against an optimum that "may imply that one of a few robots do most of '
        'the work". Read so, each cell compares the negotiated longest route with the longest route of the '
        "minimum-total optimum; negative means the negotiation spreads the work better. The extraction "
        "drops minus signs, so the paper's values are shown negative. Beside it, the other reading: against "
        "the allocation that minimises the longest route itself (never negative).\n"
    )
    for title, g, gsd, paper in (
        ("against the minimum-total optimum's longest route, ours (paper, read as negative)", t4, t4sd, -p4),
        ("other reading: against the min-max optimum, ours (paper as printed)", t4m, t4msd, p4),
    ):
        add(f"{title}:\n")
        add(head)
        add(sep)
        for i, r in enumerate(TGT_R):
            add(
                f"| {r} | "
                + " | ".join(f"{g[i, j]:.1f} ± {gsd[i, j]:.1f} ({paper[i, j]})" for j in range(len(TGT_N)))
                + " |"
            )
        add("")
    add(
        f"\nThe negotiated longest route is shorter than the minimum-total optimum's in {int((t4 < 0).sum())} of "
        f"{t4.size} cells (mean {t4.mean():.1f} %, paper read as negative {-p4.mean():.1f} %); against the "
        f"min-max optimum it is {t4m.mean():.1f} % longer on average (paper as printed {p4.mean():.1f} %).\n"
    )
    add("### Drop rules and strategies (targets, mean over the 36 cells)\n")
    add(
        "| strategy | drop rule | excess total % | longest vs min-total % | longest vs min-max % | "
        "|ours − paper| Table 3 | Table 4 | Table 4 (min-max) | rounds | messages |"
    )
    add("|---|---|---|---|---|---|---|---|---|---|")
    for c in t34["comp"]:
        add(
            f"| {c['strategy']} | {RULE_LABELS[c['rule']]} | {c['excess_total_pct']} | {c['excess_max_pct']} | "
            f"{c['excess_minmax_pct']} | {c['mad_table3']} | {c['mad_table4']} | {c['mad_table4_minmax']} | "
            f"{c['rounds']} | {c['messages']} |"
        )
    best = min(t34["comp"], key=lambda c: c["mad_table3"])
    add(
        f"\nClosest to the paper's Table 3: {best['strategy']} with {RULE_LABELS[best['rule']]} "
        f"(mean |ours − paper| {best['mad_table3']}). Data: `targets_runs.csv`, `targets_rules.csv`.\n"
    )


def _report_nfz(add, nfz: dict) -> None:
    runs = nfz["runs"]
    worst = max(x["nfz_in_S2"] for x in runs)
    s1, s2, rounds = (_mean_sd_range([x[k] for x in runs]) for k in ("dim_S1", "dim_S2", "rounds"))
    add("## §2.2 — the no-fly zone\n")
    add(
        f"Robot 2 (δ = {FIG4_DELTAS[1]}) may not fly over a 0.03 zone on T0's edge; robot 1 (δ = {FIG4_DELTAS[0]}) "
        f"does not know it. Weights α = β = γ = 1, λ = 1000, no ill-shape term. Opening claims: robot 1 "
        f"{100 * np.mean([x['open_S1'] for x in runs]):.1f} % of T0, robot 2 "
        f"{100 * np.mean([x['open_S2'] for x in runs]):.1f} % (all it may take). Over {len(runs)} seeds: "
        f"NFZ area given to robot 2: max **{worst:.2e}**; NFZ with robot 1 in "
        f"{sum(x['nfz_in_S1'] > 0.029 for x in runs)} runs; all agreed: "
        f"{'yes' if all(x['status'] == 'agreed' for x in runs) else '**no**'}.\n"
    )
    add("| | mean | sd | min | max | paper |")
    add("|---|---|---|---|---|---|")
    add(f"| dim(S1) | {s1[0]:.3f} | {s1[1]:.3f} | {s1[2]:.3f} | {s1[3]:.3f} | 0.409 |")
    add(f"| dim(S2) | {s2[0]:.3f} | {s2[1]:.3f} | {s2[2]:.3f} | {s2[3]:.3f} | 0.259 |")
    add(f"| rounds | {rounds[0]:.1f} | {rounds[1]:.1f} | {rounds[2]:.0f} | {rounds[3]:.0f} | – |")
    add(
        f"\nG = {np.mean([x['G'] for x in runs]):.3f} (paper 0.668, optimum 0.673); robot 2's value of robot "
        f"1's share (with the NFZ) g2(S1) = {np.mean([x['g2_S1'] for x in runs]):.2f}.\n"
    )
    add("![NFZ](nfz.png)\n")


def _report_missions(add, missions: dict, summary: dict) -> None:
    a, b = missions["runs"]
    same = sum(x["targets"] == y["targets"] for x, y in zip(a, b))
    n = len(a)
    offers = max(x["rounds"] for x in a + b) + 1
    sched = {d: claim_schedule(d, 5, offers) for d in sorted(set(MISSION_DELTAS[0]), reverse=True)}
    d2, d3 = MISSION_DELTAS[0][1], MISSION_DELTAS[0][2]
    first_diff = next((t for t in range(offers) if sched[d2][t] != sched[d3][t]), None)
    add("## §5.1 — three robots, five targets (the mission of Fig. 6)\n")
    add(
        "Three robots 1 m apart in the centre of a 15×15 m field, five random targets per layout, "
        "g_i = dim(S_i) − Σ overlap − p(S_i) with the shortest path p, and the §5.1 update (drop the point "
        "that shortens the path most); δ = "
        + " / ".join(f"{d:g}" for d in MISSION_DELTAS[0])
        + " (Fig. 6 left) and "
        + " / ".join(f"{d:g}" for d in MISSION_DELTAS[1])
        + f" (right). The paper's field, robot and target positions are not printed; ours are seeded ({n} layouts).\n"
    )
    for name, runs in (("left", a), ("right", b)):
        ex = _mean_sd_range([x["excess_pct"] for x in runs])
        counts = np.mean([x["counts"] for x in runs], axis=0)
        add(
            f"- Fig. 6 {name}: total distance {np.mean([x['total_m'] for x in runs]):.2f} m against the optimum "
            f"{np.mean([x['opt_total_m'] for x in runs]):.2f} m, {ex[0]:.1f} % longer (range "
            f"{ex[2]:.1f}–{ex[3]:.1f} %; paper 17.87 / 18.01 m vs 15.58 m, about 15 %); targets per robot "
            + " / ".join(f"{c:.2f}" for c in counts)
            + "."
        )
    add(
        f"\nSwapping δ2 and δ3 leaves the allocation unchanged in {same} of {n} layouts. The claim a robot may "
        f"make is ⌊δ^t·5⌋ points at its t-th offer: "
        + "; ".join(f"δ = {d:g}: {' '.join(str(v) for v in s)}" for d, s in sched.items())
        + ". "
        + (
            f"δ = {d2:g} and δ = {d3:g} allow the same counts up to offer {first_diff}, "
            f"and no negotiation here lasted more than {offers - 1} rounds"
            if first_diff is not None
            else f"δ = {d2:g} and δ = {d3:g} allow the same counts for all {offers} offers"
        )
        + ", so with the §4.2 update, where δ only sets when a point is dropped, the two robots concede at the "
        'same moments and the paper\'s "the most impatient gives up earlier" cannot show. It needs a rule in '
        "which δ enters otherwise (a continuous share, or Rubinstein's test of §3.2.1), which §5.1 does not "
        "give.\n"
    )
    add(
        "§5.2 (aerial survey) and §5.3 (box pushing) are not reproduced: the text gives the field's size "
        "(≈330×200 m, 10×10 cells) and the robots' kinds but no polygon, no rewards and no results to compare "
        "with, and refers to [4] and [3] for them.\n"
    )
