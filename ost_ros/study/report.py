"""Tables, plots (matplotlib, Agg) and report.md of a reproduction run."""

from __future__ import annotations

import csv
import statistics
from collections import defaultdict
from pathlib import Path

from ost_ros import protocols
from ost_ros.optimal import search_space_order
from ost_ros.study.design import PAPER, Design, compared
from ost_ros.study.paper import TABLE1, TABLE3, TABLE3_AGENTS
from ost_ros.study.runner import Row, Timing, row_dicts

PRIMARY = "CCP CI=1"  # the setting of Fig. 11 / Table 3 we compare cell by cell (see docs)


def means(rows: list[Row]) -> dict[tuple[int, int, str], float]:
    """Mean makespan over the object sets, by (N, M, variant)."""
    acc: dict[tuple[int, int, str], list[int]] = defaultdict(list)
    for r in rows:
        acc[(r.agents, r.objects, r.variant)].append(r.makespan)
    return {k: statistics.fmean(v) for k, v in acc.items()}


def speedup(c: dict, variant: str, m: int, n: int) -> float | None:
    """S_N = (C_10 / C_N) · (10 / N)."""
    c10, cn = c.get((10, m, variant)), c.get((n, m, variant))
    if c10 is None or cn is None:
        return None
    return (c10 / cn) * (10 / n)


def write_csv(path: Path, dicts: list[dict]) -> None:
    if not dicts:
        path.write_text("")
        return
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(dicts[0]))
        w.writeheader()
        w.writerows(dicts)


# ----------------------------------------------------------------------------- plots


def _plot(
    path: Path,
    title: str,
    xs: list[int],
    series: dict[str, list[float | None]],
    ylabel: str = "execution time (steps)",
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for name, ys in series.items():
        pts = [(x, y) for x, y in zip(xs, ys) if y is not None]
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", ms=3, label=name)
    ax.set_xlabel("number of objects M")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plots(out: Path, design: Design, c: dict) -> list[str]:
    ms = list(design.objects)
    files = []
    for fig, n in (("fig7", 10), ("fig8", 50)):
        if n in design.compare_agents:
            labels = [v.label for v in compared()]
            _plot(
                out / f"{fig}.png",
                f"The protocols compared, N={n}",
                ms,
                {v: [c.get((n, m, v)) for m in ms] for v in labels},
            )
            files.append(f"{fig}.png")
    for fig, n in (("fig9", 10), ("fig10", 50)):
        if n in design.compare_agents:
            _plot(
                out / f"{fig}.png",
                f"CCP, coordination intervals, N={n}",
                ms,
                {f"CI={ci}": [c.get((n, m, f"CCP CI={ci}")) for m in ms] for ci in design.cis},
            )
            files.append(f"{fig}.png")
    _plot(
        out / "fig11.png",
        f"CCP ({PRIMARY[4:]}), agents N",
        ms,
        {f"N={n}": [c.get((n, m, PRIMARY)) for m in ms] for n in design.agents},
    )
    files.append("fig11.png")
    return files


# ----------------------------------------------------------------------------- claims


def claim_ccp_beats_hcp(design: Design, c: dict) -> tuple[bool, str]:
    cells = wins = 0
    worst = None
    for n in design.compare_agents:
        for m in design.objects:
            h = c.get((n, m, "HCP"))
            for v in [f"CCP CI={ci}" for ci in design.cis] + ["CCP CI=M"]:
                x = c.get((n, m, v))
                if h is None or x is None:
                    continue
                cells += 1
                wins += x < h
                ratio = x / h
                if worst is None or ratio > worst[0]:
                    worst = (ratio, n, m, v)
    text = f"CCP's mean time is below HCP's in {wins} of {cells} (N, M, CI) cells" + (
        f"; the closest cell is N={worst[1]}, M={worst[2]}, {worst[3]} at {worst[0]:.2f}× HCP"
        if worst
        else ""
    )
    return wins == cells and cells > 0, text


def claim_larger_ci(design: Design, c: dict) -> tuple[bool, str]:
    pairs = better = 0
    gaps = {}
    for n in design.compare_agents:
        rel = []
        for m in design.objects:
            ys = [c.get((n, m, f"CCP CI={ci}")) for ci in design.cis]
            for i in range(len(ys)):
                for j in range(i + 1, len(ys)):
                    yi, yj = ys[i], ys[j]
                    if yi is not None and yj is not None and yi != yj:
                        pairs += 1
                        better += yj < yi
            a, b = c.get((n, m, "CCP CI=1")), c.get((n, m, "CCP CI=M"))
            if a and b and m > 1:
                rel.append((a - b) / a)
        gaps[n] = statistics.fmean(rel) if rel else 0.0
    share = better / pairs if pairs else 0.0
    gap_text = ", ".join(f"N={n}: {100 * g:.1f}%" for n, g in gaps.items())
    shrinks = len(gaps) < 2 or gaps[max(gaps)] < gaps[min(gaps)]
    text = (
        f"of {pairs} pairs of different CIs (same N, M) with different times, the larger CI "
        f"is faster in {better} ({100 * share:.0f}%); mean advantage of CI=M over CI=1: "
        f"{gap_text} ({'smaller' if shrinks else 'not smaller'} with more agents, "
        f"as the paper says it is)"
    )
    return share > 0.5, text


def _speedup_cells(design: Design, c: dict, variant: str) -> tuple[int, int, tuple | None]:
    cells = ok = 0
    low = None
    for m in design.objects:
        if m <= 30:
            continue
        for n in design.agents:
            if n == 10:
                continue
            s = speedup(c, variant, m, n)
            if s is None:
                continue
            cells += 1
            ok += s >= 1.0
            if low is None or s < low[0]:
                low = (s, n, m)
    return cells, ok, low


def claim_speedup(design: Design, c: dict) -> tuple[bool, str]:
    cells, ok, low = _speedup_cells(design, c, PRIMARY)
    other_cells, other_ok, other_low = _speedup_cells(design, c, "CCP CI=M")
    text = (
        f"S_N ≥ 1 in {ok} of {cells} cells with M > 30 ({PRIMARY})"
        + (f"; lowest S_{low[1]} = {low[0]:.2f} at M={low[2]}" if low else "")
        + f". With CI=M it is {other_ok} of {other_cells}"
        + (
            f" (lowest S_{other_low[1]} = {other_low[0]:.2f} at M={other_low[2]}): the claim "
            "depends on the CI, see the differences below"
            if other_low
            else ""
        )
    )
    return cells > 0 and ok >= 0.5 * cells, text


# ----------------------------------------------------------------------------- report


def table3_rows(design: Design, c: dict, variant: str) -> list[dict]:
    out = []
    for m in design.objects:
        row: dict[str, float | None] = {"M": m}
        for n in design.agents:
            s = speedup(c, variant, m, n)
            row[f"N={n}"] = None if s is None else round(s, 3)
            paper = TABLE3.get(m)
            if paper and n in TABLE3_AGENTS:
                row[f"paper N={n}"] = paper[TABLE3_AGENTS.index(n)]
        out.append(row)
    return out


def write_all(out: Path, design: Design, rows: list[Row], timing: Timing, quick: bool) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    c = means(rows)
    write_csv(out / "runs.csv", row_dicts(rows))
    summary = []
    for (n, m, v), mean in sorted(c.items()):
        bound = statistics.fmean(r.lower_bound for r in rows if (r.agents, r.objects, r.variant) == (n, m, v))
        summary.append(
            {
                "agents": n,
                "objects": m,
                "variant": v,
                "mean_makespan": round(mean, 1),
                "mean_lower_bound": round(bound, 1),
                "ratio_to_bound": round(mean / bound, 3),
            }
        )
    write_csv(out / "summary.csv", summary)
    t3 = {v: table3_rows(design, c, v) for v in ("CCP CI=1", "CCP CI=M")}
    write_csv(out / "table3.csv", [dict(variant=v, **r) for v, rs in t3.items() for r in rs])
    t1 = [
        {"M": m, "order_ours": round(search_space_order(m, 10), 2), "order_paper": o}
        for m, o in TABLE1.items()
    ]
    write_csv(out / "table1.csv", t1)
    figs = plots(out, design, c)
    claims = [
        ("1. CCP is better than HCP, whatever the CI", *claim_ccp_beats_hcp(design, c)),
        (
            "2. A larger CI is generally better (and CI matters less with more agents)",
            *claim_larger_ci(design, c),
        ),
        ("3. Linear or superlinear speedup for M > 30", *claim_speedup(design, c)),
    ]
    md = _markdown(design, c, rows, timing, quick, t1, t3, figs, claims)
    (out / "report.md").write_text(md)
    return out / "report.md"


def _fmt(x) -> str:
    return "–" if x is None else (f"{x:.2f}" if isinstance(x, float) else str(x))


def _markdown(design, c, rows, timing, quick, t1, t3, figs, claims) -> str:
    L = []
    L.append(f"# Reproduction of Lin & Hsu's simulation study{' (quick subset)' if quick else ''}")
    L.append("")
    L.append(
        f"- design: area 500×200, N ∈ {list(design.agents)}, M ∈ {list(design.objects)}, "
        f"{design.sets} object sets per M (n_max = 10, seed {design.seed}); HCP and the CI "
        f"sweep {list(design.cis)} at N ∈ {list(design.compare_agents)}; CCP CI=1 and CI=M "
        "at every N."
    )
    L.append(
        f"- {len(rows)} runs, event-driven engine (identical to the step simulator), "
        f"{timing.workers} worker processes: wall time **{timing.wall:.1f} s**, "
        f"{timing.cpu:.1f} CPU s in the workers, load average {timing.load:.1f} at the end "
        f"(above {timing.workers} means other programs shared the cores)."
    )
    L.append(
        "- files: runs.csv (every run), summary.csv (means, lower bound), table1.csv, "
        "table3.csv, " + ", ".join(figs)
    )
    L.append("")
    L.append("## The paper's claims")
    L.append("")
    for title, holds, text in claims:
        L.append(f"- **{title}: {'holds' if holds else 'does not hold'}.** {text}.")
    L.append("")
    L.append("## Table 3: speedup S_N = (C_10 / C_N)·(10 / N), ours vs the paper")
    for variant, rows3 in t3.items():
        L.append("")
        L.append(f"### {variant}{' (compared in the claims)' if variant == PRIMARY else ''}")
        L.append("")
        head = "| M | " + " | ".join(f"N={n} ours / paper (Δ)" for n in design.agents) + " |"
        L.append(head)
        L.append("|" + "---|" * (len(design.agents) + 1))
        diffs, signed = [], []
        for r in rows3:
            cells = []
            for n in design.agents:
                ours, paper = r.get(f"N={n}"), r.get(f"paper N={n}")
                if ours is not None and paper is not None:
                    d = ours - paper
                    if n != 10:
                        diffs.append(abs(d))
                        signed.append(d)
                    cells.append(f"{ours:.2f} / {paper:.2f} ({d:+.2f})")
                else:
                    cells.append(f"{_fmt(ours)} / {_fmt(paper)}")
            L.append(f"| {r['M']} | " + " | ".join(cells) + " |")
        if diffs:
            L.append("")
            mean = statistics.fmean(signed)
            L.append(
                f"Mean |ours − paper| over the N > 10 cells: {statistics.fmean(diffs):.3f}; "
                f"largest {max(diffs):.2f}; mean signed difference {mean:+.3f} (ours "
                f"{'above' if mean > 0 else 'below'} the paper on average)."
            )
    L.append("")
    L.append("## Mean execution time (steps), Figs 7–11")
    L.append("")
    variants = sorted({k[2] for k in c}, key=_column)
    for n in design.agents:
        present = [v for v in variants if any((n, m, v) in c for m in design.objects)]
        L.append(f"**N = {n}**")
        L.append("")
        L.append("| M | " + " | ".join(present) + " |")
        L.append("|" + "---|" * (len(present) + 1))
        for m in design.objects:
            L.append(
                f"| {m} | "
                + " | ".join(_fmt(round(c[(n, m, v)])) if (n, m, v) in c else "–" for v in present)
                + " |"
            )
        L.append("")
    for spec in protocols.REGISTRY.values():  # our protocols beside the paper's
        if spec.name != PAPER and spec.capabilities.triggers:
            L.extend(_beside_paper(design, c, spec))
    L.append("## Table 1: order of the Optimal-OST search space, N = 10")
    L.append("")
    L.append("| M | ours: log10(M!·E[C(10,i)]^M) | paper |")
    L.append("|---|---|---|")
    for r in t1:
        L.append(f"| {r['M']} | {r['order_ours']:.2f} | 10^{r['order_paper']} |")
    L.append("")
    L.append("## Where we differ from the paper, and why we think so")
    L.append("")
    L.extend(DIFFERENCES)
    return "\n".join(L) + "\n"


def _column(variant: str) -> tuple:
    """Table column order: protocols without triggers (HCP), the paper's, then ours; CI=M first."""
    names = list(protocols.REGISTRY)
    spec = protocols.get(variant.split()[0].lower())
    ci = variant.partition("=")[2]
    return (
        spec.capabilities.triggers,
        spec.name != PAPER,
        names.index(spec.name),
        ci != "M",
        int(ci) if ci.isdigit() else 0,
    )


def _beside_paper(design: Design, c: dict, spec: protocols.ProtocolSpec) -> list[str]:
    """A protocol next to CCP at the same CI: mean time ratio per (N, CI), and where it wins."""
    name, base = spec.name.upper(), PAPER.upper()
    L = [
        f"## {name} ({spec.label}) next to {base}",
        "",
        f"{spec.note} Ratio = mean {name} time / mean {base} time at the same CI.",
        "",
        f"| N | CI | M: ratio {name}/{base} | {name} faster in |",
        "|---|---|---|---|",
    ]
    for n in design.compare_agents:
        for ci in ("1", "M"):
            cells, wins, total = [], 0, 0
            for m in design.objects:
                a, b = c.get((n, m, f"{name} CI={ci}")), c.get((n, m, f"{base} CI={ci}"))
                if a is None or b is None or b == 0:
                    continue
                total += 1
                wins += a < b
                cells.append(f"{m}: {a / b:.2f}")
            if cells:
                L.append(f"| {n} | {ci} | {', '.join(cells)} | {wins} of {total} M |")
    L.append("")
    return L


DIFFERENCES = [
    "- **Absolute times.** The paper prints Figs 7–11 as images only; its absolute times cannot be "
    "compared cell by cell, so the comparison is by shape (the claims) and by Table 3, which is "
    "relative. Our times follow our readings (docs/interpretation.md): one cell per step, agents "
    "handle objects only after their own search, x-first motion, return to base included.",
    "- **HCP.** The paper only summarises HCP (§2.3; details are in its reference [7]). Ours is "
    "the design in docs/interpretation.md (owner requests, standing offers, cheapest partners, "
    "priority by object id). A different offer rule or deadlock scheme would move HCP's curve, "
    "not the CCP numbers; the claim compares against our HCP.",
    "- **Speedup formula.** The printed S_N = (C_N/N)(10/C_10) contradicts the table's values; we "
    "use S_N = (C_10/C_N)(10/N) (the issue's formula). Small M (M = 1, 10) is dominated by the "
    "search time, which scales as 1/N only roughly (partition shapes of Table 2, 3-row passes "
    "rounded up, the walk home), hence S_N < 1 there as in the paper.",
    "- **Object sets.** 10 random sets per M (ours: seeded, numpy) are not the paper's sets; with "
    "n_i up to 10 the variance per set is large, so a Table 3 cell moves by a few hundredths "
    "between seeds (rerun with another --seed to see it).",
    "- **Which CCP setting Table 3 uses** is not stated; we show CI=1 and CI=M and test the claim "
    "on CI=1 (coordination from the first object found, the protocol's default). The two bracket "
    "the paper: with CI=1 our S_N lies mostly above the paper's, with CI=M mostly below. The reason "
    "is the baseline C_10: CI=1 costs much more than CI=M at N=10 (greedy decisions on little "
    "information, see the CI tables) but little at N=50, so CI=1 inflates C_10 relative to C_N and "
    "with it S_N; CI=M has the best C_10 and the smallest S_N. A paper run with an intermediate or "
    "mixed CI would land in between, which is where its values are.",
    "- **Small M (M = 1, 10)**: our S_N is above the paper's at M = 1 (by about 0.05–0.10). One "
    "object is dominated by the search time L ≈ (W·H)/(3N) plus the walk home; the paper's "
    "simulator may count the search differently (e.g. its sensor or its row passes), which changes "
    "how search time scales with N; we found no statement that pins it down.",
    "- **Lower bound.** summary.csv lists each cell's mean lower bound (ost_ros/bounds.py) and "
    "the makespan/bound ratio: it shows how much of a time is forced (search, carry) and how much "
    "is coordination and waiting.",
]
