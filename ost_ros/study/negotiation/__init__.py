"""``ost negotiate reproduce``: Fig. 4, Table 2, Tables 3–4, the §2.2 no-fly zone and the §5.1
mission of Rossi, Aldama & Barrientos, ours next to the paper's, written as CSVs, PNG plots and
``report.md``. The negotiations (``ost_ros.negotiation``) are run by the study runner: independent
and seeded, so the result depends neither on the executor nor on the order they finish in.

``plan`` what runs, ``tables`` the CSVs, ``figures`` the PNGs, ``report`` report.md.
"""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from ost_ros.study.executors import Executor
from ost_ros.study.negotiation import figures, plan, report, tables
from ost_ros.study.runner import run_study


def reproduce(
    out: Path,
    executor: Executor,
    quick: bool = False,
    seed: int = 0,
    runs: int | None = None,
    progress: bool | None = None,
) -> dict[str, Any]:
    """Run everything and write the report into ``out``. Returns a summary dict."""
    import matplotlib

    matplotlib.use("Agg")
    t_start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    cfg = plan.Plan.make(quick, runs)
    study = plan.study(cfg, seed)
    outcome = run_study(study, executor, out, progress)
    results = dict(zip(study.specs, outcome.rows))

    summary: dict[str, Any] = {"quick": quick, "seed": seed, "workers": executor.workers, **asdict(cfg)}
    t2 = tables.table2(out, results, cfg, seed)
    t34 = tables.tables34(out, results, cfg, plan.combos(cfg), seed)
    nfz = tables.nfz(out, results, cfg.nfz_runs, seed)
    figures.nfz(out, nfz["runs"])
    missions = tables.missions(out, results, cfg.layouts, seed)
    fig4_res = results[("fig4", (seed,))]
    figures.fig4(out, tables.fig4_trace(out, fig4_res))
    figures.partitions(out, results, seed)
    summary["elapsed_s"] = time.perf_counter() - t_start
    summary["timing"] = outcome.timing
    summary["mad"] = {**t2["mad"], **t34["mad"]}
    report.write(out, summary, fig4_res, t2, t34, nfz, missions)
    outcome.finish()
    return summary
