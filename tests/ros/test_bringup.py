"""Over DDS (real rclpy processes): a run gives exactly the in-process simulator's result — CCP
under several teams and triggers, and every protocol of the registry."""

import json
import subprocess
import time

import pytest

from ost_ros import protocols
from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import BIN, REPO, UP, ost_up, reference, result_json, ros_env

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


@pytest.mark.parametrize("protocol", protocols.names())
def test_every_protocol_over_dds_equals_ost_sim(tmp_path, protocol):
    path, expected = _reference(tmp_path, 4, 8, 1, 30, 12, 1, protocol=protocol)
    run_dir = tmp_path / "run"
    run = ost_up("--scenario", str(path), "--protocol", protocol, "--json", "--run-dir", str(run_dir))
    assert run.returncode == 0, run.stderr
    assert expected["completed"] and result_json(run.stdout) == expected
    # every protocol message went over DDS (the world counts what the agents said they sent)
    stats = json.loads((run_dir / "result.json.transport.json").read_text())
    assert stats["protocol_messages"] == expected["messages"]


def test_bad_arguments_are_one_line(tmp_path):
    for args, text in [
        (("--agents", "x"), "--agents: invalid int 'x'"),
        (("--scenario", str(tmp_path / "none.yaml")), "no such file"),
        (("--agents", "4"), "give --agents N --objects M"),
        (("--bogus",), "unrecognized arguments: --bogus"),
        (
            ("--agents", "4", "--objects", "4", "--seed", "1", "--protocol", "bogus"),
            "--protocol: 'bogus' is not one of",
        ),
    ]:
        run = ost_up(*args)
        assert run.returncode == 2
        assert text in run.stderr and len(run.stderr.strip().splitlines()) == 1


def test_background_run_keeps_its_result_until_brought_down(tmp_path):
    path, expected = _reference(tmp_path, 4, 6, 1, 30, 12, 2)
    run_dir = tmp_path / "run"
    up = ost_up("--scenario", str(path), "--ci", "2", "--background", "--run-dir", str(run_dir), timeout=120)
    assert up.returncode == 0, up.stderr
    assert up.stdout.strip() == str(run_dir) and "discovery complete" in up.stderr
    deadline = time.monotonic() + 60
    while not (run_dir / "result.json").exists():
        assert time.monotonic() < deadline, (run_dir / "ost_up.log").read_text()
        time.sleep(0.1)
    domain = up.stderr.split("ROS_DOMAIN_ID=")[1].split(",")[0]
    try:
        # the run is over, the world is still up: a reader that comes now gets the result
        echoed = subprocess.run(
            [str(BIN / "ost"), "ros", "topic", "echo", "/ost/result", "--once", "--spin-time", "20"],
            capture_output=True,
            text=True,
            env=ros_env(int(domain)),
            timeout=60,
        )
        assert f'"makespan": {expected["makespan"]}' in echoed.stdout, echoed.stderr
        assert (run_dir / "world.pid").exists()
    finally:
        down = subprocess.run(
            ["bash", str(REPO / "bringup_scripts" / "ost_down.sh"), str(run_dir)],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert down.returncode == 0, down.stderr
    assert not list(run_dir.glob("*.pid"))


def test_background_run_that_cannot_start_says_so(tmp_path):
    # 21 processes cannot all start and match within 1 s on this machine: the supervisor's
    # --timeout ends the run before it starts, and --background reports that with exit 1
    up = ost_up(
        "--agents",
        "20",
        "--objects",
        "4",
        "--seed",
        "1",
        "--timeout",
        "1",
        "--background",
        "--run-dir",
        str(tmp_path / "run"),
        timeout=120,
    )
    assert up.returncode == 1, up.stderr
    assert "failed to start" in up.stderr and "timeout" in up.stderr


def test_help_prints_usage_only():
    out = subprocess.run(["bash", str(UP), "--help"], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0 and out.stdout.startswith("usage: ost up")
    assert "set -uo" not in out.stdout and "#" not in out.stdout
