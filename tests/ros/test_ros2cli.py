"""The product with the tools a ROS user has: the real ros2 CLI (ros2cli 0.32.2) and ros2 launch
against real runs. ``ros2`` comes from a full ROS install on PATH or from the test venv
(tests/ros2_tools.sh installs it from ../shared/ros2); without either these tests skip, saying so.

Over a run: ``ros2 topic list -t`` shows each message kind on its own typed topic,
``ros2 topic echo`` prints an ObjectFound's fields, ``ros2 interface show`` the interface,
``ros2 param describe`` a parameter's descriptor and ``ros2 param set`` is refused (read-only),
``ros2 pkg executables`` lists the nodes, ``ros2 run`` starts an agent, and ``ros2 launch
ost_ros team.launch.py`` runs a whole team — every result equal to ``ost sim``.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import BIN, make_keys, reference, ros_env, wait_subscribers
from tests.ros.test_graph import expected_topics

VENV = BIN.parent


def find_ros2() -> str | None:
    exe = BIN / "ros2"
    return str(exe) if exe.exists() else shutil.which("ros2")


ROS2 = find_ros2()
pytestmark = pytest.mark.skipif(
    ROS2 is None,
    reason="no ros2 CLI: neither on PATH (a full ROS install) nor in the test venv "
    "(tests/ros2_tools.sh installs it from ../shared/ros2, which this machine lacks)",
)


@pytest.fixture(autouse=True)
def stop_daemon(domain):
    """``ros2 topic echo`` starts a ros2 daemon on the test's domain (it has no --no-daemon);
    the daemon would outlive the test and show up in the next graph on that domain."""
    yield
    ros2(domain, "daemon", "stop", timeout=60)


def cli_env(domain: int) -> dict[str, str]:
    env = ros_env(domain)
    prefixes = [str(VENV), *filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(":"))]
    env.update(
        AMENT_PREFIX_PATH=":".join(dict.fromkeys(prefixes)),
        ROS_DISTRO="jazzy",
        RMW_IMPLEMENTATION="rmw_fastrtps_cpp",
    )
    return env


def ros2(domain: int, *args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(ROS2), *args], capture_output=True, text=True, env=cli_env(domain), timeout=timeout
    )


def until(predicate, what: str, seconds: float = 60):
    """Poll ``predicate`` (returning a value or None) until it gives a value, with a deadline."""
    end = time.monotonic() + seconds
    while True:
        got = predicate()
        if got is not None:
            return got
        assert time.monotonic() < end, f"no {what} after {seconds} s"


def test_interface_and_package_are_known(domain):
    shown = ros2(domain, "interface", "show", "ost_msgs/msg/ObjectFound")
    assert shown.returncode == 0, shown.stderr
    for line in (
        "int64 step",
        "uint32 seq",
        "int32 sender",
        "ObjectInfo object",
        "\tCell location",
        "\t\tint32 x",
    ):
        assert line in shown.stdout, shown.stdout
    kinds = ros2(domain, "interface", "package", "ost_msgs").stdout.split()
    assert {"ost_msgs/msg/ObjectFound", "ost_msgs/msg/Selection", "ost_msgs/msg/Tick"} <= set(kinds)
    exes = ros2(domain, "pkg", "executables", "ost_ros")
    assert exes.returncode == 0, exes.stderr
    assert exes.stdout.split("\n")[:4] == [
        "ost_ros agent_node",
        "ost_ros membership_node",
        "ost_ros watch_node",
        "ost_ros world_node",
    ]


def test_topics_echo_params_and_ros2_run_on_a_live_run(tmp_path, procs, domain):
    scenario = generate_scenario(2, 4, 3, Grid(20, 8), 2)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, "ccp", CoordinationPolicy())
    result = tmp_path / "result.json"
    keys = make_keys(tmp_path, path)
    world_args = [
        "-p",
        f"scenario:={path}",
        "-p",
        f"result_file:={result}",
        "-p",
        "exit_when_done:=false",
        *keys,
    ]
    procs.start("world", "world_node", *world_args)
    # (its parameter services on: a robot answers ros2 param only when asked to, --param-services)
    agent_0 = ["-p", f"scenario:={path}", "-p", "agent_id:=0", "-p", "param_services:=true", *keys]
    procs.start("agent_0", "agent_node", *agent_0)
    procs.wait_for("world", "waiting for 2 agents")  # agent_1 missing: the graph holds still

    want = expected_topics("ccp", 2)
    del want["/ost/agent_1/alive"]  # agent_1 is not up yet (the world reads it, but no writer)

    def graph():
        listed = ros2(domain, "topic", "list", "-t", "--no-daemon", "--spin-time", "3")
        got = dict(line.split(" ", 1) for line in listed.stdout.splitlines() if " " in line)
        return got if all(got.get(t) == f"[{k}]" for t, k in want.items()) else None

    got = until(graph, "complete graph")
    assert got["/ost/object_found"] == "[ost_msgs/msg/ObjectFound]"
    assert got["/ost/selection"] == "[ost_msgs/msg/Selection]"
    assert "/ost/help_request" not in got  # a protocol's topics exist only in its runs

    described = ros2(domain, "param", "describe", "/ost/agent_0", "ci", "--no-daemon", "--timeout", "30")
    assert described.returncode == 0, described.stderr
    assert "Type: integer" in described.stdout and "Read only: true" in described.stdout
    assert "Min value: 1" in described.stdout and "coordinate after every ci-th" in described.stdout
    refused = ros2(domain, "param", "set", "/ost/agent_0", "ci", "5", "--no-daemon", "--timeout", "30")
    assert "read-only" in (refused.stdout + refused.stderr), refused.stdout + refused.stderr
    assert (
        ros2(domain, "param", "get", "/ost/agent_0", "ci", "--no-daemon", "--timeout", "30")
        .stdout.strip()
        .endswith("1")
    )

    # echo the first ObjectFound of the run: its reader is matched (counted) before the run starts
    echo = procs.run(
        "echo",
        [str(ROS2), "topic", "echo", "--once", "/ost/object_found", "ost_msgs/msg/ObjectFound"],
        env=cli_env(domain),
    )
    wait_subscribers(domain, "/ost/object_found", 2)  # agent_0's reader and the echo's
    # the missing robot, started by ros2 run
    procs.run(
        "agent_1",
        [
            str(ROS2),
            "run",
            "ost_ros",
            "agent_node",
            "--ros-args",
            "-p",
            f"scenario:={path}",
            "-p",
            "agent_id:=1",
            *keys,
        ],
        env=cli_env(domain),
    )
    until(lambda: True if result.exists() else None, "result", 120)
    time.sleep(0.2)  # the file is written whole before the topic; let the writer close it
    assert json.loads(result.read_text()) == expected
    echo.wait(30)
    text = procs.log("echo")
    for field in ("run:", "step:", "seq:", "sender:", "object:", "location:", "x:", "required:"):
        assert field in text, text

    # the world stays up with the result (exit_when_done false): a late reader still gets it. It
    # asks for transient local itself: ros2 topic echo infers durability from the publishers its
    # fresh node has discovered when it starts, often none yet, and then reads volatile (no result)
    late = ros2(
        domain,
        "topic",
        "echo",
        "--once",
        "--no-daemon",
        "--full-length",
        "--qos-durability",
        "transient_local",
        "--qos-reliability",
        "reliable",
        "/ost/result",
        "std_msgs/msg/String",
    )
    # the String's data is printed as a quoted YAML scalar: undo its escaped quotes
    assert f'"makespan": {expected["makespan"]}' in late.stdout.replace('\\"', '"'), late.stdout[:500]


def test_ros2_launch_runs_the_team(tmp_path, domain):
    result = tmp_path / "result.json"
    launch = subprocess.Popen(
        [
            str(ROS2),
            "launch",
            "ost_ros",
            "team.launch.py",
            "agents:=4",
            "objects:=6",
            "seed:=1",
            "width:=30",
            "height:=12",
            "nmax:=3",
            "ci:=2",
            "protocol:=hcp",
            f"result_file:={result}",
            f"record:={tmp_path / 'run.mcap'}",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=cli_env(domain),
        start_new_session=True,
    )
    try:
        out, _ = launch.communicate(timeout=180)
    finally:
        if launch.poll() is None:
            os.killpg(launch.pid, signal.SIGINT)
            launch.wait(30)
    assert launch.returncode == 0, out[-3000:]
    scenario = generate_scenario(4, 6, 1, Grid(30, 12), 3)
    assert json.loads(Path(result).read_text()) == reference(scenario, "hcp", CoordinationPolicy(ci=2))
    assert "Traceback" not in out
    # launched with record:=, the watch node's recording rebuilds the same result
    replay = subprocess.run(
        [sys.executable, "-m", "ost_ros", "replay", str(tmp_path / "run.mcap"), "--json"],
        capture_output=True,
        text=True,
    )
    assert replay.returncode == 0, replay.stderr
    assert json.loads(replay.stdout) == json.loads(Path(result).read_text())


def test_ros2_launch_takes_the_options_of_ost_up(domain):
    from ost_ros.runconfig import options

    shown = subprocess.run(
        [str(ROS2), "launch", "ost_ros", "team.launch.py", "--show-args"],
        capture_output=True,
        text=True,
        env=cli_env(domain),
        timeout=60,
    )
    assert shown.returncode == 0, shown.stderr
    declared = re.findall(r"^    '(\w+)':", shown.stdout, flags=re.M)
    assert declared == [s.name for s in options()]  # derived from the one run configuration
    refused = subprocess.run(
        [str(ROS2), "launch", "ost_ros", "team.launch.py", "agents:=2", "objects:=2", "hosts:=3"],
        capture_output=True,
        text=True,
        env=cli_env(domain),
        timeout=60,
    )
    assert refused.returncode != 0
    assert (
        "hosts:= not in the launch file: simulated hosts are made by ost up"
        in refused.stdout + refused.stderr
    )


def test_ros2_action_against_a_realtime_base(tmp_path, procs, domain):
    """A realtime world serves each robot's base as an action: the real ``ros2 action`` lists it,
    describes it and sends it a goal (before the run starts the base refuses, saying why)."""
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(generate_scenario(2, 4, 3, Grid(20, 8), 2)))
    keys = make_keys(tmp_path, path)
    procs.start("world", "world_node", "-p", f"scenario:={path}", "-p", "realtime:=true", *keys)
    procs.wait_for("world", "waiting for 2 agents")
    name = "/ost/agent_1/follow_cells"

    def listed():
        out = ros2(domain, "action", "list", "-t").stdout
        return out if name in out else None

    out = until(listed, f"{name} in ros2 action list")
    assert f"{name} [ost_msgs/action/FollowCells]" in out and "/ost/agent_0/follow_cells" in out
    info = ros2(domain, "action", "info", name, "-t")
    assert info.returncode == 0 and "Action servers: 1" in info.stdout, info.stdout + info.stderr
    # (ros2action 0.32.2 prints the server's namespace mangled, "//o/s/tbases": its own join;
    # the bases are served by the world process's node "bases")
    assert "bases [ost_msgs/action/FollowCells]" in info.stdout
    sent = ros2(domain, "action", "send_goal", name, "ost_msgs/action/FollowCells",
                "{kind: 1, id: 7, state: WAITING}", timeout=90)  # fmt: skip
    assert sent.returncode == 0, sent.stderr
    assert "outcome: refused" in sent.stdout and "the run has not started" in sent.stdout, sent.stdout
    assert "ABORTED" in sent.stdout
