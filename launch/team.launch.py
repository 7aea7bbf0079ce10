"""A whole run under ``ros2 launch``: the world node and one agent node per robot.

    ros2 launch ost_ros team.launch.py agents:=4 objects:=8 seed:=1 nmax:=4 [protocol:=hcp] [ci:=2]
    ros2 launch ost_ros team.launch.py scenario:=/path/s.yaml [namespace:=team_a]
        [result_file:=/tmp/result.json] [record:=/tmp/run.mcap] [foxglove:=8765] [insecure:=true]

Its arguments are ``ost up``'s options (``ros2 launch ost_ros team.launch.py --show-args``),
derived from the one run configuration (:mod:`ost_ros.runconfig`), and it prepares the run as
``ost up`` does (:func:`ost_ros.commands.bringup.prepare`: the scenario — generated from
agents/objects/seed as ``ost generate`` does, or the given file —, the run's keys, each node's
parameter file, in ``run_dir`` or a fresh ``/tmp/ost_run.*``). The processes are started by
launch, in the caller's environment (its ROS_DOMAIN_ID); what only a supervisor or a shell can
do (``background``, ``timeout``, ``json``, ``respawn_world``, simulated ``hosts``) is refused in
one line. Launch ends when the world node exits (after the result, once the agents have left);
the result is on ``<namespace>/result`` and in ``result_file`` (default: the run directory's
``result.json``) — the JSON of ``ost sim --json``.
"""

from __future__ import annotations

from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _text(value) -> str:
    """A setting's default as a launch argument's text."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return ",".join(value)
    return str(value)


def _nodes(context: LaunchContext) -> list:
    from ost_ros.commands.bringup import prepare
    from ost_ros.errors import UsageError
    from ost_ros.runconfig import ConfigError, RunConfig, options

    given = {}
    for s in options():
        text = LaunchConfiguration(s.name).perform(context)
        if text != _text(s.default):
            given[s.name] = text
    try:
        cfg = RunConfig.of(given)
        run = prepare(cfg, lambda text: print(f"[team.launch.py] {text}"), launch=True)
    except ConfigError as exc:
        raise RuntimeError(f"team.launch.py: {exc.setting}:= {exc}") from None
    except UsageError as exc:  # the rest of the bring-up's errors
        raise RuntimeError(f"team.launch.py: {exc}") from None
    ns = "/" + cfg["namespace"].strip("/")
    nodes = {
        p.name: Node(
            package="ost_ros",
            executable=p.executable,
            name=p.name,
            namespace=ns,
            output="screen",
            parameters=[str(run.params_file(p.role)), p.params],
            remappings=[tuple(r) for r in p.remaps],
            # (a realtime run's own Fast DDS profile, if the caller loads ours: docs/ros.md)
            additional_env=dict(run.env),
        )
        for p in run.processes
    }
    # The run is over when the world leaves (it waits for the agents to read the result).
    done = RegisterEventHandler(
        OnProcessExit(target_action=nodes["world"], on_exit=[EmitEvent(event=Shutdown())])
    )
    return [*nodes.values(), done]


def generate_launch_description() -> LaunchDescription:
    from ost_ros.runconfig import options

    return LaunchDescription(
        [DeclareLaunchArgument(s.name, default_value=_text(s.default), description=s.help) for s in options()]
        + [OpaqueFunction(function=_nodes)]
    )
