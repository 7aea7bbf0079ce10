"""Animations: GIF and MP4 files with one picture per frame; bad targets are one-line errors
before any run (``ost sim --animate``)."""

import dataclasses
import re
import subprocess
import sys

import pytest
from PIL import Image

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from ost_ros.watch.animate import AnimationError, animate, check_target
from ost_ros.watch.frames import FrameRecorder

OST = [sys.executable, "-m", "ost_ros"]


@pytest.fixture(scope="module")
def recorded():
    scenario = generate_scenario(4, 6, 1, Grid(40, 16), 3)
    rec = FrameRecorder(scenario, target=40)
    result = simulate(scenario, "hcp", CoordinationPolicy(), on_step=rec, engine="step")
    return scenario, result, rec.finish()


def test_gif_has_one_picture_per_frame(recorded, tmp_path):
    scenario, result, frames = recorded
    out = animate(scenario, result, frames, tmp_path / "run.gif", fps=10)
    assert out.frames == len(frames) and out.bytes > 0
    with Image.open(tmp_path / "run.gif") as im:
        assert im.n_frames == len(frames)
        assert im.info["duration"] == 100
        first = im.convert("RGB")
        im.seek(len(frames) - 1)
        last = im.convert("RGB")
    assert first.tobytes() != last.tobytes()  # the robots moved


def test_mp4_through_the_shipped_ffmpeg(recorded, tmp_path):
    import imageio_ffmpeg

    scenario, result, frames = recorded
    animate(scenario, result, frames, tmp_path / "run.mp4", fps=25)
    n, seconds = imageio_ffmpeg.count_frames_and_secs(str(tmp_path / "run.mp4"))
    assert n == len(frames)
    assert seconds == pytest.approx(len(frames) / 25, abs=0.1)


@pytest.mark.parametrize(
    "name, why", [("run.avi", "unsupported format '.avi'"), ("run", "unsupported format '(none)'")]
)
def test_bad_targets_are_named(tmp_path, name, why):
    with pytest.raises(AnimationError, match=re.escape(why)):
        check_target(tmp_path / name)
    with pytest.raises(AnimationError, match="no such directory"):
        check_target(tmp_path / "missing" / "run.gif")


def test_cli_animates_and_refuses_bad_input(tmp_path):
    scenario = generate_scenario(3, 3, 1, Grid(20, 8), 2)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    out = subprocess.run(
        [*OST, "sim", str(path), "--animate", str(tmp_path / "a.gif"), "--every", "5"],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stderr
    assert "animation:" in out.stderr and (tmp_path / "a.gif").stat().st_size > 0
    assert out.stdout == subprocess.run([*OST, "sim", str(path)], capture_output=True, text=True).stdout
    for argv, why in (
        (["--animate", str(tmp_path / "a.avi")], "unsupported format '.avi'"),
        (["--animate", str(tmp_path / "a.gif"), "--engine", "event"], "needs every step"),
        (["--animate", str(tmp_path / "a.gif"), "--fps", "0"], "--fps"),
    ):
        bad = subprocess.run([*OST, "sim", str(path), *argv], capture_output=True, text=True)
        assert bad.returncode == 2, bad.stderr
        assert why in bad.stderr and "Traceback" not in bad.stderr
        assert len(bad.stderr.strip().splitlines()) == 1


def test_frames_of_a_run_without_a_barrier_show_the_team(tmp_path):
    """The same scene, a line and a legend row more: who is in the team, the partition."""
    from ost_ros.realtime.net import Latency, Split
    from ost_ros.realtime.run import run_realtime
    from ost_ros.watch.frames import RealtimeRecorder

    scenario = generate_scenario(4, 6, 1, Grid(40, 16), 3)
    rec = RealtimeRecorder(scenario, every=10)
    result, _ = run_realtime(
        scenario,
        latency=Latency(3, 3),
        silences=[(1, 20.0, 40.0)],
        joins={3: 30.0},
        failures={2: 80},
        splits=[Split((frozenset({0, 1}), frozenset({2, 3})), 50.0, 20.0)],
        observe=rec,
    )
    frames = rec.finish()
    out = animate(scenario, result, frames, tmp_path / "rt.gif", heading="latency 3+0..3")
    with Image.open(tmp_path / "rt.gif") as im:
        assert im.n_frames == len(frames)
        height = im.size[1]
    lockstep = animate(
        scenario, result, [dataclasses.replace(f, team=()) for f in frames[:3]], tmp_path / "ls.gif"
    )
    with Image.open(lockstep.path) as im:
        assert im.size[1] < height  # (the lockstep's frames keep their size)
    assert out.frames == len(frames)
