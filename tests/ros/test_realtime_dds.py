"""Realtime runs over DDS (``ost_up.sh --realtime``): one process per robot, no barrier, each robot
commanding its base through an action served by the world. Time is real here, so the tests assert
what the protocol promises — every object delivered by exactly its n_i robots, the same schedule on
every robot (0 disagreements, every final view alike), a failed robot recovered from — never exact
steps (those live in the in-process latency model, tests/ost_ros/realtime)."""

from __future__ import annotations

import pytest

from ost_ros.model import Grid
from ost_ros.realtime.run import REALTIME
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import ost_up, result_json

pytestmark = pytest.mark.dds


def _scenario(tmp_path, agents=4, objects=6, seed=1):
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(generate_scenario(agents, objects, seed, Grid(30, 12), 3)))
    return path


def _kept_its_promise(result: dict, scenario_objects: int) -> None:
    assert result["mode"] == "realtime" and result["completed"], result.get("error")
    assert result["disagreements"] == 0 and result["agreement"]
    assert len(result["objects"]) == scenario_objects
    for o in result["objects"]:
        assert o["delivered"] is not None
    groups = {e["object"]: e["agents"] for e in result["schedule"]}
    for o in result["objects"]:  # carried by exactly the group every robot scheduled
        assert sorted(o["agents"]) == sorted(groups[o["id"]])
    assert set(result["lag"]) == {str(a["id"]) for a in result["agents"]}


@pytest.mark.parametrize("protocol", REALTIME)
def test_a_realtime_run_keeps_the_protocols_promise(tmp_path, protocol):
    path = _scenario(tmp_path)
    run = ost_up(
        "--scenario", str(path), "--protocol", protocol, "--realtime", "--rtf", "200",
        "--json", "--run-dir", str(tmp_path / "run"), "--timeout", "180",
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    result = result_json(run.stdout)
    _kept_its_promise(result, 6)
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
