"""The peers over DDS (real rclpy processes): the auction's bids and awards travel on their own
topics (/ost/bid, /ost/award) between the agent processes and the run equals ``ost sim
--protocol auction``; CCP with the improved planner (an agent parameter) equals ``ost sim
--planner improved``."""

import json

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.protocols.ccp import CcpSettings
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import ost_up, reference, result_json


def test_auction_over_dds_equals_ost_sim(tmp_path):
    scenario = generate_scenario(6, 10, 2, Grid(36, 18), 4)
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, "auction", CoordinationPolicy())
    run = ost_up(
        "--scenario", str(path), "--protocol", "auction", "--json", "--run-dir", str(tmp_path / "run")
    )
    assert run.returncode == 0, run.stderr
    assert expected["completed"] and expected["agreement"] and expected["trigger"] == "auction"
    assert result_json(run.stdout) == expected
    # every bid and award went over DDS (the agents count what they received)
    stats = json.loads((tmp_path / "run" / "result.json.transport.json").read_text())
    assert stats["protocol_messages"] == expected["messages"]
    params = (tmp_path / "run" / "agent.params.yaml").read_text()
    assert "protocol: auction" in params


def test_improved_planner_over_dds_equals_ost_sim(tmp_path):
    scenario = generate_scenario(4, 8, 1, Grid(30, 12), 3)
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, "ccp", CoordinationPolicy(ci=1), settings=CcpSettings("improved"))
    paper = reference(scenario, "ccp", CoordinationPolicy(ci=1))
    run = ost_up(
        "--scenario", str(path), "--planner", "improved", "--json", "--run-dir", str(tmp_path / "run")
    )
    assert run.returncode == 0, run.stderr
    assert result_json(run.stdout) == expected
    assert expected["makespan"] < paper["makespan"]  # the scenario is one where it matters
