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


def test_a_decision_waits_for_the_picture_and_is_taken_once_the_base_says_more():
    """The one decide path of a robot whose base is across a network (:class:`BaseLink`, the
    agent node's and the in-process runner's): a decision asked for while a goal it sent has not
    started waits, and is answered from the picture once the base's event is in."""
    from ost_ros.coordination import CoordinationPolicy
    from ost_ros.realtime.outputs import AskFeedback, SendGoal
    from ost_ros.realtime.remote import BaseLink
    from ost_ros.realtime.run import make_agent

    s = build_scenario(Grid(12, 3), [ObjectSpec(0, (6, 2), (11, 2), 1)], n_agents=1, nmax=1)
    team = TeamInfo.from_scenario(s)
    world = RealtimeWorld(s, tracking=True)
    rt = make_agent(team, 0, "ccp", CoordinationPolicy(ci=1))
    rt.across_a_network()
    link = BaseLink(rt, mirror_of(team, 0, rt.destination))
    (ask,) = [o for o in rt.start(0.0) if isinstance(o, AskFeedback)]
    (goal,) = [o for o in link.decide(ask.at, 0.0) if isinstance(o, SendGoal)]  # the picture is whole
    link.goal(goal)
    assert rt.asking() is None
    # the next decision, asked for before the base has taken that goal over: it waits
    assert link.decide(0.2, 0.2) == [] and link.waiting == 0.2
    assert link.retry(0.25) == [] and link.waiting == 0.2  # nothing new: it waits on
    (started,) = [e for e in world.goal(0, goal.id, goal.goal, 0.0) if isinstance(e, GoalStarted)]
    assert link.event(started, (), 0.3) == []  # a goal took over: its picture's alone
    link.retry(0.3)  # the picture is whole: answered (the running goal goes on)
    assert link.waiting is None and rt.asking() is None and rt.rule.due  # (decided at the move's end)
