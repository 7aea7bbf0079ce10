"""The world node checkpoints its truth before publishing each step; killed (SIGKILL) in the
middle of a run and restarted with ``resume:=true`` (ost_up.sh --respawn-world), it continues the
run, and the result is exactly the uninterrupted run's (= ``ost sim``)."""

import pickle
import subprocess

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import BIN, kill_mid_run, reference, result_json


def test_world_killed_mid_run_resumes_from_checkpoint(tmp_path):
    scenario = generate_scenario(4, 8, 1, Grid(30, 12), 4)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, "ccp", CoordinationPolicy(ci=1))
    run_dir = tmp_path / "run"
    # skipping off: a round trip per step, so the run lasts long enough to be interrupted
    up = kill_mid_run(
        run_dir, "world", 40, "--scenario", str(path), "--json", "--no-skip", "--respawn-world", "1"
    )
    out, err = up.stdout, up.stderr
    assert up.returncode == 0, err
    assert "restarting it from its checkpoint" in err
    assert "resuming step" in (run_dir / "world.log").read_text()
    assert result_json(out) == expected


def test_resume_refuses_a_foreign_checkpoint(tmp_path, domain):
    from tests.ros.dds_helpers import ros_env

    a = generate_scenario(2, 2, 1, Grid(12, 6), 2)
    path = tmp_path / "a.yaml"
    path.write_text(dump_scenario(a))
    ckpt = tmp_path / "c.pkl"
    ckpt.write_bytes(pickle.dumps({"fingerprint": "someone-else"}))
    r = subprocess.run(
        [
            str(BIN / "world_node"),
            "--ros-args",
            "-p",
            f"scenario:={path}",
            "-p",
            f"checkpoint_file:={ckpt}",
            "-p",
            "resume:=true",
            "-p",
            "insecure:=true",
        ],
        capture_output=True,
        text=True,
        env=ros_env(domain),
        timeout=60,
    )
    assert r.returncode == 2
    assert "is not a checkpoint of this scenario" in r.stderr and "Traceback" not in r.stderr
