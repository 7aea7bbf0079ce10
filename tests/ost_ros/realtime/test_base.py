"""A robot's own picture of its base (ost_ros/realtime/base.py): when it may be decided from."""

from ost_ros.model import Grid, ObjectSpec
from ost_ros.realtime.base import mirror_of
from ost_ros.realtime.messages import SEARCHING_STATE
from ost_ros.realtime.world import REACHED, Follow, GoalResult, GoalStarted, RealtimeWorld
from ost_ros.scenario import build_scenario
from ost_ros.team import TeamInfo


def test_a_route_over_by_the_decision_waits_for_its_result():
    """Over DDS a base's events come late now and then (seconds, at rtf 1000): a sweep decided
    over on the picture alone said SearchDone before the detections on its way were in, and those
    objects were never carried. A route the base has finished by the decision's time holds the
    decision until its result, which comes after every detection on the way."""
    s = build_scenario(Grid(12, 3), [ObjectSpec(0, (6, 2), (11, 2), 1)], n_agents=1, nmax=1)
    team = TeamInfo.from_scenario(s)
    world = RealtimeWorld(s, tracking=True)
    mirror = mirror_of(team, 0, lambda obj: s.objects[obj].destination)
    start = mirror.cell
    path = tuple((start[0] + k, start[1]) for k in range(5))
    goal = Follow(path, SEARCHING_STATE)
    mirror.sent(1, goal)
    assert not mirror.settled(0.0)  # sent, not started
    events = world.goal(0, 1, goal, 0.0)
    (started,) = [e for e in events if isinstance(e, GoalStarted)]
    mirror.take(started)
    assert mirror.settled(0.0) and mirror.settled(3.0)  # on its way: the picture holds
    assert not mirror.settled(4.0) and not mirror.settled(10.0)  # over by then: its result first
    results = [e for e in world.advance(10.0) if isinstance(e, GoalResult)]
    assert [r.outcome for r in results] == [REACHED] and results[0].time == 4.0
    mirror.take(results[0])
    assert mirror.settled(10.0) and mirror.feedback(10.0).cell == path[-1]
