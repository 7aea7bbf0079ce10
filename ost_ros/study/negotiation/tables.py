"""The negotiation study's tables: each one's cells from the runs, written as CSV."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ost_ros.negotiation.protocol import rubinstein_share
from ost_ros.negotiation.scenarios import FIG4_DELTAS, PaperValues
from ost_ros.study.negotiation.plan import AREA_R, T2_METRICS, TGT_KEYS, TGT_N, TGT_R, Plan
from ost_ros.study.stats import spread
from ost_ros.study.tables import write_csv


# ---------------------------------------------------------------- Table 2 ---------------------
def table2(out: Path, results: dict, cfg: Plan, seed: int) -> dict:
    rows, cells = [], {}
    for stop in cfg.stoppings:
        for r in AREA_R:
            runs = [results[("t2", (r, stop, seed + k))] for k in range(cfg.area_runs)]
            rows += [{k: x[k] for k in x if k != "shares"} for x in runs]
            cell = {m: spread([x[m] for x in runs]) for m in (*T2_METRICS, "offer_ratio", "max_share")}
            cell["timeouts"] = sum(x["status"] != "agreed" for x in runs)
            cells[(stop, r)] = cell
    write_csv(out / "table2_runs.csv", rows)
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
    write_csv(out / "table2.csv", table)
    mad = {}
    for stop in cfg.stoppings:
        for i, m in enumerate(T2_METRICS):
            diffs = [abs(cells[(stop, r)][m][0] - PaperValues.table2[r][i]) for r in AREA_R]
            mad[f"table2_{stop}_{m}"] = float(np.mean(diffs))
    return {"cells": cells, "table": table, "mad": mad}


# ---------------------------------------------------------------- Tables 3/4 ------------------
def tables34(out: Path, results: dict, cfg: Plan, combos: list, seed: int) -> dict:
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
    write_csv(out / "targets_runs.csv", rows)
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
        write_csv(
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
    write_csv(out / "targets_rules.csv", comp)
    main = next(c for c in comp if c["strategy"] == "rounds" and c["rule"] == "furthest")
    mad = {
        "table3": main["mad_table3"],
        "table4": main["mad_table4"],
        "table4_minmax": main["mad_table4_minmax"],
    }
    return {"cells": cells, "comp": comp, "grid": grid, "p3": p3, "p4": p4, "mad": mad}


# ---------------------------------------------------------------- NFZ ---------------------------
def nfz(out: Path, results: dict, n_nfz: int, seed: int) -> dict:
    runs = [results[("nfz", (seed + k,))] for k in range(n_nfz)]
    write_csv(out / "nfz.csv", [{k: v for k, v in x.items() if k not in ("shares", "nfz")} for x in runs])
    return {"runs": runs}


# ---------------------------------------------------------------- §5.1 ---------------------------
def missions(out: Path, results: dict, layouts: int, seed: int) -> dict:
    runs = [[results[("mission", (lay, v, seed))] for lay in range(layouts)] for v in range(2)]
    write_csv(
        out / "missions.csv",
        [{k: (str(v) if isinstance(v, list) else v) for k, v in x.items()} for rs in runs for x in rs],
    )
    return {"runs": runs}


# ---------------------------------------------------------------- Fig. 4 ------------------------
def fig4_trace(out: Path, res: dict) -> list[dict[str, Any]]:
    """One row per offer of the Fig. 4 negotiation."""
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
    write_csv(out / "fig4_trace.csv", rows)
    return rows
