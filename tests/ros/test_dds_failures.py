"""Robot failures over DDS: an agent process killed with SIGKILL mid-run (by itself at a given
step, or from outside at an arbitrary moment) is detected by its lost liveliness, declared failed
in the step the world was at, and the survivors re-coordinate — the result is exactly the
in-process run with that failure (``ost sim --fail AGENT:STEP``), for every protocol of the
registry that recovers, under each organisation it runs (CCP's coordinator organisation too).
Too few survivors end the run with a result that says why."""

import subprocess

import pytest

from ost_ros import protocols
from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import kill_mid_run, ost_up, reference, result_json


def scenario_file(tmp_path, n=4, m=8, seed=1, grid=Grid(30, 12), nmax=3):
    s = generate_scenario(n, m, seed, grid, nmax)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(s))
    return s, path


def in_process(scenario, got, protocol="ccp"):
    failures = {f["agent"]: f["step"] for f in got["failures"]}
    r = simulate(scenario, protocol, CoordinationPolicy(ci=1), failures=failures)
    r.lower_bound = lower_bound(scenario).value
    return r.to_dict()


def test_agent_killing_itself_at_a_step_equals_ost_sim_with_that_failure(tmp_path):
    scenario, path = scenario_file(tmp_path)
    run = ost_up(
        "--scenario", str(path), "--json", "--kill-agent", "2:40", "--run-dir", str(tmp_path / "run")
    )
    assert run.returncode == 0, run.stderr
    got = result_json(run.stdout)
    assert [f["agent"] for f in got["failures"]] == [2] and got["failures"][0]["step"] >= 40
    assert got == in_process(scenario, got)
    assert got["completed"] and got["agreement"]
    assert "agent_2 (pid" in run.stderr and "died mid-run" in run.stderr
    world = (tmp_path / "run" / "world.log").read_text()
    assert "agent 2 lost (no liveliness for 2 x 1 s)" in world
    assert "Traceback" not in world


def test_agent_killed_from_outside_at_any_moment(tmp_path):
    scenario, path = scenario_file(tmp_path, n=6, m=10, seed=3, grid=Grid(36, 18))
    run_dir = tmp_path / "run"
    # skipping off and a short lease: the kill lands mid-run, wherever the lockstep is
    up = kill_mid_run(
        run_dir, "agent_4", 30, "--scenario", str(path), "--json", "--no-skip", "--failure-timeout", "1"
    )
    out, err = up.stdout, up.stderr
    assert up.returncode == 0, err
    got = result_json(out)
    assert [f["agent"] for f in got["failures"]] == [4] and got["failures"][0]["step"] >= 30
    assert got == in_process(scenario, got)
    assert got["completed"]
    leftovers = subprocess.run(["pgrep", "-f", str(run_dir)], capture_output=True, text=True).stdout
    assert not leftovers.strip()


def test_too_few_survivors_end_with_what_could_not_be_done(tmp_path):
    scenario, path = scenario_file(tmp_path, nmax=4)
    run = ost_up("--scenario", str(path), "--json", "--kill-agent", "1:0", "--run-dir", str(tmp_path / "run"))
    got = result_json(run.stdout)
    assert got == in_process(scenario, got)
    assert not got["completed"] and "cannot be delivered" in got["error"]
    assert "need up to 4 robots and 3 survive" in got["error"]


def test_hcp_recovers_from_a_failed_agent_as_in_process(tmp_path):
    scenario, path = scenario_file(tmp_path)
    run = ost_up(
        "--scenario",
        str(path),
        "--json",
        "--protocol",
        "hcp",
        "--kill-agent",
        "3:10",
        "--run-dir",
        str(tmp_path / "run"),
    )
    assert run.returncode == 0, run.stderr
    got = result_json(run.stdout)
    assert got["completed"] and got["failures"][0]["agent"] == 3
    assert got == in_process(scenario, got, "hcp")


@pytest.mark.parametrize(
    "protocol, organisation",
    [
        (spec.name, organisation)
        for spec in protocols.REGISTRY.values()
        if spec.capabilities.recovers_failures
        for organisation in spec.capabilities.organisations
    ],
)
def test_every_protocol_recovers_from_a_killed_agent_as_in_process(tmp_path, protocol, organisation):
    scenario, path = scenario_file(tmp_path)
    policy = CoordinationPolicy(ci=1, organisation=organisation)
    run = ost_up(
        "--scenario",
        str(path),
        "--json",
        "--protocol",
        protocol,
        "--coordination",
        organisation,
        "--kill-agent",
        "0:10",  # the coordinator, a negotiator, an auctioneer
        "--run-dir",
        str(tmp_path / "run"),
    )
    assert run.returncode == 0, run.stderr
    got = result_json(run.stdout)
    assert got["completed"] and got["agreement"] and got["failures"][0]["agent"] == 0
    failures = {f["agent"]: f["step"] for f in got["failures"]}
    assert got == reference(scenario, protocol, policy, failures=failures)
