"""The workspace built as a ROS user builds it: colcon (colcon-common-extensions from PyPI, pinned
in tests/ros2_tools.lock) against the Jazzy wheels' prefix — the venv, sourced through the
``setup.bash`` ament writes into it, as ``source /opt/ros/jazzy/setup.bash`` on a ROS install — in
a copy of the repository:

    source VENV/setup.bash
    colcon build --base-paths . ost_msgs_py/ost_msgs
    source install/setup.bash
    ros2 launch ost_ros team.launch.py agents:=4 objects:=8 seed:=1 nmax:=4 result_file:=...

and the launched team's result equals ``ost sim --json`` on the same scenario. One build per
session (a module fixture: building ``ost_msgs`` takes a minute or more here). ``ros2 launch``
needs the real ros2 CLI: without it these tests skip, saying why, as tests/ros/test_ros2cli.py.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

from tests.ros.dds_helpers import BIN, REPO, ros_env
from tests.ros.test_ros2cli import ROS2

VENV = BIN.parent
UNDERLAY = VENV / "setup.bash"  # written by bringup_scripts/build_msgs.sh (ament's prefix setup)
NODES = ("agent_node", "membership_node", "watch_node", "world_node")
# what a fresh clone holds, not what runs and builds left in the source tree
IGNORED = shutil.ignore_patterns(
    ".git", ".venv", "build", "install", "log", "__pycache__", "*.egg-info", ".*_cache", ".hypothesis"
)

pytestmark = pytest.mark.skipif(
    ROS2 is None,
    reason="no ros2 CLI for ros2 launch: neither on PATH (a full ROS install) nor in the test venv "
    "(tests/ros2_tools.sh installs it from ../shared/ros2, which this machine lacks)",
)


def user_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    """A shell's environment before it sources anything ROS: what this test process inherited
    from the venv's loader (library path, its re-exec guard) and any ROS prefix taken out."""
    env = dict(extra if extra is not None else os.environ)
    for name in (
        "AMENT_PREFIX_PATH",
        "CMAKE_PREFIX_PATH",
        "COLCON_PREFIX_PATH",
        "PYTHONPATH",
        "LD_LIBRARY_PATH",
        "_ROS_WHEELS_BOOTSTRAP_COMPLETE",
        "VIRTUAL_ENV",
    ):
        env.pop(name, None)
    env["PATH"] = os.pathsep.join(p for p in env["PATH"].split(os.pathsep) if Path(p) != BIN)
    env["ROS_DISTRO"] = "jazzy"
    # colcon runs make with -j<cores> -l<cores>: on a machine shared with other runs the load limit
    # holds it to one job (twice the time); two jobs, as bringup_scripts/build_msgs.sh
    env["MAKEFLAGS"] = "-j2"
    return env


def sourced(ws: Path, command: str, **kw) -> subprocess.CompletedProcess:
    """``command`` in bash after sourcing the ROS prefix and the workspace, as a user types it."""
    script = f'source "{UNDERLAY}" && source "{ws}/install/setup.bash" && {command}'
    return subprocess.run(["bash", "-c", script], capture_output=True, text=True, **kw)


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    colcon = BIN / "colcon"
    if not colcon.exists():
        pytest.fail("no colcon in the test venv: tests/ros2_tools.sh installs it (tests/ros2_tools.lock)")
    assert UNDERLAY.exists(), f"{UNDERLAY} missing: bringup_scripts/build_msgs.sh writes it"
    ws = tmp_path_factory.mktemp("colcon") / "ost"
    shutil.copytree(REPO, ws, ignore=IGNORED, symlinks=True)
    t0 = time.monotonic()
    build = subprocess.run(
        ["bash", "-c", f'source "{UNDERLAY}" && colcon build --base-paths . ost_msgs_py/ost_msgs'],
        cwd=ws,
        capture_output=True,
        text=True,
        env=user_env(),
        timeout=1200,
    )
    took = time.monotonic() - t0
    (ws / "colcon_build.out").write_text(
        build.stdout + build.stderr + f"\n[test] colcon build: {took:.1f} s\n"
    )
    assert build.returncode == 0, (build.stdout + build.stderr)[-4000:]
    assert "Summary: 2 packages finished" in build.stdout, build.stdout[-2000:]
    assert "WARNING" not in build.stdout + build.stderr, (build.stdout + build.stderr)[-2000:]
    return ws


def test_colcon_installs_both_packages_as_ros_expects(workspace, tmp_path):
    ost_ros = workspace / "install" / "ost_ros"
    share = ost_ros / "share" / "ost_ros"
    assert (ost_ros / "share" / "ament_index" / "resource_index" / "packages" / "ost_ros").is_file()
    assert (share / "package.xml").read_text() == (REPO / "package.xml").read_text()
    launch = sorted(p.name for p in (REPO / "launch").glob("*.launch.py"))
    assert sorted(p.name for p in (share / "launch").iterdir()) == launch
    for node in NODES:
        assert os.access(ost_ros / "lib" / "ost_ros" / node, os.X_OK), node
    # every interface the venv's build (build_msgs.sh) has, wherever its .msg files live
    built = workspace / "install" / "ost_msgs" / "share" / "ost_msgs" / "msg"
    want = sorted(p.name for p in (VENV / "share" / "ost_msgs" / "msg").glob("*.msg"))
    assert sorted(p.name for p in built.glob("*.msg")) == want

    env = user_env()
    prefix = sourced(workspace, "ros2 pkg prefix ost_ros && ros2 pkg prefix ost_msgs", env=env, cwd=tmp_path)
    assert prefix.stdout.split() == [str(ost_ros), str(workspace / "install" / "ost_msgs")], prefix.stderr
    exes = sourced(workspace, "ros2 pkg executables ost_ros", env=env, cwd=tmp_path).stdout.split("\n")
    assert {f"ost_ros {n}" for n in NODES} <= set(exes), exes
    # the workspace's code, not the venv's editable install, runs
    where = sourced(
        workspace,
        "python3 -c 'import ost_ros, world_node, ost_msgs.msg as m; print(ost_ros.__file__, m.__file__)'",
        env=env,
        cwd=tmp_path,
    )
    assert where.returncode == 0, where.stderr
    assert all(f.startswith(str(workspace / "install")) for f in where.stdout.split()), where.stdout


def test_ros2_launch_from_the_workspace_gives_the_ost_sim_result(workspace, tmp_path, domain):
    result = tmp_path / "result.json"
    team = "agents:=4 objects:=8 seed:=1 nmax:=4"
    launch = subprocess.Popen(
        [
            "bash",
            "-c",
            f'source "{UNDERLAY}" && source "{workspace}/install/setup.bash" && '
            f'exec ros2 launch ost_ros team.launch.py {team} result_file:="{result}"',
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=user_env(ros_env(domain)),
        cwd=tmp_path,
        start_new_session=True,
    )
    try:
        out, _ = launch.communicate(timeout=300)
    finally:
        if launch.poll() is None:
            os.killpg(launch.pid, signal.SIGINT)
            launch.wait(30)
    assert launch.returncode == 0, out[-3000:]
    assert "Traceback" not in out, out[-3000:]
    # (launch_ros finds the nodes as ros2 pkg prefix does: in the workspace, as the test above shows)

    scenario = tmp_path / "s.yaml"
    generate = [str(BIN / "ost"), "generate", "--agents", "4", "--objects", "8", "--seed", "1", "--nmax", "4"]
    subprocess.run([*generate, "-o", str(scenario)], check=True)
    sim = subprocess.run([str(BIN / "ost"), "sim", str(scenario), "--json"], capture_output=True, text=True)
    assert sim.returncode == 0, sim.stderr
    assert json.loads(result.read_text()) == json.loads(sim.stdout)
