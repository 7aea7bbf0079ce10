"""The coordinator organisation over DDS: agent 0's process alone runs Algorithm Coordination and
broadcasts the schedule on /ost/schedule_update; the run equals ``ost sim --coordination
coordinator`` field by field (N = 4 and 10, event skipping on)."""

import json
import subprocess
import sys

import pytest

from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import ost_up, result_json


@pytest.mark.parametrize("n, m, grid", [(4, 8, Grid(30, 12)), (10, 15, Grid(50, 20))])
def test_coordinator_over_dds_equals_ost_sim(tmp_path, n, m, grid):
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(generate_scenario(n, m, 1, grid, 4)))
    sim = subprocess.run(
        [sys.executable, "-m", "ost_ros", "sim", str(path), "--coordination", "coordinator", "--json"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert sim.returncode == 0, sim.stderr
    run = ost_up(
        "--scenario", str(path), "--coordination", "coordinator", "--json", "--run-dir", str(tmp_path / "run")
    )
    assert run.returncode == 0, run.stderr
    got = result_json(run.stdout)
    assert got == json.loads(sim.stdout)
    assert got["completed"] and got["trigger"] == "CI=1, coordinator"
