"""The node/topic graph over DDS is as documented (one typed topic per message kind), and
malformed messages injected on the typed topics are survived: a warning naming the topic, the
sender and the field, no crash, and the run still matches ``ost sim``."""

import json
import subprocess
import sys
import time

from ost_msgs_py import wire
from ost_ros import protocols
from ost_ros.coordination import CoordinationPolicy
from ost_ros.lockstep.messages import Tick
from ost_ros.model import Grid
from ost_ros.node import transport as tp
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import BIN, INSECURE, reference, ros_env


def expected_topics(protocol: str, agents: int, ns: str = "/ost") -> dict[str, str]:
    """Every topic of a run and its type, as ``ros2 topic list -t`` resolves them."""
    topics = {f"{ns}/{name}": kind for name, (_, kind) in tp.TOPICS.items()}
    # one per message kind the protocol broadcasts (the lockstep agent's runtime.kinds)
    topics.update(
        {f"{ns}/{tp.message_topic(m)}": wire.type_name(m) for m in protocols.get(protocol).messages}
    )
    for i in range(agents):
        topics[f"{ns}/{tp.tick_topic(i)}"] = wire.type_name(Tick)
        topics[f"{ns}/{tp.alive_topic(i)}"] = "std_msgs/msg/String"
    return topics


TOPICS = expected_topics("ccp", 2)

# Malformed on purpose, each typed right but wrong in a value: the warning names the field.
INJECT = r"""
import time, rclpy
import ost_msgs.msg as ros
from ost_ros.node import transport as tp
rclpy.init()
node = rclpy.create_node("injector", namespace=tp.NAMESPACE)
acted = ros.Acted(); acted.action.agent = 1; acted.action.kind = "jump"
report = ros.AgentReport(agent=1, predicted_makespan=-5)
tick = ros.Tick(t=0, last=-1, peers=[1], counts=[]); tick.observation.agent = 0
sel = ros.Selection(run="other", step=0, seq=0, sender=5, t=0, coordination=1, objects=[99])
msgs = [("acted", acted), ("reports", report), ("agent_0/tick", tick), ("selection", sel)]
pubs = [(node.create_publisher(type(m), t, tp.TOPICS.get(t, (tp.LOCKSTEP_QOS,))[0]), m) for t, m in msgs]
end = time.monotonic() + 10
while any(p.get_subscription_count() == 0 for p, _ in pubs) and time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.05)
for p, m in pubs:
    p.publish(m)
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
        *INSECURE,  # the decoders' warnings (tests/ros/test_secure.py: the signatures)
    )
    procs.start("agent_0", "agent_node", "-p", f"scenario:={path}", "-p", "agent_id:=0", *INSECURE)
    # agent_1 is missing: the world waits for it, so the graph holds still.
    procs.wait_for("world", "waiting for 2 agents")
    # ros2 topic list -t's form, through the stand-in (tests/ros/test_ros2cli.py: the real CLI)
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

    inj = subprocess.run(
        [sys.executable, "-c", INJECT], env=ros_env(domain), capture_output=True, text=True, timeout=60
    )
    assert inj.returncode == 0, inj.stderr
    # Each receiver warns once per topic and sender, naming both and the field, and keeps running.
    procs.wait_for(
        "world",
        "dropped message on /ost/acted from agent 1: malformed: acted.action.kind: 'jump' is not one of wait, "
        "move, carry",
    )
    procs.wait_for(
        "world",
        "dropped message on /ost/reports from agent 1: malformed: agent_report.predicted_makespan: -5 "
        "(expected -1 for none, or a value >= 0)",
    )
    procs.wait_for(
        "agent_0", "dropped message on /ost/agent_0/tick from the world: tick lists 1 peers and 0 counts"
    )

    procs.start("agent_1", "agent_node", "-p", f"scenario:={path}", "-p", "agent_id:=1", *INSECURE)
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
    # the stray selection (another run, an agent not in the team) was dropped once the run began
    assert "dropped message on /ost/selection from agent 5: selection of run 'other'" in procs.log("agent_0")
    assert "Traceback" not in procs.log("world") + procs.log("agent_0") + procs.log("agent_1")


def test_bad_parameters_are_one_line(tmp_path, domain):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(dump_scenario(generate_scenario(2, 2, 1, Grid(20, 10), nmax=2)))
    for exe, args, text in [
        ("agent_node", ["-p", "agent_id:=0"], "scenario: must name a scenario file"),
        (
            "agent_node",
            [
                "-p",
                "agent_id:=0",
                "-p",
                f"scenario:={scenario}",
                "-p",
                "insecure:=true",
                "-p",
                "executor:=threads",
            ],
            "executor: 'threads' is not one of events, single",
        ),
        (
            "world_node",
            ["-p", f"scenario:={scenario}", "-p", "insecure:=true", "-p", "executor:=threads"],
            "executor: 'threads'",
        ),
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
