"""Animations of a run: ``ost sim --animate run.gif|run.mp4`` and ``ost replay --animate``.

One frame per recorded :class:`~ost_ros.watch.frames.Frame`: the grid with its subareas, each
robot coloured by its state, objects sized by n_i (labelled with it on small runs) — grey until
a robot has found them, red once found, green while a group carries them — their destinations,
a ``k/n`` tag where a group gathers, the step counter and the deliveries so far. Frames of a run
without a barrier also show who is in the team: a robot declared out grey with a dashed edge, a
silent one (not declared yet) with an orange edge, a dead one crossed, one not joined yet a
dotted ring at its base (all drawn larger); while a partition holds, each robot's edge is its
side's colour and the partition is written under the title, beside the latest change in the
team. GIF through Pillow; MP4 through the ffmpeg binary that the ``imageio-ffmpeg`` package
ships.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ost_ros.errors import OstError
from ost_ros.messages import FINISH_STATE
from ost_ros.model import Scenario
from ost_ros.plot import MEMBERSHIP_COLOURS, state_colours
from ost_ros.realtime.membership import ABSENT, DEAD, OUT, SILENT
from ost_ros.result import RunResult
from ost_ros.watch.frames import FAILED_STATE, Frame

FORMATS = (".gif", ".mp4")
# Who is in the team (runs without a barrier): edges of robots silent, out, not there yet; the
# sides of a partition (edge colours, side 0, 1, ...)
SILENT_EDGE, OUT_EDGE = "#ff7f00", "#636363"
SIDES = ("#1f78b4", "#e31a1c", "#33a02c", "#6a3d9a", "#b15928")
# Objects carry their n_i as text on runs this small (text is the costliest part of a frame).
LABEL_OBJECTS_UP_TO = 12


class AnimationError(OstError):
    """The animation cannot be written (format, missing encoder, file); the text says why."""


@dataclass(frozen=True)
class Written:
    path: Path
    frames: int
    bytes: int


def check_target(path: str | Path) -> str:
    """The file's format (``.gif`` / ``.mp4``), or an :class:`AnimationError` naming the problem —
    checked before a run, so a long run never ends in a bad file name."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise AnimationError(f"{path}: unsupported format {suffix or '(none)'!r} (use .gif or .mp4)")
    if suffix == ".mp4":
        ffmpeg_exe()
    parent = Path(path).resolve().parent
    if not parent.is_dir():
        raise AnimationError(f"{path}: no such directory {parent}")
    return suffix


def ffmpeg_exe() -> str:
    try:
        import imageio_ffmpeg
    except ImportError:
        raise AnimationError(
            "MP4 needs the imageio-ffmpeg package (it ships ffmpeg; pinned in requirements.lock); "
            "write a .gif instead"
        ) from None
    try:
        return str(imageio_ffmpeg.get_ffmpeg_exe())
    except RuntimeError as exc:
        raise AnimationError(f"MP4: no ffmpeg binary ({exc})") from None


def state_palette(protocol: str) -> dict[str, str]:
    """Every state a robot can be drawn in: the protocol's (as in ``--plot``), home, failed."""
    out = state_colours(protocol)
    out[FINISH_STATE] = "#252525"
    out[FAILED_STATE] = "#ff00ff"
    return out


def animate(
    scenario: Scenario,
    result: RunResult,
    frames: Sequence[Frame],
    path: str | Path,
    fps: int = 20,
    progress: Callable[[int, int], None] | None = None,
    heading: str = "",
) -> Written:
    """Write the animation; ``progress(i, n)`` is called per frame drawn; ``heading`` ends the
    title (e.g. the latency of a run without a barrier)."""
    suffix = check_target(path)
    if fps < 1:
        raise AnimationError(f"fps: {fps} must be at least 1")
    if not frames:
        raise AnimationError("no frames to draw")
    scene = _Scene(scenario, result, team=any(f.team for f in frames), heading=heading)
    try:
        images = (scene.render(f) for f in _counted(frames, progress))
        if suffix == ".mp4":
            _write_mp4(images, scene.size, path, fps)
        else:
            _write_gif(images, path, fps)
    except OSError as exc:
        raise AnimationError(f"{path}: cannot write ({exc.strerror or exc})") from None
    finally:
        scene.close()
    return Written(Path(path), len(frames), Path(path).stat().st_size)


def _counted(frames: Sequence[Frame], progress: Callable[[int, int], None] | None):
    for k, frame in enumerate(frames):
        yield frame
        if progress is not None:
            progress(k + 1, len(frames))


def _write_gif(images, path: str | Path, fps: int) -> None:
    from PIL import Image

    def quantised():
        # Fast octree: a palette of its own per frame in ~3 ms (median cut: ~40 ms).
        for rgb in images:
            yield Image.fromarray(rgb).quantize(colors=128, method=Image.Quantize.FASTOCTREE)

    frames = quantised()
    next(frames).save(
        path, save_all=True, append_images=frames, duration=round(1000 / fps), loop=0, optimize=False
    )


def _write_mp4(images, size: tuple[int, int], path: str | Path, fps: int) -> None:
    import subprocess

    w, h = size
    cmd = [
        ffmpeg_exe(), "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
        "-s", f"{w}x{h}", "-r", str(fps), "-i", "-",
        "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2",  # H.264 wants even sides
        "-c:v", "libx264", "-pix_fmt", "yuv420p", "-movflags", "+faststart", str(path),
    ]  # fmt: skip
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdin is not None
    try:
        for rgb in images:
            proc.stdin.write(rgb.tobytes())
    except BrokenPipeError:
        pass  # ffmpeg gave up: its message follows
    finally:
        proc.stdin.close()
        err = proc.stderr.read().decode(errors="replace").strip() if proc.stderr else ""
        code = proc.wait()
    if code != 0:
        raise AnimationError(f"{path}: ffmpeg failed ({err.splitlines()[-1] if err else f'exit {code}'})")


class _Scene:
    """The figure: a fixed background and the artists one frame updates."""

    dpi = 72

    def __init__(self, scenario: Scenario, result: RunResult, team: bool = False, heading: str = ""):
        """``team``: the frames say who is in the team (a run without a barrier): a line more
        under the title, and its legend."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.lines import Line2D
        from matplotlib.patches import Rectangle

        self.scenario, self.result, self.heading = scenario, result, heading
        g = scenario.grid
        width = 8.0
        map_h = width * g.height / g.width
        height = max(map_h, 1.5) + 1.3  # the map, the title above, the legend below
        extra = 0.45 if team else 0.0  # the team's line, a row more of legend
        self.fig = plt.figure(figsize=(width, height + extra), dpi=self.dpi)
        total = height + extra
        self.ax = self.fig.add_axes((0.03, (0.2 * height + 0.2 * extra) / total, 0.94, 0.7 * height / total))
        ax = self.ax
        for k, area in enumerate(scenario.subareas):
            ax.add_patch(
                Rectangle(
                    (area.x0 - 0.5, area.y0 - 0.5),
                    area.width,
                    area.height,
                    fill=True,
                    lw=0.6,
                    ec="#bdbdbd",
                    fc="#f7f7f7" if k % 2 else "#efefef",
                    zorder=0,
                )
            )
        dest = np.array([o.destination for o in scenario.objects], dtype=float).reshape(-1, 2)
        ax.scatter(dest[:, 0], dest[:, 1], marker="x", s=18, c="#3182bd", lw=1, zorder=1)
        bases = np.array([a.base for a in scenario.agents], dtype=float).reshape(-1, 2)
        ax.scatter(
            bases[:, 0], bases[:, 1], marker="s", s=10, facecolors="none", edgecolors="#636363", lw=0.6
        )
        ax.set_xlim(-1, g.width)
        ax.set_ylim(g.height, -1)  # y grows downward, as the sweep's rows
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        self.found = dict(result.found)
        self.required = np.array([o.required for o in scenario.objects])
        sizes = 10 + 6 * self.required
        # objects are squares, robots circles
        self.objects = ax.scatter([], [], s=[], marker="s", zorder=2, edgecolors="#7f0000", linewidths=0.4)
        self.object_sizes = sizes
        self.robots = ax.scatter([], [], s=34, zorder=4, edgecolors="k", linewidths=0.7)
        self.labels = (
            [
                ax.text(0, 0, str(o.required), fontsize=6, ha="center", va="center", zorder=3, visible=False)
                for o in scenario.objects
            ]
            if len(scenario.objects) <= LABEL_OBJECTS_UP_TO
            else []
        )
        self.tags = [
            ax.text(0, 0, "", fontsize=7, color="#006d2c", ha="left", va="bottom", zorder=5, visible=False)
            for _ in scenario.objects
        ]
        self.palette = state_palette(result.protocol)
        top = 0.05 * height / total  # the title's distance from the top, as a fraction
        self.title = self.fig.text(0.03, 1 - top, "", fontsize=11, va="center")
        self.team = team
        if team:
            # dead robots crossed; the partition in force and the latest change in the team
            self.crosses = ax.scatter([], [], s=60, marker="x", c="k", linewidths=1.3, zorder=5)
            line = 1 - (0.1 * height + 0.2 * extra) / total
            self.split = self.fig.text(0.03, line, "", fontsize=9, va="center", color="#b15928")
            self.note = self.fig.text(0.97, line, "", fontsize=9, va="center", ha="right", color="#252525")
        handles = [
            Line2D([], [], ls="", marker="o", mfc=c, mec="k", mew=0.5, label=s.lower())
            for s, c in self.palette.items()
        ] + [
            Line2D([], [], ls="", marker="s", mfc="#d9d9d9", mec="#7f0000", label="object, not found yet"),
            Line2D([], [], ls="", marker="s", mfc="#de2d26", mec="#7f0000", label="found"),
            Line2D(
                [], [], ls="", marker="s", mfc="#31a354", mec="#7f0000", label="held/carried (k/n robots)"
            ),
            Line2D([], [], ls="", marker="x", color="#3182bd", label="destination"),
        ]
        if team:

            def ring(face: str, edge: str, label: str) -> Line2D:
                return Line2D([], [], ls="", marker="o", mfc=face, mec=edge, mew=1.2, label=label)

            handles += [
                ring(MEMBERSHIP_COLOURS["OUT"], OUT_EDGE, "declared out"),
                ring("w", SILENT_EDGE, "silent (not declared)"),
                Line2D([], [], ls="", marker="x", color="k", label="dead"),
                ring("none", OUT_EDGE, "not joined yet"),
                ring("w", SIDES[0], "partition: edge = side"),
            ]
        self.fig.legend(
            handles=handles, loc="lower center", ncol=min(len(handles), 6), fontsize=7, frameon=False
        )
        # Blitting: the background (grid, areas, destinations, legend) is drawn once; a frame
        # restores it and draws only what moves (~10x faster than drawing the figure each time).
        self.dynamic = [self.objects, *self.labels, *self.tags, self.robots, self.title]
        if team:
            self.dynamic += [self.crosses, self.split, self.note]
        for artist in self.dynamic:
            artist.set_animated(True)
        canvas: Any = self.fig.canvas  # Agg: copy_from_bbox, restore_region, buffer_rgba
        canvas.draw()
        self.background = canvas.copy_from_bbox(self.fig.bbox)
        w, h = canvas.get_width_height()
        self.size = (int(w), int(h))

    def render(self, frame: Frame) -> np.ndarray:
        """The frame as an (H, W, 3) uint8 image."""
        self.draw(frame)
        canvas: Any = self.fig.canvas
        canvas.restore_region(self.background)
        for artist in self.dynamic:
            if artist.get_visible():
                self.fig.draw_artist(artist)
        canvas.blit(self.fig.bbox)
        return np.ascontiguousarray(np.asarray(canvas.buffer_rgba())[..., :3])

    def close(self) -> None:
        import matplotlib.pyplot as plt

        plt.close(self.fig)

    def draw(self, frame: Frame) -> None:
        n_obj = len(self.scenario.objects)
        live = ~frame.delivered
        held = {int(o) for o in frame.holding if o >= 0}
        colours = []
        for o in self.scenario.objects:
            if o.id in held:
                colours.append("#31a354")
            elif self.found.get(o.id, frame.t + 1) <= frame.t:
                colours.append("#de2d26")
            else:
                colours.append("#d9d9d9")
        at = frame.objects.astype(float)
        self.objects.set_offsets(at[live] if n_obj else np.empty((0, 2)))
        self.objects.set_sizes(self.object_sizes[live])
        self.objects.set_facecolor([c for c, keep in zip(colours, live) if keep])
        for k, label in enumerate(self.labels):
            label.set_visible(bool(live[k]))
            label.set_position((at[k, 0], at[k, 1]))
        gathered: dict[int, int] = {}
        for o in frame.holding:
            if o >= 0:
                gathered[int(o)] = gathered.get(int(o), 0) + 1
        for k, tag in enumerate(self.tags):
            oid = self.scenario.objects[k].id
            count = gathered.get(oid, 0)
            tag.set_visible(count > 0 and bool(live[k]))
            if count:
                tag.set_text(f"{count}/{self.required[k]}")
                tag.set_position((at[k, 0] + 1.5, at[k, 1] - 1.5))
        self.robots.set_offsets(frame.positions.astype(float))
        self.robots.set_facecolor([self.palette.get(s, "#969696") for s in frame.states])
        if self.team:
            self._draw_team(frame)
        delivered = int(frame.delivered.sum())
        self.title.set_text(
            f"{self.result.protocol.upper()}  step {frame.t:>6}   delivered {delivered}/{n_obj}   "
            f"N={self.scenario.n_agents}  {self.scenario.grid.width}×{self.scenario.grid.height}"
            + (f"   {self.heading}" if self.heading else "")
        )

    def _draw_team(self, frame: Frame) -> None:
        """Who is in the team: faces, edges and crosses of the robots; the partition, the news."""
        team = frame.team or ("",) * len(frame.states)
        faces: list[str] = []
        edges: list[str] = []
        widths: list[float] = []
        styles: list[Any] = []
        sizes: list[float] = []
        for k, (state, where) in enumerate(zip(frame.states, team)):
            face, edge, width, style, size = self.palette.get(state, "#969696"), "k", 0.7, "solid", 34
            if frame.sides and frame.sides[k] >= 0:
                edge, width, size = SIDES[frame.sides[k] % len(SIDES)], 1.6, 48
            if where == OUT:
                face, edge, width, style, size = MEMBERSHIP_COLOURS["OUT"], OUT_EDGE, 1.3, "dashed", 70
            elif where == SILENT:
                edge, width, size = SILENT_EDGE, 2.0, 70
            elif where == ABSENT:
                face, edge, width, style, size = "none", OUT_EDGE, 1.3, "dotted", 70
            elif where == DEAD:
                size = 48
            faces.append(face)
            edges.append(edge)
            widths.append(width)
            styles.append(style)
            sizes.append(size)
        self.robots.set_facecolor(faces)
        self.robots.set_edgecolor(edges)
        self.robots.set_linewidth(widths)
        self.robots.set_linestyle(styles)
        self.robots.set_sizes(sizes)
        dead = np.array([where == DEAD for where in team], dtype=bool)
        self.crosses.set_offsets(frame.positions[dead].astype(float) if dead.any() else np.empty((0, 2)))
        self.crosses.set_visible(bool(dead.any()))
        self.split.set_text(f"partition {frame.split}" if frame.split else "")
        self.split.set_visible(bool(frame.split))
        self.note.set_text(frame.note)
        self.note.set_visible(bool(frame.note))
