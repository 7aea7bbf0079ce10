"""``ost negotiate reproduce``: Fig. 4, Table 2, Tables 3–4 and the §2.2 no-fly-zone example,
ours next to the paper's, written as CSVs, PNG plots and ``report.md``.

Runs are independent and seeded, so they are spread over a process pool; the result does not
depend on the number of workers or on completion order.
"""

from __future__ import annotations

import csv
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from .proposals import AreaSearch
from .protocol import rubinstein_share
from .scenarios import FIG4_DELTAS, TARGET_DELTA, PaperValues, fig4, nfz_run, table2_run, target_run

AREA_VARIANTS = {"strict": AreaSearch(min_scale=1.0), "undercut": AreaSearch(min_scale=0.9)}
T2_METRICS = ("overlap_pct", "G", "covered_pct", "out_pct", "rounds")


def _job(kind: str, args: tuple) -> tuple[str, tuple, Any]:
    """Worker entry point (top level so it pickles)."""
    if kind == "t2":
        robots, variant, seed = args
        return kind, args, table2_run(robots, seed, AREA_VARIANTS[variant])
    if kind == "tgt":
        n, robots, run, strategy, seed = args
        return kind, args, target_run(n, robots, run, strategy=strategy, seed=seed)
    if kind == "nfz":
        return kind, args, nfz_run(args[0])
    if kind == "fig4":
        res = fig4(args[0])
        return (
            kind,
            args,
            {
                "trace": res.trace,
                "shares": [list(res.task.encode(s)) for s in res.shares],
                "metrics": res.metrics(),
                "rounds": res.rounds,
                "status": res.status,
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
    n_area = runs if runs is not None else (2 if quick else 10)
    n_tgt = runs if runs is not None else (3 if quick else 10)
    n_nfz = 3 if quick else 10
    workers = workers or min(2, os.cpu_count() or 1)
    area_r, tgt_r, tgt_n = (2, 3, 4, 5), range(2, 8), range(2, 8)
    variants = ("strict",) if quick else ("strict", "undercut")

    jobs: list[tuple[str, tuple]] = []
    # longest first, so the pool stays busy to the end
    for r in sorted(area_r, reverse=True):
        for v in variants:
            jobs += [("t2", (r, v, seed + k)) for k in range(n_area)]
    jobs.append(("fig4", (seed,)))
    jobs += [("nfz", (seed + k,)) for k in range(n_nfz)]
    for strategy in ("rounds", "all-against-all"):
        jobs += [("tgt", (n, r, k, strategy, seed)) for r in tgt_r for n in tgt_n for k in range(n_tgt)]
    results = run_jobs(jobs, workers, progress)
    elapsed = time.perf_counter() - t_start

    summary = {
        "elapsed_s": elapsed,
        "quick": quick,
        "seed": seed,
        "area_runs": n_area,
        "target_runs": n_tgt,
        "workers": workers,
    }
    fig4_res = results[("fig4", (seed,))]
    t2 = _table2(out, results, variants, area_r, n_area, seed)
    t34 = _tables34(out, results, tgt_r, tgt_n, n_tgt, seed)
    nfz = _nfz(out, results, n_nfz, seed)
    _fig4(out, fig4_res)
    _partitions(out, results, area_r, seed)
    _report(out, summary, fig4_res, t2, t34, nfz, variants)
    summary["elapsed_s"] = time.perf_counter() - t_start
    return summary


# ---------------------------------------------------------------- Table 2 ---------------------
def _table2(out: Path, results: dict, variants, area_r, n_area: int, seed: int) -> dict:
    rows, summary = [], {}
    for v in variants:
        for r in area_r:
            runs = [results[("t2", (r, v, seed + k))] for k in range(n_area)]
            rows += [{"variant": v, **{k: x[k] for k in x if k != "shares"}} for x in runs]
            summary[(v, r)] = {
                m: (float(np.mean([x[m] for x in runs])), float(np.std([x[m] for x in runs])))
                for m in T2_METRICS
            }
            summary[(v, r)]["timeouts"] = sum(x["status"] != "agreed" for x in runs)
    _write_csv(out / "table2_runs.csv", rows)
    table = []
    for (v, r), s in summary.items():
        p = PaperValues.table2[r]
        table.append(
            {
                "variant": v,
                "R": r,
                **{f"{m}_ours": round(s[m][0], 4) for m in T2_METRICS},
                **{f"{m}_paper": p[i] for i, m in enumerate(T2_METRICS)},
                "coverage_ok": s["covered_pct"][0] >= p[2],
                "overlap_ok": s["overlap_pct"][0] <= p[0],
                "rounds_ok": s["rounds"][0] <= p[4],
                "timeouts": s["timeouts"],
            }
        )
    _write_csv(out / "table2.csv", table)
    return {"summary": summary, "table": table}


# ---------------------------------------------------------------- Tables 3/4 ------------------
def _tables34(out: Path, results: dict, tgt_r, tgt_n, n_tgt: int, seed: int) -> dict:
    rows = []
    cells: dict = {}
    for strategy in ("rounds", "all-against-all"):
        for r in tgt_r:
            for n in tgt_n:
                runs = [results[("tgt", (n, r, k, strategy, seed))] for k in range(n_tgt)]
                rows += runs
                cells[(strategy, r, n)] = {
                    "total": float(np.mean([x["excess_total_pct"] for x in runs])),
                    "max": float(np.mean([x["excess_max_pct"] for x in runs])),
                    "rounds": float(np.mean([x["rounds"] for x in runs])),
                    "messages": float(np.mean([x["messages"] for x in runs])),
                    "G_is_N": all(abs(x["G"] - n) < 1e-9 for x in runs),
                    "overlap": max(x["overlap"] for x in runs),
                    "agreed": all(x["status"] == "agreed" for x in runs),
                }
    _write_csv(out / "targets_runs.csv", rows)
    for name, key, paper in (("table3", "total", PaperValues.table3), ("table4", "max", PaperValues.table4)):
        tab = []
        for r in tgt_r:
            row = {"R": r}
            for n in tgt_n:
                row[f"N{n}_ours"] = round(cells[("rounds", r, n)][key], 1)
                row[f"N{n}_paper"] = paper[r][n - 2]
            tab.append(row)
        _write_csv(out / f"{name}.csv", tab)
    comp = []
    for r in tgt_r:
        for strategy in ("rounds", "all-against-all"):
            cs = [cells[(strategy, r, n)] for n in tgt_n]
            comp.append(
                {
                    "R": r,
                    "strategy": strategy,
                    "excess_total_pct": round(float(np.mean([c["total"] for c in cs])), 1),
                    "excess_max_pct": round(float(np.mean([c["max"] for c in cs])), 1),
                    "rounds": round(float(np.mean([c["rounds"] for c in cs])), 1),
                    "messages": round(float(np.mean([c["messages"] for c in cs])), 1),
                }
            )
    _write_csv(out / "targets_strategies.csv", comp)
    return {"cells": cells, "strategies": comp}


# ---------------------------------------------------------------- NFZ ---------------------------
def _nfz(out: Path, results: dict, n_nfz: int, seed: int) -> dict:
    runs = [results[("nfz", (seed + k,))] for k in range(n_nfz)]
    _write_csv(out / "nfz.csv", [{k: v for k, v in x.items() if k not in ("shares", "nfz")} for x in runs])
    import matplotlib.pyplot as plt

    from .scenarios import make_task_polygon

    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    t0 = np.asarray(make_task_polygon(0.673).exterior.coords)
    ax.plot(t0[:, 0], t0[:, 1], "k-", lw=1, label="T0")
    for i, (sh, col) in enumerate(zip(runs[0]["shares"], ("tab:red", "tab:green"))):
        c = np.asarray(sh).reshape(-1, 2)
        ax.fill(c[:, 0], c[:, 1], color=col, alpha=0.45, label=f"S{i + 1} (robot {i + 1})")
    z = np.asarray(runs[0]["nfz"]).reshape(-1, 2)
    ax.fill(z[:, 0], z[:, 1], color="tab:blue", alpha=0.8, label="NFZ (robot 2 only)")
    ax.set_aspect("equal")
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title(f"§2.2 no-fly zone, seed {runs[0]['seed']:d}", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "nfz.png", dpi=120)
    plt.close(fig)
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
    a.plot(per, [r["share_1"] for r in rows], "r-", label="agent 1 claim (δ=0.95)")
    a.plot(per, [r["share_2"] for r in rows], "b-", label="agent 2 claim (δ=0.955)")
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
    b.legend(fontsize=7)
    fig.suptitle("Fig. 4 reproduced: two agents partition an area of 0.74", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "fig4.png", dpi=120)
    plt.close(fig)


def _partitions(out: Path, results: dict, area_r, seed: int) -> None:
    import matplotlib.pyplot as plt

    from .scenarios import make_task_polygon

    t0 = np.asarray(make_task_polygon(0.673).exterior.coords)
    fig, axes = plt.subplots(1, len(area_r), figsize=(3.2 * len(area_r), 3.3))
    for ax, r in zip(axes, area_r):
        res = results[("t2", (r, "strict", seed))]
        ax.plot(t0[:, 0], t0[:, 1], "k-", lw=1)
        for sh in res["shares"]:
            c = np.asarray(sh).reshape(-1, 2)
            if len(c):
                ax.fill(c[:, 0], c[:, 1], alpha=0.5)
        ax.set_title(f"R={r}: covered {res['covered_pct']:.1f} %, {res['rounds']} rounds", fontsize=8)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(out / "table2_partitions.png", dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------- report ------------------------
def _yes(ok: bool) -> str:
    return "yes" if ok else "**no**"


def _report(out: Path, summary: dict, fig4_res: dict, t2: dict, t34: dict, nfz: dict, variants) -> None:
    L: list[str] = []
    add = L.append
    p1 = rubinstein_share(*FIG4_DELTAS)
    add("# Negotiation-based task subdivision and allocation — reproduction report\n")
    add(
        f"Rossi, Aldama, Barrientos (2015). Seed {summary['seed']}, "
        f"{'quick' if summary['quick'] else 'full'} run: {summary['area_runs']} runs per Table 2 row, "
        f"{summary['target_runs']} runs per Table 3/4 cell, {summary['workers']} worker processes."
    )
    add(
        f"Wall time of the negotiations: **{summary['elapsed_s']:.1f} s** on {os.cpu_count()} cores "
        f"({platform.machine()}, Python {platform.python_version()}).\n"
    )

    add("## Fig. 4 — two agents, δ1 = 0.95, δ2 = 0.955, area 0.74\n")
    fin = fig4_res["trace"][-1]
    add(
        f"Final shares: agent 1 **{fin['shares'][0]:.3f}**, agent 2 **{fin['shares'][1]:.3f}** of T0 after "
        f"{fig4_res['rounds']} rounds (status {fig4_res['status']}); Rubinstein (Eq. 2): {p1:.3f} / {1 - p1:.3f} "
        f"(deviation {100 * (fin['shares'][0] - p1) / p1:+.1f} % for agent 1). Final overlap "
        f"{100 * fig4_res['metrics']['overlap']:.2f} %, G = {fig4_res['metrics']['G']:.3f} (optimum 0.74). "
        f"Minimum G over the negotiation: {min(s['G'] for s in fig4_res['trace']):.3f}.\n"
    )
    add("![Fig. 4](fig4.png)\n")
    add("Data: `fig4_trace.csv` (one row per offer).\n")

    add("## Table 2 — areas (dim T0 = 0.673, δ = 0.98, mean over runs)\n")
    add(
        "Variants: **strict** — each offer's share of T0 is exactly δ × the previous one (the size rule of "
        "§3.2.1, which Rubinstein's prediction needs); **undercut** — the search may claim up to 10 % less "
        "than that cap when it pays (the paper allows the rule to be broken in practice).\n"
    )
    add(
        "| variant | R | overlap % (paper) | G (paper) | covered % (paper) | out % (paper) | rounds (paper) "
        "| coverage ≥ | overlap ≤ | rounds ≤ |"
    )
    add("|---|---|---|---|---|---|---|---|---|---|")
    for row in t2["table"]:
        add(
            f"| {row['variant']} | {row['R']} | {row['overlap_pct_ours']:.2f} ({row['overlap_pct_paper']}) "
            f"| {row['G_ours']:.3f} ({row['G_paper']}) | {row['covered_pct_ours']:.1f} ({row['covered_pct_paper']}) "
            f"| {row['out_pct_ours']:.2f} ({row['out_pct_paper']}) | {row['rounds_ours']:.1f} ({row['rounds_paper']}) "
            f"| {_yes(row['coverage_ok'])} | {_yes(row['overlap_ok'])} | {_yes(row['rounds_ok'])} |"
        )
    bad = [r for r in t2["table"] if not r["rounds_ok"]]
    add("")
    if bad:
        add(
            "Where rounds exceed the paper's: with the strict size rule a claim after k rounds is 0.98^k of "
            "T0, and claims stop overlapping only when they are about 1/R of T0 (R = 2: Rubinstein's "
            "share ≈ 0.5), so at least ln(1/R)/ln(0.98) ≈ 34, 54, 69, 80 rounds are needed for R = 2…5 — "
            "the paper's 19, 44, 59, 66 are below that bound, so its agents must have shrunk faster than δ "
            "per round. The undercut variant does so and meets the paper's rounds where marked; for R = 2 "
            "termination is Rubinstein's acceptance at p̂ ≈ 0.5, which the δ-per-round cap reaches only "
            "after ≈ 28–34 rounds.\n"
        )
    add("![Table 2 partitions](table2_partitions.png)\n")

    for name, key, paper, title in (
        ("3", "total", PaperValues.table3, "excess total distance"),
        ("4", "max", PaperValues.table4, "excess maximum individual distance"),
    ):
        add(f"## Table {name} — targets, {title} vs the exact optimum (%), ours (paper)\n")
        add(
            "Rows R robots at (0.5, 0), columns N random targets; rounds strategy, drop the farthest "
            f"contested point (§4.2), δ = {TARGET_DELTA}. Optimum: exact branch and bound over assignments with "
            f"Held–Karp routes ({'minimum total' if key == 'total' else 'minimum of the longest route'}).\n"
        )
        add("| R \\ N | " + " | ".join(str(n) for n in range(2, 8)) + " | G = N, no overlap, all agreed |")
        add("|---|" + "---|" * 7)
        better = 0
        for r in range(2, 8):
            cells = [t34["cells"][("rounds", r, n)] for n in range(2, 8)]
            better += sum(c[key] <= paper[r][i] for i, c in enumerate(cells))
            ok = all(c["G_is_N"] and c["overlap"] == 0 and c["agreed"] for c in cells)
            add(
                f"| {r} | "
                + " | ".join(f"{c[key]:.1f} ({paper[r][i]})" for i, c in enumerate(cells))
                + f" | {_yes(ok)} |"
            )
        add(f"\nOurs ≤ paper in {better} of 36 cells.\n")
    add(
        "Coverage and overlap targets for the target tables: every run ends with G = N and no point "
        "claimed twice (the paper's claim too); the paper gives no round counts for targets, so there "
        "is nothing to compare rounds with (ours are in `targets_runs.csv`).\n"
    )
    add("### Rounds vs all-against-all (targets, mean over N = 2…7)\n")
    add("| R | strategy | excess total % | excess max % | rounds | messages |")
    add("|---|---|---|---|---|---|")
    for c in t34["strategies"]:
        add(
            f"| {c['R']} | {c['strategy']} | {c['excess_total_pct']} | {c['excess_max_pct']} | {c['rounds']} | {c['messages']} |"
        )
    add("")

    add("## §2.2 — the no-fly zone\n")
    runs = nfz["runs"]
    worst = max(x["nfz_in_S2"] for x in runs)
    add(
        f"Robot 2 (δ = 0.955) may not fly over a 0.03 zone; robot 1 (δ = 0.95) does not know it. Weights "
        f"α = β = γ = 1, λ = 1000, no ill-shape term. Over {len(runs)} seeds: NFZ area given to robot 2: "
        f"max **{worst:.2e}** (must be 0); NFZ with robot 1 in {sum(x['nfz_in_S1'] > 0.029 for x in runs)} runs; "
        f"mean dim(S1) = {np.mean([x['dim_S1'] for x in runs]):.3f}, dim(S2) = {np.mean([x['dim_S2'] for x in runs]):.3f}, "
        f"G = {np.mean([x['G'] for x in runs]):.3f} (paper: 0.409 / 0.259, G = 0.668, optimum 0.673); "
        f"g2 of robot 1's share (with the NFZ) = {np.mean([x['g2_S1'] for x in runs]):.2f}.\n"
    )
    add("![NFZ](nfz.png)\n")
    (out / "report.md").write_text("\n".join(L) + "\n")
