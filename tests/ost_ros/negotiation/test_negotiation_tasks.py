"""Task types: validation of bad input, geometry helpers and the message encoding."""

import pytest
from shapely.geometry import Polygon, box

from ost_ros.negotiation.errors import NegotiationError
from ost_ros.negotiation.messages import Offer
from ost_ros.negotiation.tasks import AreaTask, TargetTask, hole_free, make_task_polygon


@pytest.mark.parametrize(
    "verts, msg",
    [
        ([[0, 0], [1, 1]], "at least 3 distinct"),
        ([[0, 0], [1, 0], [2, 0]], "degenerate|invalid"),
        ([[0, 0], [1, 1], [0, 1], [1, 0]], "self-intersecting"),
        ([[0, 0], [1, float("nan")], [0, 1]], "finite"),
        ([1, 2, 3], "pairs"),
        ([[0, 0], [0, 0], [0, 0], [1, 1]], "at least 3 distinct"),
    ],
)
def test_degenerate_polygons_are_refused(verts, msg):
    with pytest.raises(NegotiationError, match=msg):
        AreaTask.from_vertices(verts)


def test_paper_polygon_has_the_stated_area():
    assert make_task_polygon(0.673).area == pytest.approx(0.673)
    assert make_task_polygon(0.74).area == pytest.approx(0.74)
    assert len(make_task_polygon().exterior.coords) == 7  # six vertices, closed ring
    with pytest.raises(NegotiationError):
        make_task_polygon(1.5)


def test_area_operators():
    t = AreaTask(box(0, 0, 1, 1))
    a, b = box(0, 0, 0.6, 1), box(0.4, 0, 1.5, 1)
    assert t.dim(t.overlap(a, b)) == pytest.approx(0.2)
    assert t.dim(t.union([a, b])) == pytest.approx(1.5)
    assert t.dim(t.outside(b)) == pytest.approx(0.5)
    assert t.size == 1.0


def test_area_encoding_round_trip_and_holes():
    t = AreaTask(make_task_polygon())
    p = Polygon([(0.2, 0.2), (0.5, 0.25), (0.4, 0.6)])
    assert t.decode(t.encode(p)).equals(p)
    with_hole = box(0, 0, 1, 1).difference(box(0.4, 0.4, 0.6, 0.6))
    with pytest.raises(NegotiationError, match="holes"):
        t.encode(with_hole)
    cut = hole_free(with_hole)
    assert not cut.interiors and cut.area > 0.45 and cut.within(with_hole.buffer(1e-9))


def test_target_task_validation_and_encoding():
    t = TargetTask.from_points([[0.1, 0.2], [0.5, 0.5], [0.9, 0.1]], [1, 2, 1])
    assert t.dim(frozenset({1, 2})) == 3.0 and t.size == 4.0
    assert t.decode(t.encode(frozenset({0, 2}))) == frozenset({0, 2})
    assert t.outside(frozenset({0})) == frozenset()
    with pytest.raises(NegotiationError, match="not one of the task's targets"):
        t.decode([0.3, 0.3])
    with pytest.raises(NegotiationError, match="at least one"):
        TargetTask.from_points([])
    with pytest.raises(NegotiationError, match="positive weight"):
        TargetTask.from_points([[0, 0]], [0])
    with pytest.raises(NegotiationError, match="distinct"):
        TargetTask.from_points([[0, 0], [0, 0]])


def test_offer_is_plain_data():
    import json

    o = Offer(round=3, period=7, sender=1, receiver=-1, kind="offer", params=(0.1, 0.2, 0.3, 0.4))
    d = json.loads(json.dumps(o.to_dict()))
    assert Offer.from_dict(d) == o
    assert all(isinstance(v, float) for v in d["params"])
    with pytest.raises(NegotiationError, match="unknown message kind"):
        Offer(0, 0, 0, 1, "haggle")
    with pytest.raises(NegotiationError, match="malformed"):
        Offer.from_dict({"round": 1})
    with pytest.raises(NegotiationError, match="finite"):
        Offer(0, 0, 0, 1, "offer", (float("inf"),))
