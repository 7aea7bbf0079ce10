"""Isolation over DDS: two runs at once (each on its own domain) do not interfere, and a stray
publisher on a run's own domain sending well-formed but false messages — another run's step
selections and actions claiming to be agent 1, with a selection that contradicts the algorithm —
is detected (warned, naming the topic and the claimed sender) and ignored: the run still equals
``ost sim``."""

import subprocess
import sys
import threading

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import ost_up, reference, result_json, ros_env

STRAY = r"""
import sys, time, rclpy
from ost_msgs_py import wire
from ost_ros.lockstep.messages import Acted, Sample
from ost_ros.messages import Action, ActionKind
from ost_ros.node import transport as tp
from ost_ros.protocols.ccp.messages import Selection
rclpy.init()
node = rclpy.create_node("stray", namespace=tp.NAMESPACE)
batch = node.create_publisher(wire.ros_type(Selection), tp.message_topic(Selection), tp.LOCKSTEP_QOS)
acted = node.create_publisher(wire.ros_type(Acted), tp.ACTED, tp.LOCKSTEP_QOS)
end = time.monotonic() + 30
# volatile QoS: a sample sent before its reader is matched is never delivered, so wait for
# every agent's selection reader and the world's action reader
while ((batch.get_subscription_count() < 4 or acted.get_subscription_count() < 1)
       and time.monotonic() < end):
    rclpy.spin_once(node, timeout_sec=0.05)
sent = 0
end = time.monotonic() + 6.0   # keep at it while the run goes on (it may start after us)
while time.monotonic() < end and batch.get_subscription_count() >= 4:
    for t in range(0, 50):   # false selections for steps, claiming agent 1, from "another run"
        batch.publish(wire.to_ros(Sample(Selection(1, t, 1, (99,)), t, 0, run="stray")))
        acted.publish(wire.to_ros(Acted(Action(1, t, ActionKind.WAIT), 0, (), run="stray")))
        sent += 1
    rclpy.spin_once(node, timeout_sec=0.2)
node.destroy_node(); rclpy.shutdown()
print("sent" if sent else "nothing sent")
"""


def scenario_file(tmp_path, name, seed, grid=Grid(30, 12)):
    s = generate_scenario(4, 8, seed, grid, 4)
    path = tmp_path / f"{name}.yaml"
    path.write_text(dump_scenario(s))
    return path, reference(s, "ccp", CoordinationPolicy())


def test_two_runs_at_once_do_not_interfere(tmp_path):
    runs = {name: scenario_file(tmp_path, name, seed) for name, seed in (("a", 1), ("b", 2))}
    out = {}

    def go(name):
        out[name] = ost_up(
            "--scenario",
            str(runs[name][0]),
            "--json",
            "--no-skip",
            "--run-dir",
            str(tmp_path / f"run_{name}"),
        )

    threads = [threading.Thread(target=go, args=(n,)) for n in runs]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    domains = set()
    for name, (_, expected) in runs.items():
        assert out[name].returncode == 0, out[name].stderr
        assert result_json(out[name].stdout) == expected
        domains.add(out[name].stderr.split("ROS_DOMAIN_ID=")[1].split(",")[0])
    assert len(domains) == 2


def test_stray_publisher_is_detected_and_ignored(tmp_path, domain):
    path, expected = scenario_file(tmp_path, "s", 3, Grid(100, 40))  # a run of several seconds
    result = {}
    th = threading.Thread(
        target=lambda: result.update(
            run=ost_up(
                "--scenario",
                str(path),
                "--json",
                "--no-skip",
                "--insecure",  # the run-id check itself (signed runs: tests/ros/test_secure.py)
                "--domain-id",
                str(domain),
                "--run-dir",
                str(tmp_path / "run"),
            )
        )
    )
    th.start()
    stray = subprocess.run(
        [sys.executable, "-c", STRAY], env=ros_env(domain), capture_output=True, text=True, timeout=90
    )
    th.join()
    assert stray.returncode == 0 and "sent" in stray.stdout, stray.stderr
    run = result["run"]
    assert run.returncode == 0, run.stderr
    assert result_json(run.stdout) == expected
    logs = {p.name: p.read_text() for p in (tmp_path / "run").glob("*.log")}
    assert "dropped message on /ost/acted from agent 1: action of run 'stray'" in logs["world.log"]
    assert any(
        "dropped message on /ost/selection from agent 1: selection of run 'stray'" in text
        for name, text in logs.items()
        if name.startswith("agent_")
    )
    assert not any("Traceback" in text for text in logs.values())


def test_two_teams_in_two_namespaces_share_a_domain(tmp_path, domain):
    runs = {"ost": scenario_file(tmp_path, "a", 1), "team_a": scenario_file(tmp_path, "b", 2)}
    out = {}

    def go(ns):
        out[ns] = ost_up(
            "--scenario",
            str(runs[ns][0]),
            "--json",
            "--no-skip",
            "--namespace",
            ns,
            "--domain-id",
            str(domain),
            "--run-dir",
            str(tmp_path / f"run_{ns}"),
        )

    threads = [threading.Thread(target=go, args=(ns,)) for ns in runs]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for ns, (_, expected) in runs.items():
        assert out[ns].returncode == 0, out[ns].stderr
        assert f"namespace /{ns}," in out[ns].stderr
        assert result_json(out[ns].stdout) == expected
        logs = [p.read_text() for p in (tmp_path / f"run_{ns}").glob("*.log")]
        assert not any("dropped message" in text for text in logs)  # nothing crossed over
