"""Set-up says what it does and nothing when there is nothing to do: bringup_scripts/setup.sh (with
build_msgs.sh) and tests/ros2_tools.sh print one line per stage that had work, with its time, and
a run on a ready venv — this test's — prints nothing on stderr and the venv on stdout's last line.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
VENV = Path(sys.executable).parent.parent


def run(*argv: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["bash", *argv], capture_output=True, text=True, env=env or dict(os.environ, OST_VENV=str(VENV))
    )


def test_setup_on_a_ready_venv_prints_nothing_but_the_venv():
    out = run(str(REPO / "bringup_scripts" / "setup.sh"))
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""
    assert out.stdout.splitlines()[-1] == str(VENV)


def test_build_msgs_and_ros2_tools_with_nothing_to_do_are_silent():
    built = run(str(REPO / "bringup_scripts" / "build_msgs.sh"), str(VENV))
    assert (built.returncode, built.stderr, built.stdout) == (0, "", "")
    tools = run(str(REPO / "tests" / "ros2_tools.sh"), str(VENV))
    assert tools.returncode == 0, tools.stderr
    sources = Path(os.environ.get("OST_ROS2_SOURCES", REPO.parent / "shared" / "ros2"))
    if (sources / "install.sh").exists():
        assert tools.stderr == ""
    else:  # the one note that says why the real-CLI tests will skip
        assert tools.stderr.startswith("ros2_tools: no ROS 2 CLI sources at "), tools.stderr


def test_a_stage_line_names_the_stage_and_its_time():
    script = f'. "{REPO}/bringup_scripts/stage.sh"; stage_begin "doing it"; stage_end "it done"'
    out = run("-c", script)
    assert re.fullmatch(r"setup: it done \(\d\.\d s\)\n", out.stderr), out.stderr
    quiet = run("-c", script, env=dict(os.environ, OST_SETUP_QUIET="1"))
    assert quiet.stderr == ""
