"""NCP over DDS (real rclpy processes): negotiation moves travel on /ost/negotiation_offer between the
agent processes and the run equals ``ost sim --protocol ncp``; a negotiator that goes silent is
timed out and the others conclude without it — the same outcome as in-process."""

import json

import pytest

from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines.step import run_steps
from ost_ros.model import Grid
from ost_ros.protocols import make_agents
from ost_ros.protocols.ncp import SPEC as ncp
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import ost_up, reference, result_json


@pytest.mark.parametrize("ci", [1, 8])
def test_ncp_over_dds_equals_ost_sim(tmp_path, ci):
    scenario = generate_scenario(4, 8, 1, Grid(30, 12), 4)
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, "ncp", CoordinationPolicy(ci=ci))
    run = ost_up(
        "--scenario",
        str(path),
        "--protocol",
        "ncp",
        "--ci",
        str(ci),
        "--json",
        "--run-dir",
        str(tmp_path / "run"),
    )
    assert run.returncode == 0, run.stderr
    assert expected["completed"] and expected["agreement"] and expected["protocol"] == "ncp"
    assert result_json(run.stdout) == expected
    # the moves really went over the negotiation topic (the agents count what they received)
    stats = json.loads((tmp_path / "run" / "result.json.transport.json").read_text())
    assert stats["protocol_messages"] == expected["messages"]


def in_process_with_mute(scenario, policy, silent: int, step: int) -> dict:
    agents = make_agents(scenario, "ncp", policy)
    ncp.silence(agents[[a.id for a in scenario.agents].index(silent)], step)
    out = run_steps(scenario, agents).to_dict()
    out["lower_bound"] = lower_bound(scenario).value
    return out


def test_silent_negotiator_over_dds(tmp_path):
    scenario = generate_scenario(4, 8, 1, Grid(30, 12), 3)
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(scenario))
    policy = CoordinationPolicy(ci=8)
    expected = in_process_with_mute(scenario, policy, silent=1, step=0)
    assert expected["completed"] and any("agent(s) 1 silent" in w for w in expected["warnings"])
    assert all(1 not in o["agents"] for o in expected["objects"])
    run = ost_up(
        "--scenario",
        str(path),
        "--protocol",
        "ncp",
        "--ci",
        "8",
        "--json",
        "--mute-negotiation",
        "1:0",
        "--run-dir",
        str(tmp_path / "run"),
    )
    assert run.returncode == 0, run.stderr
    assert result_json(run.stdout) == expected


def test_heterogeneous_team_over_dds(tmp_path):
    # agents of periods 1, 2, 3, 1 (moves every k steps): the DDS run is still the in-process run
    import dataclasses

    from ost_ros.scenario import build_scenario

    base = generate_scenario(4, 6, 5, Grid(30, 12), 3)
    agents = [dataclasses.replace(a, period=k) for a, k in zip(base.agents, (1, 2, 3, 1))]
    scenario = build_scenario(base.grid, base.objects, agents=agents, nmax=3)
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(scenario))
    for protocol in ("ccp", "ncp"):
        expected = reference(scenario, protocol, CoordinationPolicy(ci=2))
        run = ost_up(
            "--scenario",
            str(path),
            "--protocol",
            protocol,
            "--ci",
            "2",
            "--json",
            "--run-dir",
            str(tmp_path / f"run_{protocol}"),
        )
        assert run.returncode == 0, run.stderr
        assert result_json(run.stdout) == expected
