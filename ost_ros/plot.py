"""Pictures of a run: the map (subareas, objects, where they go) and each agent's timeline.

Used by ``ost sim --plot FILE.png``. Matplotlib with the Agg backend (no display needed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from ost_ros import protocols
from ost_ros.messages import Action
from ost_ros.model import Scenario
from ost_ros.result import RunResult
from ost_ros.world import World

# The shared-schedule protocols' states keep these colours; other states (a protocol's own, from
# the registry) take the next colours of a qualitative palette.
STATE_COLOURS = {
    "SEARCHING": "#9ecae1",
    "DECISION": "#d9d9d9",
    "HELPING": "#fdae6b",
    "WAITING": "#e6550d",
    "MOVING": "#31a354",
    "RETURNING": "#756bb1",
}
MEMBERSHIP_COLOURS = {"OUT": "#bdbdbd", "FAILED": "#252525"}  # declared out (stopped), dead
_MORE = ("#fd8d3c", "#c994c7", "#74c476", "#6baed6", "#bcbddc", "#fdd0a2")


def state_colours(protocol: str) -> dict[str, str]:
    """Colour of every state a protocol's robots report (FINISH is not drawn)."""
    out, extra = {}, iter(_MORE)
    for state in protocols.get(protocol).states:
        if state != "FINISH":
            out[state] = STATE_COLOURS.get(state) or next(extra, "#969696")
    return out


@dataclass
class Timeline:
    """Per agent, runs of equal global state: [state, first step, last step]. Feed it from the
    step engine's ``on_step`` hook (or, for a run without a barrier, :meth:`of_labels`)."""

    runs: dict[int, list[list]] = field(default_factory=dict)
    splits: list[tuple[str, float, float]] = field(default_factory=list)  # (groups, from, steps)

    @classmethod
    def of_labels(cls, labels: dict[int, list[tuple[float, str]]], end: float) -> Timeline:
        """From a realtime world's changes of what each robot does (``RealtimeWorld.labels``),
        each state lasting until the next change (or ``end``)."""
        tl = cls()
        for agent, changes in labels.items():
            runs = tl.runs.setdefault(agent, [])
            for k, (t, state) in enumerate(changes):
                until = changes[k + 1][0] if k + 1 < len(changes) else end
                first, last = math.ceil(t - 1e-9), math.ceil(until - 1e-9) - 1
                if last >= first:
                    runs.append([state, first, last])
        return tl

    def __call__(self, world: World, actions: list[Action]) -> None:
        t = world.t - 1
        for a in actions:
            runs = self.runs.setdefault(a.agent, [])
            if runs and runs[-1][0] == a.state and runs[-1][2] == t - 1:
                runs[-1][2] = t
            else:
                runs.append([a.state, t, t])


def plot_run(scenario: Scenario, result: RunResult, timeline: Timeline, path: str | Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch, Rectangle

    fig, (ax_map, ax_t) = plt.subplots(1, 2, figsize=(16, 6), gridspec_kw={"width_ratios": [1.1, 1]})
    g = scenario.grid
    for k, area in enumerate(scenario.subareas):
        ax_map.add_patch(
            Rectangle(
                (area.x0 - 0.5, area.y0 - 0.5), area.width, area.height, fill=False, lw=0.8, ec="#888888"
            )
        )
        ax_map.text(
            area.x0 + area.width / 2,
            area.y0 + area.height / 2,
            f"r{scenario.agents[k].id}",
            ha="center",
            va="center",
            fontsize=8,
            color="#888888",
        )
    for o in scenario.objects:
        ax_map.annotate(
            "",
            xy=o.destination,
            xytext=o.location,
            arrowprops=dict(arrowstyle="->", lw=0.6, color="#3182bd", alpha=0.6),
        )
    if scenario.objects:
        ax_map.scatter(
            [o.location[0] for o in scenario.objects],
            [o.location[1] for o in scenario.objects],
            s=[12 + 8 * o.required for o in scenario.objects],
            c="#de2d26",
            zorder=3,
            label="object (size ∝ n_i)",
        )
        ax_map.scatter(
            [o.destination[0] for o in scenario.objects],
            [o.destination[1] for o in scenario.objects],
            marker="x",
            s=20,
            c="#3182bd",
            zorder=3,
            label="destination",
        )
    ax_map.scatter(
        [a.base[0] for a in scenario.agents],
        [a.base[1] for a in scenario.agents],
        marker="s",
        s=25,
        c="k",
        zorder=4,
        label="base",
    )
    ax_map.set_xlim(-1, g.width)
    ax_map.set_ylim(g.height, -1)  # y grows downward, as rows of the sweep
    ax_map.set_aspect("equal")
    ax_map.set_title(
        f"{g.width}×{g.height}, partition {scenario.partition[0]}×{scenario.partition[1]}, "
        f"N={scenario.n_agents}, M={scenario.n_objects}"
    )
    ax_map.legend(loc="upper right", fontsize=7)

    colours = state_colours(result.protocol)
    if any(r[0] in MEMBERSHIP_COLOURS for runs in timeline.runs.values() for r in runs):
        colours |= MEMBERSHIP_COLOURS  # (a run without a barrier: who was out when)
    ids = [a.id for a in scenario.agents]
    for groups, start, steps in timeline.splits:
        ax_t.axvspan(start, start + steps, color="#fee391", alpha=0.5, lw=0)
        ax_t.text(start, len(ids) - 0.45, f" split {groups}", fontsize=7, va="bottom")
    for row, aid in enumerate(ids):
        for state, first, last in timeline.runs.get(aid, []):
            if state in colours:
                ax_t.barh(row, last - first + 1, left=first, height=0.8, color=colours[state], lw=0)
    ax_t.set_yticks(range(len(ids)), [f"r{i}" for i in ids], fontsize=7 if len(ids) > 20 else 9)
    ax_t.invert_yaxis()
    ax_t.set_xlabel("time step")
    if result.makespan is not None:
        ax_t.axvline(result.makespan, color="k", lw=0.8, ls="--")
    ax_t.set_title(
        f"{result.protocol.upper()} ({result.trigger}): makespan {result.makespan}, "
        f"last delivery {result.last_delivery}"
    )
    ax_t.legend(
        handles=[Patch(color=c, label=s) for s, c in colours.items()],
        fontsize=7,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.1),
        ncol=min(len(colours), 6),
        frameon=False,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
