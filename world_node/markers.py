"""``/ost/markers``: the grid, agents, objects and their destinations as a MarkerArray (RViz,
Foxglove). One cell = 1 m in frame ``map``; z = 0."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from ost_ros.world import World

FRAME = "map"


def _marker(mid: int, ns: str, kind: int, stamp: Time, scale: float, rgba) -> Marker:
    m = Marker()
    m.header.frame_id = FRAME
    m.header.stamp = stamp
    m.ns, m.id, m.type, m.action = ns, mid, kind, Marker.ADD
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = m.scale.z = scale
    m.color = ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
    return m


def _pt(x: float, y: float) -> Point:
    return Point(x=float(x), y=float(y), z=0.0)


def world_markers(world: World, stamp: Time) -> MarkerArray:
    g = world.scenario.grid
    grid = _marker(0, "grid", Marker.LINE_STRIP, stamp, 0.2, (0.6, 0.6, 0.6, 1.0))
    grid.points = [
        _pt(-0.5, -0.5),
        _pt(g.width - 0.5, -0.5),
        _pt(g.width - 0.5, g.height - 0.5),
        _pt(-0.5, g.height - 0.5),
        _pt(-0.5, -0.5),
    ]
    agents = _marker(1, "agents", Marker.SPHERE_LIST, stamp, 1.0, (0.1, 0.4, 1.0, 1.0))
    agents.points = [_pt(*world.positions[a.id]) for a in world.scenario.agents]
    live = [o for o in world.objects.values() if o.delivered is None]
    objects = _marker(2, "objects", Marker.CUBE_LIST, stamp, 0.8, (1.0, 0.5, 0.0, 1.0))
    objects.points = [_pt(*o.at) for o in live]
    dest = _marker(3, "destinations", Marker.CUBE_LIST, stamp, 0.4, (0.1, 0.8, 0.2, 0.8))
    dest.points = [_pt(*o.spec.destination) for o in live]
    return MarkerArray(markers=[grid, agents, objects, dest])
