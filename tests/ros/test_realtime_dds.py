"""Realtime runs over DDS (``ost_up.sh --realtime``): one process per robot, no barrier, each robot
commanding its base through an action served by the world. Time is real here, so the tests assert
what the protocol promises — every object delivered by exactly its n_i robots, the same schedule on
every robot (0 disagreements, every final view alike), a failed robot recovered from — never exact
steps (those live in the in-process latency model, tests/ost_ros/realtime)."""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
import time

import pytest

from ost_ros.model import Grid
from ost_ros.realtime.run import REALTIME
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import (
    BIN,
    Processes,
    free_domain,
    kept_its_promise,
    ost_up,
    release_domain,
    result_json,
)

pytestmark = pytest.mark.dds


def _scenario(tmp_path, agents=4, objects=6, seed=1):
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(generate_scenario(agents, objects, seed, Grid(30, 12), 3)))
    return path


@pytest.mark.parametrize("protocol", REALTIME)
def test_a_realtime_run_keeps_the_protocols_promise(tmp_path, protocol):
    path = _scenario(tmp_path)
    run = ost_up(
        "--scenario", str(path), "--protocol", protocol, "--realtime", "--rtf", "200",
        "--json", "--run-dir", str(tmp_path / "run"), "--timeout", "180",
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    result = result_json(run.stdout)
    kept_its_promise(result, 6)
    assert result["rtf"] == 200
    for a in result["agents"]:  # the record is the world's: every robot came home
        assert a["cost"] > 0


def test_a_robot_killed_mid_run_is_recovered_from(tmp_path):
    path = _scenario(tmp_path, agents=5, objects=8, seed=2)
    run = ost_up(
        "--scenario", str(path), "--realtime", "--rtf", "50", "--kill-agent", "2:40",
        "--json", "--run-dir", str(tmp_path / "run"), "--timeout", "180",
    )  # fmt: skip
    assert run.returncode in (0, 1), run.stderr[-3000:]
    result = result_json(run.stdout)
    assert [f["agent"] for f in result["failures"]] == [2]
    assert result["disagreements"] == 0 and result["agreement"]
    movable = [o for o in result["objects"] if o["delivered"] is not None]
    # every object the four survivors can carry is delivered (n_i <= 3 here: all of them)
    assert len(movable) == 8, result.get("error")
    assert "agent_2" in run.stderr and "died mid-run" in run.stderr


# A publisher of detections that never publishes: the cut-off robots' subscriptions match it
# (so they start), and hear nothing.
SILENT = r"""
import sys, rclpy
from ost_msgs.msg import Detection
rclpy.init()
node = rclpy.create_node("silent_detections", namespace="/ost")
pubs = [node.create_publisher(Detection, topic, 10) for topic in sys.argv[1:]]
rclpy.spin(node)
"""


def test_robots_cut_off_from_their_detections_still_find_every_object(tmp_path):
    """A goal's result repeats the detections since the previous result, so a detection lost on
    its topic (on a lossy link DDS repairs it late, maybe after the robot has ended its search
    and said so) still reaches the robot in order. Here every robot's detections topic is
    remapped to one nobody publishes on: whatever a robot finds, it learns from its results."""
    path = _scenario(tmp_path)
    run_dir = tmp_path / "run"
    prep = [str(BIN / "ost"), "up", "--prepare", "--scenario", str(path), "--realtime", "--rtf", "50",
            "--run-dir", str(run_dir)]  # fmt: skip
    subprocess.run(prep, check=True, capture_output=True)
    lines = [line.split("\t") for line in (run_dir / "processes").read_text().splitlines()]
    agents = [name for name, _host, _cmd in lines if name != "world"]
    domain = free_domain()
    procs = Processes(run_dir, domain)
    try:
        procs.run("silent", [sys.executable, "-c", SILENT, *(f"{a}/no_detections" for a in agents)])
        for name, _host, cmd in lines:
            cut = [] if name == "world" else ["-r", f"{name}/detections:={name}/no_detections"]
            procs.run(name, [*shlex.split(cmd), *cut])
        end = time.monotonic() + 180
        while not (run_dir / "result.json").exists():  # written whole (tmp + rename)
            assert procs.procs["world"].poll() is None, procs.log("world")[-3000:]
            assert time.monotonic() < end, (
                f"no result in 180 s; progress {(run_dir / 'progress').read_text()}"
            )
            time.sleep(0.2)
        result = json.loads((run_dir / "result.json").read_text())
    finally:
        procs.stop()
        release_domain(domain)
    kept_its_promise(result, 6)
    for a in agents:  # not one detection came by the topic
        assert "detection Detection" not in procs.log(a)


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (("--protocol", "hcp"), "hcp does not run without a barrier"),
        (("--planner", "improved"), "--planner improved does not run without a barrier"),
        (("--respawn-world", "1"), "--respawn-world: is for the lockstep run"),
    ],
)
def test_what_does_not_run_without_a_barrier_is_one_line(tmp_path, args, text):
    path = _scenario(tmp_path)
    run = ost_up("--scenario", str(path), "--realtime", *args, "--run-dir", str(tmp_path / "run"))
    assert run.returncode == 2
    assert text in run.stderr and len(run.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "run" / "world.pid").exists()


def test_lockstep_only_options_need_realtime(tmp_path):
    path = _scenario(tmp_path)
    run = ost_up("--scenario", str(path), "--rtf", "100", "--run-dir", str(tmp_path / "run"))
    assert run.returncode == 2 and "--rtf: needs --realtime" in run.stderr
