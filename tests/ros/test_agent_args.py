"""The agent node's name comes from ``agent_id`` in its ROS arguments (``-p`` or a params file)."""

from agent_node.agent_node import agent_id_from_args
from ost_ros.node.params import robot_node_options


def test_agent_id_from_p_and_params_file(tmp_path):
    params = tmp_path / "p.yaml"
    params.write_text("/**:\n  ros__parameters:\n    agent_id: 7\n    ci: 1\n")
    assert agent_id_from_args(["agent_node", "--ros-args", "-p", "agent_id:=3"]) == 3
    assert agent_id_from_args(["x", "--ros-args", "--params-file", str(params)]) == 7
    # the last assignment wins, as in rcl
    assert agent_id_from_args(["x", "--ros-args", "--params-file", str(params), "-p", "agent_id:=2"]) == 2
    assert agent_id_from_args(["x", "--ros-args", "-p", "agent_id:=2", "--params-file", str(params)]) == 7


def test_agent_id_absent_or_bad_gives_none(tmp_path):
    assert agent_id_from_args(["agent_node"]) is None
    assert agent_id_from_args(["x", "-p", "agent_id:=3"]) is None  # not a ROS argument
    assert agent_id_from_args(["x", "--ros-args", "-p", "agent_id:=abc"]) is None
    assert agent_id_from_args(["x", "--ros-args", "-p", "agent_id:=-1"]) is None
    assert agent_id_from_args(["x", "--ros-args", "--params-file", str(tmp_path / "none.yaml")]) is None
    bad = tmp_path / "bad.yaml"
    bad.write_text(": : :\n")
    assert agent_id_from_args(["x", "--ros-args", "--params-file", str(bad)]) is None


def test_a_robot_node_without_parameter_services_unless_asked():
    """14 DDS endpoints a robot nobody of the team calls: off unless ``param_services:=true``."""
    off = robot_node_options(["agent_node", "--ros-args", "-p", "agent_id:=3"])
    assert off["start_parameter_services"] is False
    assert [(p.name, p.value) for p in off["parameter_overrides"]] == [
        ("start_type_description_service", False)
    ]
    assert robot_node_options(["agent_node", "--ros-args", "-p", "param_services:=true"]) == {}
