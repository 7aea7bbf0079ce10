"""``ost compare``: every protocol and CCP planner on the same scenarios, side by side.

The study's grid (500×200, the paper's object law, N × M, ≥ 10 object sets; ``quick``: a corner
of it) is run with every variant: every protocol of the registry (those with triggers at CI = 1
and CI = M), and CCP with the improved planner at both. Per (variant, N, M): mean makespan with a 95 % interval
(Student t over the object sets), mean ratio to the lower bound, protocol messages per object,
CPU seconds per run (the in-process run: planning and the engine). Every statement of the
report is computed from these rows.

``latency`` (``ost compare --latency L[:J]``): every variant that runs without a barrier also runs
so (:mod:`ost_ros.realtime`, in process, the latency model seeded by the object set's seed): rows
labelled ``… L=L:J``, the report's table, findings and figures gaining them. A realtime run with a
disagreement, or one that does not deliver every object, stops the study (as any failed run).
"""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ost_ros import protocols
from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.study.design import Design, Task, scenario_of
from ost_ros.study.executors import Executor
from ost_ros.study.runner import Outcome, Study, Timing, run_study
from ost_ros.study.stats import interval
from ost_ros.study.tables import write_csv

PAPER = "CCP CI=1"  # the reference: the paper's protocol at its own trigger


@dataclass(frozen=True)
class Variant:
    """A protocol (with its trigger and, for CCP, its planner) as the comparison runs it."""

    protocol: str
    ci: str = ""  # "1", "M" or "" (no triggers)
    planner: str = "paper"
    latency: tuple[float, float] | None = None  # without a barrier, at latency L + U[0, J]

    @property
    def label(self) -> str:
        name = self.protocol.upper() + (f" CI={self.ci}" if self.ci else "")
        name += " improved" if self.planner != "paper" else ""
        return name + (f" L={self.latency[0]:g}:{self.latency[1]:g}" if self.latency else "")

    def run(self, task: Task):
        scenario = scenario_of(task)
        ci = task.objects if self.ci == "M" else int(self.ci or 1)
        policy = CoordinationPolicy(ci=max(ci, 1)) if self.ci else None
        settings = protocols.settings_from(self.protocol, {"planner": self.planner}) if self.ci else None
        if self.latency is not None:
            from ost_ros.realtime.net import Latency
            from ost_ros.realtime.run import run_realtime

            r, rep = run_realtime(
                scenario, self.protocol, policy, settings, latency=Latency(*self.latency), seed=task.seed
            )
            if rep.disagreements:
                raise RuntimeError(f"{self.label}: {rep.disagreements} disagreements")
            return r
        return simulate(scenario, self.protocol, policy, engine="event", settings=settings)


def variants(latency: tuple[float, float] | None = None) -> list[Variant]:
    """Every protocol of the registry; those with triggers at CI = 1 and CI = M; CCP with each
    planner; with ``latency``, also each of them that runs without a barrier, so."""
    from ost_ros.realtime.run import REALTIME

    out: list[Variant] = []
    for spec in protocols.REGISTRY.values():
        planners = [o for o in spec.options if o.name == "planner"]
        names = ("paper", "improved") if planners else ("paper",)
        cis = ("1", "M") if spec.capabilities.triggers else ("",)
        out.extend(Variant(spec.name, ci, p) for p in names for ci in cis)
    if latency is not None:
        out += [Variant(v.protocol, v.ci, v.planner, latency) for v in list(out) if v.protocol in REALTIME]
    return out


@dataclass(frozen=True)
class Row:
    agents: int
    objects: int
    set: int
    seed: int
    variant: str
    makespan: int
    lower_bound: int
    messages: int
    cpu_s: float


def grid(quick: bool, sets: int | None) -> list[Task]:
    d = Design()
    ns = (10, 50) if quick else d.agents
    ms = (10, 50) if quick else tuple(m for m in d.objects if m >= 10)
    k = sets or (3 if quick else d.sets)
    tasks = [Task(n, m, s, d.object_seed(m, s), ()) for n in ns for m in ms for s in range(k)]
    return sorted(tasks, key=lambda t: -t.objects * t.agents)  # heavy first


@dataclass(frozen=True)
class Run:
    """One variant on one object set with one team size."""

    task: Task
    variant: Variant


@lru_cache(maxsize=4)
def _bound(task: Task) -> int:
    return lower_bound(scenario_of(task)).value


def run(spec: Run) -> Row:
    """The row of one run; its CPU seconds are those of the run itself (scenario and engine)."""
    task, v = spec.task, spec.variant
    cpu = time.process_time()
    r = v.run(task)
    cpu = time.process_time() - cpu
    if not r.completed or r.rejections or r.warnings:
        raise RuntimeError(f"{v.label} on N={task.agents} M={task.objects} set {task.set}: {r.error}")
    return Row(
        task.agents,
        task.objects,
        task.set,
        task.seed,
        v.label,
        int(r.makespan or 0),
        _bound(task),
        r.messages,
        cpu,
    )


def weight(spec: Run) -> float:
    """Rough relative cost: stepped protocols and the improved planner grow with N·M; a run
    without a barrier runs every robot's comm (N times the work)."""
    v = spec.variant
    heavy = protocols.get(v.protocol).team_comm is None or v.planner != "paper"
    n = spec.task.agents
    return (1 + spec.task.objects) * (n if heavy else 2) * (n if v.latency else 1)


def study(tasks: list[Task], latency: tuple[float, float] | None = None) -> Study[Run, Row]:
    """Every variant on every task, the tasks in the given order (heaviest first)."""
    return Study("compare", [Run(t, v) for t in tasks for v in variants(latency)], run, weight, Row)


def run_all(
    tasks: list[Task],
    executor: Executor,
    out: Path | None = None,
    progress: bool | None = None,
    latency: tuple[float, float] | None = None,
) -> tuple[list[Row], Outcome[Row]]:
    """Every variant on every task: the rows sorted as runs.csv lists them, and the outcome."""
    outcome = run_study(study(tasks, latency), executor, out, progress)
    return sorted(outcome.rows, key=lambda r: (r.agents, r.objects, r.variant, r.set)), outcome


# ----------------------------------------------------------------------------- summary


@dataclass(frozen=True)
class Cell:
    variant: str
    agents: int
    objects: int
    runs: int
    makespan: float  # mean
    half: float  # 95 % interval half-width
    ratio: float  # mean makespan / lower bound
    messages_per_object: float
    cpu_s: float  # mean per run


def summarise(rows: list[Row]) -> list[Cell]:
    groups: dict[tuple[str, int, int], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.variant, r.agents, r.objects), []).append(r)
    cells = []
    for (v, n, m), rs in sorted(groups.items(), key=lambda kv: (kv[0][1], kv[0][2], kv[0][0])):
        xs = [r.makespan for r in rs]
        cells.append(
            Cell(
                v,
                n,
                m,
                len(rs),
                statistics.mean(xs),
                interval(xs)[1],
                statistics.mean(r.makespan / r.lower_bound for r in rs),
                statistics.mean(r.messages / r.objects for r in rs),
                statistics.mean(r.cpu_s for r in rs),
            )
        )
    return cells


def findings(rows: list[Row], cells: list[Cell]) -> list[str]:
    """The report's statements, each computed from the rows."""
    by_key: dict[tuple[str, int, int, int], Row] = {(r.variant, r.agents, r.objects, r.set): r for r in rows}
    labels = sorted({r.variant for r in rows})
    out = []
    # who wins each (N, M)
    wins: dict[str, int] = {}
    points = sorted({(c.agents, c.objects) for c in cells})
    for n, m in points:
        best = min(
            (c for c in cells if (c.agents, c.objects) == (n, m)), key=lambda c: (c.makespan, c.variant)
        )
        wins[best.variant] = wins.get(best.variant, 0) + 1
    ranking = ", ".join(f"{v} {k}" for v, k in sorted(wins.items(), key=lambda kv: (-kv[1], kv[0])))
    out.append(f"Lowest mean makespan, by (N, M) point ({len(points)} points): {ranking}.")
    # each variant against the paper's CCP CI=1, run by run
    for v in labels:
        if v == PAPER:
            continue
        change = [
            100 * (by_key[(v, n, m, s)].makespan / r.makespan - 1)
            for (w, n, m, s), r in by_key.items()
            if w == PAPER and (v, n, m, s) in by_key
        ]
        if not change:
            continue
        better = sum(c < 0 for c in change)
        worse = sum(c > 0 for c in change)
        out.append(
            f"{v} vs {PAPER}: mean makespan change {statistics.mean(change):+.1f} % over {len(change)} runs "
            f"(better in {better}, worse in {worse}; range {min(change):+.1f} … {max(change):+.1f} %)."
        )
    # the improved planner against the paper's at the same trigger
    for ci in ("1", "M"):
        paper, improved = f"CCP CI={ci}", f"CCP CI={ci} improved"
        pairs = [
            (r, by_key[(improved, n, m, s)])
            for (w, n, m, s), r in by_key.items()
            if w == paper and (improved, n, m, s) in by_key
        ]
        if pairs:
            change = [100 * (b.makespan / a.makespan - 1) for a, b in pairs]
            worst = max(change)
            out.append(
                f"Improved planner vs the paper's at CI={ci}: mean {statistics.mean(change):+.1f} %, "
                f"never worse: {'yes' if worst <= 0 else f'no (worst {worst:+.1f} %)'}; "
                f"CPU per run {statistics.mean(x.cpu_s for _, x in pairs):.2f} s against "
                f"{statistics.mean(a.cpu_s for a, _ in pairs):.2f} s."
            )
    # each variant without a barrier against itself in lockstep, run by run
    for v in sorted({r.variant for r in rows if " L=" in r.variant}):
        base = v.split(" L=")[0]
        change = [
            100 * (by_key[(v, n, m, s)].makespan / r.makespan - 1)
            for (w, n, m, s), r in by_key.items()
            if w == base and (v, n, m, s) in by_key
        ]
        if change:
            out.append(
                f"{v} (no barrier) vs {base} in lockstep: mean {statistics.mean(change):+.1f} % over "
                f"{len(change)} runs (range {min(change):+.1f} … {max(change):+.1f} %), 0 disagreements."
            )
    msgs: dict[str, list[float]] = {c.variant: [] for c in cells}
    for c in cells:
        msgs[c.variant].append(c.messages_per_object)
    text = ", ".join(
        f"{v} {statistics.mean(x):.1f}"
        for v, x in sorted(msgs.items(), key=lambda kv: statistics.mean(kv[1]))
    )
    out.append(f"Protocol messages per object (mean over the points): {text}.")
    return out


# ----------------------------------------------------------------------------- outputs


def plot(cells: list[Cell], out: Path) -> list[str]:
    """One figure per N: mean makespan vs M, one curve per variant, 95 % intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    labels = sorted({c.variant for c in cells})
    for n in sorted({c.agents for c in cells}):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for k, v in enumerate(labels):
            cs = sorted((c for c in cells if c.agents == n and c.variant == v), key=lambda c: c.objects)
            if not cs:
                continue
            shift = 1 + 0.012 * (k - (len(labels) - 1) / 2)  # side by side, intervals readable
            ax.errorbar(
                [c.objects * shift for c in cs],
                [c.makespan for c in cs],
                yerr=[0 if math.isnan(c.half) else c.half for c in cs],
                marker="os^vD<>p*h"[k % 10],
                capsize=3,
                label=v,
                linestyle=":" if " L=" in v else "--" if "improved" in v else "-",
            )
        ax.set_xscale("log")
        ax.set_xticks(
            sorted({c.objects for c in cells}), [str(m) for m in sorted({c.objects for c in cells})]
        )
        ax.set_xlabel("M (objects, log scale)")
        ax.set_ylabel("makespan (steps), mean ± 95 % interval")
        ax.set_title(f"Every protocol and planner, N = {n} robots, 500×200 grid")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        name = f"compare_N{n}.png"
        fig.savefig(out / name, dpi=110)
        plt.close(fig)
        names.append(name)
    return names


def report(rows: list[Row], cells: list[Cell], timing: Timing, figures: list[str]) -> str:
    sets = max((r.set for r in rows), default=0) + 1
    lines = [
        "# Every protocol and planner, side by side",
        "",
        f"- {len(rows)} runs: {len({(r.agents, r.objects) for r in rows})} (N, M) points × "
        f"{sets} object sets × {len({r.variant for r in rows})} variants, 500×200 grid, "
        f"event engine (identical to the step simulator); wall time {timing.wall:.1f} s on "
        f"{timing.executor or f'{timing.workers} workers'}, load {timing.load:.1f} at the end.",
        f"- Reference: {PAPER} (the paper's protocol at its own trigger). Intervals: 95 %, Student t "
        "over the object sets. CPU: seconds per in-process run (planning and the engine).",
    ]
    realtime = sorted({r.variant for r in rows if " L=" in r.variant})
    if realtime:
        lat = realtime[0].split(" L=")[1]
        lines.append(
            f"- Rows `… L={lat}`: the same variant without a barrier (`ost sim --latency {lat}`: every "
            "robot its own runtime, latency L + U[0, J] steps per message, seeded by the object "
            "set), for every protocol (docs/realtime.md)."
        )
    lines += [
        "",
        "## Findings",
        "",
    ]
    lines += [f"- {s}" for s in findings(rows, cells)]
    labels = sorted({c.variant for c in cells})
    lines += ["", "## Mean makespan ± 95 % interval (ratio to the lower bound)", ""]
    lines.append("| N | M | " + " | ".join(labels) + " |")
    lines.append("|---|---|" + "---|" * len(labels))
    index = {(c.variant, c.agents, c.objects): c for c in cells}
    for n, m in sorted({(c.agents, c.objects) for c in cells}):
        row = []
        for v in labels:
            c = index.get((v, n, m))
            row.append("" if c is None else f"{c.makespan:.0f} ± {c.half:.0f} ({c.ratio:.2f})")
        lines.append(f"| {n} | {m} | " + " | ".join(row) + " |")
    lines += ["", "## Messages per object and CPU per run", ""]
    lines.append("| variant | messages per object (mean) | CPU s per run (mean) |")
    lines.append("|---|---|---|")
    for v in labels:
        cs = [c for c in cells if c.variant == v]
        lines.append(
            f"| {v} | {statistics.mean(c.messages_per_object for c in cs):.1f} | "
            f"{statistics.mean(c.cpu_s for c in cs):.3f} |"
        )
    lines += ["", "## Figures", ""]
    lines += [f"![{f}]({f})" for f in figures]
    return "\n".join(lines) + "\n"


def write_all(rows: list[Row], timing: Timing, out: Path) -> list[str]:
    cells = summarise(rows)
    write_csv(out / "runs.csv", rows, digits=4)
    write_csv(out / "summary.csv", cells, digits=4)
    figures = plot(cells, out)
    (out / "report.md").write_text(report(rows, cells, timing, figures))
    return ["report.md", "runs.csv", "summary.csv", *figures]
