"""Over DDS (real rclpy processes): a run gives exactly the in-process simulator's result."""

import pytest

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import ost_up, reference, result_json

CASES = [  # (agents, objects, seed, width, height, ci)
    (4, 8, 1, 30, 12, 1),
    (4, 8, 1, 30, 12, 8),  # CI = M: coordinate once, after the whole search
    (10, 12, 2, 40, 20, 1),
    (10, 12, 2, 40, 20, 12),
]


def _reference(tmp_path, n, m, seed, w, h, ci, protocol="ccp"):
    scenario = generate_scenario(n, m, seed, Grid(w, h), 4)
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(scenario))
    return path, reference(scenario, protocol, CoordinationPolicy(ci=ci))


@pytest.mark.parametrize("n, m, seed, w, h, ci", CASES)
def test_dds_run_equals_ost_sim(tmp_path, n, m, seed, w, h, ci):
    path, expected = _reference(tmp_path, n, m, seed, w, h, ci)
    run = ost_up("--scenario", str(path), "--ci", str(ci), "--json", "--run-dir", str(tmp_path / "run"))
    assert run.returncode == 0, run.stderr
    assert expected["completed"] and expected["agreement"]
    assert result_json(run.stdout) == expected
    assert "discovery complete" in run.stderr


def test_without_event_skipping_too(tmp_path):
    path, expected = _reference(tmp_path, 4, 8, 3, 30, 12, 1)
    run = ost_up("--scenario", str(path), "--json", "--no-skip", "--run-dir", str(tmp_path / "run"))
    assert run.returncode == 0, run.stderr
    assert result_json(run.stdout) == expected
    stats = (tmp_path / "run" / "result.json.transport.json").read_text()
    assert '"skipped_steps": 0' in stats


def test_generated_scenario_and_text_output(tmp_path):
    run = ost_up(
        "--agents",
        "4",
        "--objects",
        "5",
        "--seed",
        "7",
        "--width",
        "24",
        "--height",
        "12",
        "--nmax",
        "3",
        "--run-dir",
        str(tmp_path / "run"),
    )
    assert run.returncode == 0, run.stderr
    assert "completed" in run.stdout and "makespan" in run.stdout
    for name in ("world", "agent_0", "agent_3"):
        assert (tmp_path / "run" / f"{name}.log").exists()
    assert not list((tmp_path / "run").glob("*.pid"))  # torn down


def test_hcp_over_dds_equals_ost_sim(tmp_path):
    path, expected = _reference(tmp_path, 4, 8, 1, 30, 12, 1, protocol="hcp")
    run = ost_up("--scenario", str(path), "--protocol", "hcp", "--json", "--run-dir", str(tmp_path / "run"))
    assert run.returncode == 0, run.stderr
    assert result_json(run.stdout) == expected


def test_bad_arguments_are_one_line(tmp_path):
    for args, text in [
        (("--agents", "x"), "--agents: expected a non-negative integer"),
        (("--scenario", str(tmp_path / "none.yaml")), "no such file"),
        (("--agents", "4"), "give --agents N --objects M --seed S"),
        (("--bogus",), "unknown argument"),
    ]:
        run = ost_up(*args)
        assert run.returncode == 2
        assert text in run.stderr and len(run.stderr.strip().splitlines()) == 1
