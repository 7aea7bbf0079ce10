"""The live view: a run streamed to the Foxglove app over its WebSocket protocol (foxglove-sdk).

Two channels: ``/ost/scene`` (``foxglove.SceneUpdate``, for the 3D panel: one cell = 1 m in
frame ``map``, y downward as the sweep's rows) and ``/ost/robots`` (JSON, for the Raw Messages,
Table and Plot panels: ``{"step", "delivered", "objects", "robots": [{"id", "x", "y", "state",
"holding"}]}``). Updates go out at most ``rate`` times a second of wall time, and once more
whenever the run's step changes after a quiet spell, so the last state is always on screen.
"""

from __future__ import annotations

import json
import time
from typing import Any

from ost_ros.watch.animate import state_palette
from ost_ros.world import World

FRAME = "map"
ROBOTS_TOPIC = "/ost/robots"
SCENE_TOPIC = "/ost/scene"
ROBOTS_SCHEMA = {
    "type": "object",
    "properties": {
        "step": {"type": "integer"},
        "delivered": {"type": "integer"},
        "objects": {"type": "integer"},
        "robots": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "id": {"type": "integer"},
                    "x": {"type": "integer"},
                    "y": {"type": "integer"},
                    "state": {"type": "string"},
                    "holding": {"type": "integer"},
                },
            },
        },
    },
}


def _rgba(hex_colour: str, alpha: float = 1.0) -> tuple[float, float, float, float]:
    h = hex_colour.lstrip("#")
    return (int(h[0:2], 16) / 255, int(h[2:4], 16) / 255, int(h[4:6], 16) / 255, alpha)


class LiveView:
    def __init__(self, host: str, port: int, rate: float):
        import foxglove
        from foxglove.channels import SceneUpdateChannel

        self.server = foxglove.start_server(name="ost", host=host, port=port)
        self.port = self.server.port
        self.robots = foxglove.Channel(
            ROBOTS_TOPIC,
            schema=foxglove.Schema(
                name="ost.Robots", encoding="jsonschema", data=json.dumps(ROBOTS_SCHEMA).encode()
            ),
            message_encoding="json",
        )
        self.scene = SceneUpdateChannel(SCENE_TOPIC)
        self.period = 1.0 / rate
        self.sent_at = -1e9
        self.sent_step = -1
        self.states: dict[int, str] = {}
        self.palette: dict[str, str] | None = None

    def step(self, follower: Any, world: World, actions: list) -> None:
        """After each step the follower executed: note the robots' states, send if the rate allows."""
        for a in actions:
            self.states[a.agent] = a.state
        if time.monotonic() - self.sent_at >= self.period:
            self.send(follower, world)

    def tick(self, follower: Any, world: World) -> None:
        """From the node's timer: the newest step if it was not sent yet, and the latest state
        again every second (the protocol keeps no last message for a panel that opens later)."""
        if world.t != self.sent_step or time.monotonic() - self.sent_at >= 1.0:
            self.send(follower, world)

    def send(self, follower: Any, world: World) -> None:
        rt = follower.rt
        if rt is None:
            return
        if self.palette is None:
            self.palette = state_palette(rt.protocol)
        now = time.time_ns()
        self.robots.log(json.dumps(self.snapshot(world)), log_time=now)
        self.scene.log(self.scene_update(world), log_time=now)
        self.sent_at, self.sent_step = time.monotonic(), world.t

    def snapshot(self, world: World) -> dict:
        agents = [a.id for a in world.scenario.agents]
        return {
            "step": world.t,
            "delivered": sum(o.delivered is not None for o in world.objects.values()),
            "objects": len(world.objects),
            "robots": [
                {
                    "id": a,
                    "x": world.positions[a][0],
                    "y": world.positions[a][1],
                    "state": "FAILED" if a in world.failed else self.states.get(a, "SEARCHING"),
                    "holding": world.carrying.get(a, -1),
                }
                for a in agents
            ],
        }

    def scene_update(self, world: World) -> Any:
        from foxglove.messages import (
            Color,
            CubePrimitive,
            LinePrimitive,
            LinePrimitiveLineType,
            Point3,
            Pose,
            Quaternion,
            SceneEntity,
            SceneUpdate,
            SpherePrimitive,
            Vector3,
        )

        def pose(x: float, y: float, z: float = 0.0) -> Any:
            return Pose(position=Vector3(x=float(x), y=float(y), z=z), orientation=Quaternion(w=1.0))

        def colour(rgba: tuple[float, float, float, float]) -> Any:
            return Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])

        g = world.scenario.grid
        boxes = []
        for area in world.scenario.subareas:
            x0, y0, x1, y1 = (
                area.x0 - 0.5,
                area.y0 - 0.5,
                area.x0 + area.width - 0.5,
                area.y0 + area.height - 0.5,
            )
            boxes.append(
                LinePrimitive(
                    type=LinePrimitiveLineType.LineLoop,
                    pose=pose(0, 0),
                    thickness=0.3,
                    points=[Point3(x=x0, y=y0), Point3(x=x1, y=y0), Point3(x=x1, y=y1), Point3(x=x0, y=y1)],
                    color=colour((0.6, 0.6, 0.6, 1.0)),
                )
            )
        held = set(world.carrying.values())
        objects, dests = [], []
        for o in world.objects.values():
            if o.delivered is not None:
                continue
            rgba = (0.19, 0.64, 0.33, 1.0) if o.spec.id in held else (0.87, 0.18, 0.15, 1.0)
            side = 0.6 + 0.15 * o.spec.required
            objects.append(
                CubePrimitive(pose=pose(*o.at, 0.5), size=Vector3(x=side, y=side, z=side), color=colour(rgba))
            )
            dests.append(
                CubePrimitive(
                    pose=pose(*o.spec.destination, 0.05),
                    size=Vector3(x=1.0, y=1.0, z=0.1),
                    color=colour((0.19, 0.51, 0.74, 0.8)),
                )
            )
        palette = self.palette or {}
        robots = [
            SpherePrimitive(
                pose=pose(*world.positions[a.id], 1.2),
                size=Vector3(x=2.0, y=2.0, z=2.0),
                color=colour(
                    _rgba(
                        palette.get(
                            "FAILED" if a.id in world.failed else self.states.get(a.id, "SEARCHING"),
                            "#969696",
                        )
                    )
                ),
            )
            for a in world.scenario.agents
        ]
        grid = LinePrimitive(
            type=LinePrimitiveLineType.LineLoop,
            pose=pose(0, 0),
            thickness=0.5,
            points=[
                Point3(x=-0.5, y=-0.5),
                Point3(x=g.width - 0.5, y=-0.5),
                Point3(x=g.width - 0.5, y=g.height - 0.5),
                Point3(x=-0.5, y=g.height - 0.5),
            ],
            color=colour((0.3, 0.3, 0.3, 1.0)),
        )
        return SceneUpdate(
            entities=[
                SceneEntity(frame_id=FRAME, id="grid", lines=[grid, *boxes]),
                SceneEntity(frame_id=FRAME, id="objects", cubes=objects + dests),
                SceneEntity(frame_id=FRAME, id="robots", spheres=robots),
            ]
        )

    def stop(self) -> None:
        self.server.stop()
