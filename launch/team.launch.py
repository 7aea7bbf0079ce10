"""A whole run under ``ros2 launch``: the world node and one agent node per robot.

    ros2 launch ost_ros team.launch.py agents:=4 objects:=8 seed:=1 [protocol:=hcp] [ci:=2]
    ros2 launch ost_ros team.launch.py scenario:=/path/s.yaml [namespace:=team_a]
        [result_file:=/tmp/result.json] [record:=/tmp/run.mcap] [foxglove:=8765] [insecure:=true]

The same processes and parameters as ``bringup_scripts/ost_up.sh`` (which stays the main
bring-up: it also picks a free domain, cleans up and prints the result): with ``scenario`` empty
the paper's random scenario is generated from agents/objects/seed (and width/height/nmax) into a
temporary file, exactly as ``ost generate`` does. Launch ends when the world node exits (after
the result, once the agents have left); the result is on ``<namespace>/result`` and, with
``result_file``, in that file — the JSON of ``ost sim --json``. ``record`` and ``foxglove`` start
the watch node with the run (a recording for ``ost replay``, a live Foxglove view), counted as an
observer that every node waits for before step 0. Every message is signed with keys made for
the run (in a temporary directory, or ``keys:=DIR`` from ``ost keys make``) unless
``insecure:=true``.
"""

from __future__ import annotations

import tempfile

from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

ARGUMENTS = {
    "scenario": ("", "scenario YAML (ost generate); empty: generate from agents/objects/seed"),
    "agents": ("0", "team size (generating: required; with a scenario: replaces its team, 0 = keep)"),
    "objects": ("0", "objects to generate"),
    "seed": ("1", "seed of the generated scenario"),
    "width": ("500", "grid width of the generated scenario"),
    "height": ("200", "grid height of the generated scenario"),
    "nmax": ("10", "largest group of the generated scenario"),
    "protocol": ("ccp", "cooperation protocol (ost protocols list)"),
    "ci": ("1", "coordination trigger: coordinate after every ci-th found object"),
    "interval": ("0", "coordination trigger: every interval steps (0: off)"),
    "coordination": ("distributed", "distributed or coordinator"),
    "namespace": ("ost", "the run's namespace"),
    "result_file": ("", "write the result JSON there ('': none)"),
    "event_skipping": ("true", "execute the agents' plans for quiet steps"),
    "max_steps": ("0", "step limit (0: the simulator's)"),
    "record": ("", "record every topic of the run to this MCAP file ('': none)"),
    "foxglove": ("0", "serve a live Foxglove view on this port (0: none)"),
    "keys": ("", "the run's key directory (ost keys make); empty: fresh keys in a temporary one"),
    "insecure": ("false", "no signed messages (for comparison)"),
}


def _nodes(context: LaunchContext) -> list:
    from ost_msgs_py.auth import make_keys
    from ost_ros.model import Grid
    from ost_ros.scenario import dump_scenario, generate_scenario, load_scenario, with_team

    arg = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    agents = int(arg["agents"])
    if arg["scenario"]:
        path = arg["scenario"]
        scenario = load_scenario(path)
        if agents:
            scenario = with_team(scenario, agents)
    else:
        if agents < 1 or int(arg["objects"]) < 1:
            raise RuntimeError("team.launch.py: give agents:=N objects:=M (seed:=S), or scenario:=FILE")
        grid = Grid(int(arg["width"]), int(arg["height"]))
        scenario = generate_scenario(agents, int(arg["objects"]), int(arg["seed"]), grid, int(arg["nmax"]))
        with tempfile.NamedTemporaryFile("w", prefix="ost_scenario_", suffix=".yaml", delete=False) as f:
            f.write(dump_scenario(scenario))
        path, agents = f.name, 0  # the generated file has the team already
    ns = "/" + arg["namespace"].strip("/")
    watch = []
    if arg["record"] or int(arg["foxglove"]):
        watched = {"record": arg["record"], "foxglove_port": int(arg["foxglove"])}
        watch = [
            Node(
                package="ost_ros",
                executable="watch_node",
                name="watch",
                namespace=ns,
                output="screen",
                parameters=[watched],
            )
        ]
    common: dict = {"scenario": path, "agents": agents, "observers": len(watch)}
    if arg["insecure"].lower() == "true":
        common["insecure"] = True
    else:  # signed messages: a key per robot and one for the world (docs/ros.md)
        keys = arg["keys"] or tempfile.mkdtemp(prefix="ost_keys_")
        if not arg["keys"]:
            make_keys(keys, [a.id for a in scenario.agents])
        common["keys"] = keys
    world = Node(
        package="ost_ros",
        executable="world_node",
        name="world",
        namespace=ns,
        output="screen",
        parameters=[
            {
                **common,
                "result_file": arg["result_file"],
                "event_skipping": arg["event_skipping"].lower() == "true",
                "max_steps": int(arg["max_steps"]),
            }
        ],
    )
    team = [
        Node(
            package="ost_ros",
            executable="agent_node",
            name=f"agent_{a.id}",
            namespace=ns,
            output="screen",
            parameters=[
                {
                    **common,
                    "agent_id": a.id,
                    "protocol": arg["protocol"],
                    "ci": int(arg["ci"]),
                    "interval": int(arg["interval"]),
                    "coordination": arg["coordination"],
                }
            ],
        )
        for a in scenario.agents
    ]
    # The run is over when the world leaves (it waits for the agents to read the result).
    done = RegisterEventHandler(OnProcessExit(target_action=world, on_exit=[EmitEvent(event=Shutdown())]))
    return [*watch, world, *team, done]


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=d, description=h) for name, (d, h) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_nodes)]
    )
