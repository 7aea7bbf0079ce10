"""Negotiated search areas over DDS: ``ost_up.sh --partition negotiated`` negotiates the robots'
regions once (by speed and private forbidden zones), every process loads that scenario, and the
run equals ``ost sim --partition negotiated`` field by field."""

import json
import subprocess
import sys

import yaml

from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import ost_up, result_json


def test_negotiated_partition_over_dds_equals_ost_sim(tmp_path):
    s = generate_scenario(4, 8, 2, Grid(40, 16), 2)
    d = yaml.safe_load(dump_scenario(s))
    for a, period in zip(d["agents"], (1, 1, 2, 3)):
        a["period"] = period
    d["agents"][3]["forbidden"] = [[0, 0, 12, 6]]
    path = tmp_path / "team.yaml"
    path.write_text(yaml.safe_dump(d))
    sim = subprocess.run(
        [sys.executable, "-m", "ost_ros", "sim", str(path), "--partition", "negotiated", "--json"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert sim.returncode == 0, sim.stderr
    run = ost_up(
        "--scenario", str(path), "--partition", "negotiated", "--json", "--run-dir", str(tmp_path / "run")
    )
    assert run.returncode == 0, run.stderr
    assert "search areas negotiated: team search time" in run.stderr
    assert result_json(run.stdout) == json.loads(sim.stdout)
    assert result_json(run.stdout)["completed"]
