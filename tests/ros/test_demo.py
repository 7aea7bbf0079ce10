"""The main job, as a new user runs it: bringup_scripts/demo.sh sets up, runs the paper's
scenario over DDS (one process per robot) and confirms it is identical to ``ost sim``."""

import shutil
import subprocess

from tests.ros.dds_helpers import REPO, ros_env


def test_the_demo_runs_and_agrees_with_the_simulator(domain):
    # Fewer objects than the demo's 20: the same path through every step, in a third of the time.
    out = subprocess.run(
        ["bash", str(REPO / "bringup_scripts" / "demo.sh"), "--objects", "3", "--seed", "2"],
        capture_output=True,
        text=True,
        timeout=300,
        env=ros_env(domain),  # this test's own domain (the demo takes ROS_DOMAIN_ID if set)
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "== identical to the in-process simulator (ost sim --json) ==" in out.stdout
    assert "objects         3/3 delivered" in out.stdout  # the run's result, as `ost sim` prints it
    logs = out.stdout.rsplit("logs: ", 1)[1].strip()
    shutil.rmtree(logs.removesuffix("/ros"), ignore_errors=True)  # the demo keeps its run dir


def test_a_bad_flag_is_one_line_and_exit_code_2():
    out = subprocess.run(
        ["bash", str(REPO / "bringup_scripts" / "demo.sh"), "--agents"], capture_output=True, text=True
    )
    assert out.returncode == 2
    assert out.stderr.strip() == "demo.sh: error: --agents needs a value"
