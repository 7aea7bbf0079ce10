"""Node parameters with descriptors — what ``ros2 param describe`` shows and ``ros2 param set``
obeys — and the node layer's errors.

Every parameter of the world and agent nodes defines the run and is read once at start, so all
are read-only: ``ros2 param set /ost/agent_0 ci 5`` is refused with rclpy's reason ("Trying to
set a read-only parameter") instead of answering "successful" and being ignored. (A robot answers
``ros2 param`` only with ``param_services:=true``: :func:`robot_node_options`.) Numeric ones
carry their range, which rclpy checks when the node starts (a value out of range stops the node
with one line naming the parameter).
"""

from __future__ import annotations

from typing import Any

import yaml
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from ost_ros.errors import OstError
from ost_ros.yamlload import safe_load

INT_MAX = 2**31 - 1


class NodeError(OstError):
    """The node layer's error base: a node that cannot start as configured (one line)."""


class ParameterError(NodeError):
    """A bad node parameter; the text names it (the node exits with one line and code 2)."""


def declare(
    node: Node,
    name: str,
    default: Any,
    description: str,
    lo: float | None = None,
    hi: float | None = None,
    constraints: str = "",
) -> None:
    """Declare a read-only parameter with its description, range and constraints."""
    d = ParameterDescriptor(description=description, read_only=True, additional_constraints=constraints)
    if lo is not None or hi is not None:
        if isinstance(default, bool):
            raise TypeError(f"{name}: a bool has no range")
        if isinstance(default, int):
            d.integer_range = [IntegerRange(from_value=int(lo or 0), to_value=int(hi or INT_MAX), step=0)]
        else:
            d.floating_point_range = [
                FloatingPointRange(from_value=float(lo or 0.0), to_value=float(hi or 1e9), step=0.0)
            ]
    node.declare_parameter(name, default, d)


def declare_role(node: Node, role: str) -> dict[str, Any]:
    """Declare every setting a node of ``role`` reads (:func:`ost_ros.runconfig.of_node`), read-only
    with its description, range and choices; their values, checked as every bring-up checks them
    (:class:`~ost_ros.runconfig.RunConfig`: a bad one is a :class:`ParameterError` naming it)."""
    from ost_ros import runconfig

    settings = runconfig.of_node(role)
    for s in settings:
        choices = "one of " + ", ".join(s.choices) if s.choices else ""
        declare(node, s.name, s.default, s.help, s.lo, s.hi, constraints=choices)
    values = {s.name: node.get_parameter(s.name).value for s in settings}
    try:
        runconfig.RunConfig.of(values)
    except runconfig.ConfigError as exc:
        raise ParameterError(f"{exc.setting}: {exc}") from None
    return values


def node_scenario(p: dict[str, Any]) -> Any:
    """The run's scenario from a node's ``scenario`` (and ``agents``: the team) parameters; a
    missing or bad file is a :class:`ParameterError`."""
    from ost_ros.scenario import ScenarioError, load_scenario, with_team

    if not p["scenario"]:
        raise ParameterError("scenario: must name a scenario file (-p scenario:=FILE)")
    try:
        scenario = load_scenario(p["scenario"])
        return with_team(scenario, p["agents"]) if p["agents"] else scenario
    except ScenarioError as exc:
        raise ParameterError(f"scenario: {exc}") from None


def declare_agent(node: Node) -> tuple[dict[str, Any], Any, Any, Any]:
    """An agent node's settings (lockstep or realtime), declared and checked: (the values, their
    :class:`~ost_ros.runconfig.RunConfig`, the scenario with the run's team, the protocol's
    :class:`~ost_ros.protocols.ProtocolSpec`). A missing or bad one is a :class:`ParameterError`."""
    from ost_ros.runconfig import AGENT, ConfigError, RunConfig

    p = declare_role(node, AGENT)
    if p["agent_id"] < 0:
        raise ParameterError("agent_id: must be set to a non-negative id (-p agent_id:=N)")
    scenario = node_scenario(p)
    cfg = RunConfig.of(p)
    try:
        spec = cfg.check_protocol(scenario)
    except ConfigError as exc:
        raise ParameterError(f"protocol: {exc}") from None
    ids = [a.id for a in scenario.agents]
    if p["agent_id"] not in ids:
        raise ParameterError(f"agent_id: {p['agent_id']} is not in the scenario's team {ids}")
    return p, cfg, scenario, spec


def param_from_args(argv: list[str], name: str) -> Any:
    """Parameter ``name`` as a node's ROS arguments set it — ``-p``/``--param name:=V`` or a
    ``--params-file`` (the last assignment wins, as in rcl) — as text or the file's value; None
    when unset. For what a node must know before it exists (its name, its mode); the node still
    declares and checks the parameter itself."""
    value = None
    ros, k = False, 0
    while k < len(argv):
        a = argv[k]
        if a == "--ros-args":
            ros = True
        elif a == "--":
            ros = False
        elif ros and a in ("-p", "--param") and k + 1 < len(argv):
            key, _, v = argv[k + 1].partition(":=")
            if key == name:
                value = v
            k += 1
        elif ros and a == "--params-file" and k + 1 < len(argv):
            try:
                with open(argv[k + 1]) as f:
                    doc = safe_load(f)
                for section in (doc or {}).values():
                    params = (section or {}).get("ros__parameters", {}) if isinstance(section, dict) else {}
                    if isinstance(params, dict) and name in params:
                        value = params[name]
            except (OSError, yaml.YAMLError, AttributeError):
                pass  # the node reports a bad params file itself
            k += 1
        k += 1
    return value


def flag_from_args(argv: list[str], name: str) -> bool:
    """Whether the ROS arguments set the bool parameter ``name`` true."""
    value = param_from_args(argv, name)
    return value is True or (isinstance(value, str) and value.strip().lower() in ("true", "1", "yes"))


def realtime_from_args(argv: list[str]) -> bool:
    """Whether the ROS arguments ask for a realtime node (``realtime:=true``)."""
    return flag_from_args(argv, "realtime")


def robot_node_options(argv: list[str]) -> dict[str, Any]:
    """What a robot's node is built with (``rclpy.node.Node`` keywords): without rclpy's parameter
    and type-description services unless ``param_services:=true``. They are 14 DDS endpoints a
    robot that every participant of the run discovers and keeps in its graph, and nobody of the
    team calls them: at N=50 they are a third of the run's endpoints and of its bring-up
    (docs/ros.md, "Bring-up"). The robot still declares its parameters (read-only)."""
    return {} if flag_from_args(argv, "param_services") else without_services()


def without_services() -> dict[str, Any]:
    """``rclpy.node.Node`` keywords for a node without parameter and type-description services."""
    return {
        "start_parameter_services": False,
        "parameter_overrides": [Parameter("start_type_description_service", value=False)],
    }
