"""The node/topic graph over DDS is as documented, and malformed messages injected on every
String topic are survived: a warning naming the sender, no crash, and the run still matches
``ost sim``."""

import json
import subprocess
import sys
import time

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import BIN, reference, ros_env

TOPICS = {
    "/clock": "rosgraph_msgs/msg/Clock",
    "/ost/markers": "visualization_msgs/msg/MarkerArray",
    "/ost/acted": "std_msgs/msg/String",
    "/ost/step_messages": "std_msgs/msg/String",
    "/ost/ready": "std_msgs/msg/String",
    "/ost/run_end": "std_msgs/msg/String",
    "/ost/reports": "std_msgs/msg/String",
    "/ost/result": "std_msgs/msg/String",
    "/ost/agent_0/tick": "std_msgs/msg/String",
    "/ost/agent_1/tick": "std_msgs/msg/String",
    "/ost/agent_0/alive": "std_msgs/msg/String",
    "/ost/agent_1/alive": "std_msgs/msg/String",
}
# Malformed on purpose: not JSON; wrong field type (with a sender to name); wrong version.
BAD = [
    "{not json",
    '{"type": "acted", "sender": 1, "t": "x", "version": 1}',
    '{"type": "step_messages", "sender": 5, "t": 0, "messages": [], "version": 99}',
]

INJECT = r"""
import sys, time, rclpy
from std_msgs.msg import String
from agent_node import transport as tp
topics, bad = sys.argv[1].split(","), sys.argv[2:]
rclpy.init()
node = rclpy.create_node("injector")
pubs = [node.create_publisher(String, t, tp.TOPICS.get(t, (tp.LOCKSTEP_QOS,))[0]) for t in topics]
end = time.monotonic() + 10
while any(p.get_subscription_count() == 0 for p in pubs) and time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.05)
for p in pubs:
    for text in bad:
        p.publish(String(data=text))
end = time.monotonic() + 1.0   # let reliable delivery finish before leaving
while time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.05)
node.destroy_node(); rclpy.shutdown()
"""


def ost(domain, *args, timeout=30):
    return subprocess.run(
        [str(BIN / "ost"), *args], capture_output=True, text=True, env=ros_env(domain), timeout=timeout
    )


def test_graph_and_malformed_messages(tmp_path, procs, domain):
    scenario = generate_scenario(2, 4, 3, Grid(20, 8), 2)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, "ccp", CoordinationPolicy())
    result = tmp_path / "result.json"
    procs.start(
        "world",
        "world_node",
        "-p",
        f"scenario:={path}",
        "-p",
        f"result_file:={result}",
        "-p",
        "exit_when_done:=false",
    )
    procs.start("agent_0", "agent_node", "-p", f"scenario:={path}", "-p", "agent_id:=0")
    # agent_1 is missing: the world waits for it, so the graph holds still.
    procs.wait_for("world", "waiting for 2 agents")
    end = time.monotonic() + 30
    while True:  # discovery takes 0-3 s: poll the graph until complete (or give up)
        nodes = ost(domain, "ros", "node", "list", "--spin-time", "3")
        listed = ost(domain, "ros", "topic", "list", "-t", "--spin-time", "3")
        assert nodes.returncode == 0 and listed.returncode == 0, nodes.stderr + listed.stderr
        graph = dict(line.split(" ", 1) for line in listed.stdout.splitlines())
        complete = all(graph.get(name) == f"[{kind}]" for name, kind in TOPICS.items())
        if (complete and nodes.stdout.split() == ["/ost/agent_0", "/ost/world"]) or time.monotonic() > end:
            break
    assert nodes.stdout.split() == ["/ost/agent_0", "/ost/world"]
    for name, kind in TOPICS.items():
        assert graph.get(name) == f"[{kind}]", (name, listed.stdout)

    strings = [
        t
        for t, k in TOPICS.items()  # agent_1's tick has no reader yet; alive: no data
        if k == "std_msgs/msg/String" and t != "/ost/agent_1/tick" and not t.endswith("/alive")
    ]
    inj = subprocess.run(
        [sys.executable, "-c", INJECT, ",".join(strings), *BAD],
        env=ros_env(domain),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert inj.returncode == 0, inj.stderr
    # Each receiver warns once per topic and sender, naming both, and keeps running.
    for name, topic in [
        ("world", "/ost/acted"),
        ("world", "/ost/ready"),
        ("world", "/ost/reports"),
        ("agent_0", "/ost/step_messages"),
        ("agent_0", "/ost/run_end"),
        ("agent_0", "/ost/agent_0/tick"),
    ]:
        procs.wait_for(name, f"dropped message on {topic} from unknown")
    procs.wait_for("world", "dropped message on /ost/acted from agent 1: acted.sender: unknown field")
    procs.wait_for("agent_0", "from agent 5: step_messages.version: unsupported version 99")

    procs.start("agent_1", "agent_node", "-p", f"scenario:={path}", "-p", "agent_id:=1")
    end = time.monotonic() + 60
    while not result.exists():
        assert time.monotonic() < end, procs.log("world")[-2000:]
        assert procs.procs["world"].poll() is None, procs.log("world")[-2000:]
        time.sleep(0.1)
    time.sleep(0.2)
    assert json.loads(result.read_text()) == expected
    echoed = ost(domain, "ros", "topic", "echo", "/ost/result", "--once")
    assert f'"makespan": {expected["makespan"]}' in echoed.stdout
    for name in ("agent_0", "agent_1"):
        procs.procs[name].wait(20)
        assert procs.procs[name].returncode == 0, procs.log(name)
    assert "Traceback" not in procs.log("world") + procs.log("agent_0") + procs.log("agent_1")


def test_bad_parameters_are_one_line(tmp_path, domain):
    for exe, args, text in [
        ("agent_node", ["-p", "agent_id:=0"], "scenario: must name a scenario file"),
        ("agent_node", ["-p", "agent_id:=0", "-p", f"scenario:={tmp_path}/none.yaml"], "scenario:"),
        ("world_node", [], "scenario: must name a scenario file"),
        ("world_node", ["-p", "scenario:=x", "-p", "agents:=abc"], "error"),
    ]:
        run = subprocess.run(
            [str(BIN / exe), "--ros-args", *args],
            capture_output=True,
            text=True,
            env=ros_env(domain),
            timeout=30,
        )
        assert run.returncode == 2, (exe, args, run.stderr)
        assert text in run.stderr and "Traceback" not in run.stderr
