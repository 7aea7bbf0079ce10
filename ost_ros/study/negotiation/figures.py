"""The negotiation study's figures (matplotlib, Agg): Fig. 4, the Table 2 partitions, the §2.2
no-fly zone."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ost_ros.negotiation.protocol import rubinstein_share
from ost_ros.negotiation.scenarios import FIG4_DELTAS, make_task_polygon
from ost_ros.study.negotiation.plan import AREA_R


def nfz(out: Path, runs: list[dict[str, Any]]) -> None:
    import matplotlib.pyplot as plt

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


def fig4(out: Path, rows: list[dict[str, Any]]) -> None:
    import matplotlib.pyplot as plt

    p1 = rubinstein_share(*FIG4_DELTAS)
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


def partitions(out: Path, results: dict, seed: int) -> None:
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

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
