"""The robots' bases in continuous time, by hand: a path at the robot's period, results and
detections computed from the path, preemption at a cell boundary, the carry rule (the last of the
declared group starts it, never another group), failures dropping a load where the move under
way ends, stalls, speed noise — and the record the lockstep world keeps."""

import pytest

from ost_ros.model import AgentSpec, Grid, ObjectSpec
from ost_ros.realtime.messages import FINISH_STATE, SEARCHING_STATE
from ost_ros.realtime.world import (
    ABORTED,
    PREEMPTED,
    REACHED,
    REFUSED,
    Carry,
    CarryStarted,
    Detection,
    Follow,
    GoalResult,
    RealtimeWorld,
    Stand,
)
from ost_ros.scenario import build_scenario
from ost_ros.search import route


def line(periods=(1, 1), objects=(), width=12, height=3):
    agents = [AgentSpec(i, (0, 1), k) for i, k in enumerate(periods)]
    return build_scenario(
        Grid(width, height),
        list(objects),
        partition=(len(periods), 1),
        agents=agents,
        nmax=min(2, len(periods)),
    )


def run_until(w, t):
    out = []
    while (nt := w.next_time()) is not None and nt <= t:
        out += w.advance(nt)
    return out


def test_a_path_at_the_robots_period_reaches_its_end_and_senses_on_the_way():
    w = RealtimeWorld(line(periods=(2, 1), objects=[ObjectSpec(0, (5, 2), (0, 0), 1)]))
    path = tuple(route([(0, 1), (6, 1)]))
    assert w.goal(0, 1, Follow(path, SEARCHING_STATE), 1.0) == []
    # period 2: moves begin at steps 2, 4, ...; the object comes into range at (4, 1), reached at 9
    events = run_until(w, 100)
    det = [e for e in events if isinstance(e, Detection)]
    assert [(d.time, d.cell, [o.id for o in d.objects]) for d in det] == [(9, (4, 1), [0])]
    assert [e for e in events if isinstance(e, GoalResult)] == [GoalResult(0, 1, REACHED, 13, (6, 1))]
    assert w.position(0, 6.5) == (2, 1) and w.position(0, 7) == (3, 1)  # (mid-move: where it left)


def test_a_new_goal_takes_over_at_the_next_cell_boundary():
    w = RealtimeWorld(line())
    w.goal(0, 1, Follow(tuple(route([(0, 1), (8, 1)])), "HELPING"), 0.0)
    fb = w.feedback(0, 3.0)  # a move leaving at exactly 3 has not begun: it stands at (3, 1)
    assert (fb.cell, fb.time, fb.goal, fb.index) == ((3, 1), 3.0, 1, 3)
    out = w.goal(0, 2, Follow(((3, 1), (3, 2)), "HELPING"), 3.0)
    assert out == [GoalResult(0, 1, PREEMPTED, 3.0, (3, 1))]
    assert run_until(w, 10) == [GoalResult(0, 2, REACHED, 4, (3, 2))]
    refused = w.goal(0, 3, Follow(((5, 1), (6, 1)), "HELPING"), 4.0)
    assert refused[0].outcome == REFUSED and refused[0].code == "START"


def test_a_goal_decided_less_than_a_step_ago_takes_over_when_it_was_decided():
    """An agent node's goal reaches the world milliseconds after its decision: a move or a stand
    takes over at the decision's time (every event it causes is still to come: a move takes a
    step), so its first move begins in that step — not in the next one."""
    w = RealtimeWorld(line())
    w.goal(0, 1, Follow(((0, 1), (1, 1)), "HELPING"), 0.0)
    assert run_until(w, 1) == [GoalResult(0, 1, REACHED, 1, (1, 1))]
    go = Follow(((1, 1), (2, 1), (3, 1)), "HELPING")
    assert w.takeover(0, go, 1.0, 1.4) == 1.0  # decided at 1 (on its result), here at 1.4
    assert w.takeover(0, Stand("DECISION"), 1.0, 1.4) == 1.0
    assert w.takeover(0, go, 1.0, 2.0) == 2.0  # a step late: its first move may have been due
    assert w.takeover(0, go, 0.5, 1.4) == 1.4  # before its base's last event (reached at 1)
    assert w.takeover(0, Follow(((1, 1),), "HELPING"), 1.0, 1.4) == 1.4  # no move: reached now
    assert w.takeover(0, go, 1.6, 1.4) == 1.6  # (for later: as asked)
    w.goal(0, 2, go, w.takeover(0, go, 1.0, 1.4))
    assert run_until(w, 10) == [GoalResult(0, 2, REACHED, 3, (3, 1))]


def test_a_hold_or_a_let_go_takes_over_when_it_arrives():
    """A hold's lift and a let-go concern the partners' bases too: never taken over earlier."""
    obj = ObjectSpec(0, (2, 1), (6, 1), 2)
    w = RealtimeWorld(line(periods=(1, 1), objects=[obj]))
    for a in (0, 1):
        w.goal(a, 1, Follow(((0, 1), (1, 1), (2, 1)), "HELPING"), 0.0)
    run_until(w, 2)
    hold = Carry(0, (0, 1), "WAITING")
    assert w.takeover(0, hold, 2.0, 2.3) == 2.3
    w.goal(0, 2, hold, 2.3)
    assert w.takeover(0, Stand("DECISION", unless_carrying=True), 2.3, 2.5) == 2.5
    assert w.takeover(0, Follow(((2, 1), (3, 1)), "HELPING"), 2.3, 2.5) == 2.5  # it holds


def test_the_last_member_of_the_declared_group_starts_the_carry_and_no_other_group_does():
    obj = ObjectSpec(0, (2, 1), (6, 1), 2)
    w = RealtimeWorld(line(periods=(1, 1, 1), objects=[obj]))
    for a in (0, 1, 2):
        w.goal(a, 1, Follow(((0, 1), (1, 1), (2, 1)), "HELPING"), 0.0)
    run_until(w, 2)
    assert w.goal(0, 2, Carry(0, (0, 1), "WAITING"), 2.0) == []
    assert w.goal(2, 2, Carry(0, (1, 2), "WAITING"), 2.0) == []  # a stale plan: another group
    assert w.next_time() is None  # nobody has both members of a group holding yet
    bad = w.goal(1, 2, Carry(0, (1,), "WAITING"), 3.0)
    assert bad[0].code == "BAD_GROUP"
    w.goal(1, 3, Carry(0, (0, 1), "WAITING"), 5.0)  # the last of (0, 1): the lift at 5
    events = run_until(w, 100)
    assert events[0] == CarryStarted(0, (0, 1), 5)
    assert sorted(e.agent for e in events if isinstance(e, GoalResult)) == [0, 1]
    assert {e.time for e in events if isinstance(e, GoalResult)} == {9}
    rec = w.objects[0]
    assert (rec.start, rec.delivered, rec.carriers) == (5, 9, (0, 1))
    assert w.bots[2].kind == "hold"  # still holding for its group: it will never start


def test_a_let_go_releases_a_hold_and_is_refused_once_the_group_has_lifted():
    """A robot letting go of a hold after a failure (its let-go crossing the network while its
    group may lift): a hold not lifted is released; a carry under way goes on, the let-go refused."""
    obj = ObjectSpec(0, (2, 1), (6, 1), 2)
    w = RealtimeWorld(line(periods=(1, 1), objects=[obj]))
    for a in (0, 1):
        w.goal(a, 1, Follow(((0, 1), (1, 1), (2, 1)), "HELPING"), 0.0)
    run_until(w, 2)
    w.goal(0, 2, Carry(0, (0, 1), "WAITING"), 2.0)
    assert w.goal(0, 3, Stand("DECISION", unless_carrying=True), 2.0) == [
        GoalResult(0, 2, PREEMPTED, 2.0, (2, 1))
    ]
    w.goal(0, 4, Carry(0, (0, 1), "WAITING"), 3.0)
    w.goal(1, 2, Carry(0, (0, 1), "WAITING"), 3.0)  # the lift at 3
    run_until(w, 3)
    refused = w.goal(1, 3, Stand("DECISION", unless_carrying=True), 3.5)
    assert refused[0].outcome == REFUSED and refused[0].code == "CARRYING"
    assert w.objects[0].carriers == (0, 1)  # it goes on
    run_until(w, 100)
    assert w.objects[0].delivered == 7


def test_refusals_name_their_reason():
    w = RealtimeWorld(line(objects=[ObjectSpec(0, (4, 1), (6, 1), 1)]))
    assert w.goal(0, 1, Carry(0, (0,), "WAITING"), 0.0)[0].code == "NOT_AT_OBJECT"
    assert w.goal(0, 2, Stand(FINISH_STATE), 0.0) == []  # at its base
    w.goal(1, 1, Follow(((0, 1), (1, 1)), "HELPING"), 0.0)
    run_until(w, 1)
    assert w.goal(1, 2, Stand(FINISH_STATE), 1.0)[0].code == "NOT_AT_BASE"
    assert w.goal(0, 3, Follow(((0, 1), (0, 5)), "HELPING"), 1.0)[0].code == "PATH"
    assert w.goal(0, 4, Carry(7, (0,), "WAITING"), 1.0)[0].code == "UNKNOWN"


def test_a_failed_carrier_drops_the_load_where_the_move_under_way_ends():
    obj = ObjectSpec(0, (1, 1), (9, 1), 2)
    w = RealtimeWorld(line(objects=[obj]))
    for a in (0, 1):
        w.goal(a, 1, Follow(((0, 1), (1, 1)), "HELPING"), 0.0)
    run_until(w, 1)
    for a in (0, 1):
        w.goal(a, 2, Carry(0, (0, 1), "WAITING"), 1.0)
    run_until(w, 4)  # lifted at 1: at (4, 1) at step 4
    w.kill(1, 4.0)  # a move leaving at 4 has not begun
    assert w.objects[0].at == (4, 1) and not w.objects[0].moving
    events = run_until(w, 10)  # the survivor's goal ends; the load now lies in its sensor
    assert [e for e in events if isinstance(e, GoalResult)] == [
        GoalResult(0, 2, ABORTED, 4.0, (4, 1), "MEMBER_FAILED", "agent 1 failed")
    ]
    assert [(e.agent, e.cell) for e in events if isinstance(e, Detection)] == [(0, (4, 1))]
    notice = w.notice(1, 4, 3)
    assert notice.dropped[0].location == (4, 1) and notice.at == (4, 1) and notice.delivered == ()
    assert w.failed == {1: 4} and w.survivors == 1
    assert w.goal(0, 3, Carry(0, (0, 1), "WAITING"), 10.0)[0].code == "MEMBER_FAILED"


def test_a_stall_delays_every_move_not_begun():
    w = RealtimeWorld(line(), stalls=((0, 2.0, 5.0),))
    w.goal(0, 1, Follow(tuple(route([(0, 1), (4, 1)])), "HELPING"), 0.0)
    assert run_until(w, 100) == [GoalResult(0, 1, REACHED, 9.0, (4, 1))]


def test_speed_noise_slows_a_goal_by_a_seeded_factor():
    reached = []
    for seed in (1, 1, 2):
        w = RealtimeWorld(line(), speed_jitter=0.5, seed=seed)
        w.goal(0, 1, Follow(tuple(route([(0, 1), (4, 1)])), "HELPING"), 0.0)
        (r,) = run_until(w, 100)
        reached.append(r.time)
    assert reached[0] == reached[1] != reached[2]
    assert all(4 < t <= 6 for t in reached)


def test_the_record_counts_like_the_lockstep_world():
    # One robot: sweep 3 cells, wait 2 steps, walk 2 cells back, finish at its base.
    w = RealtimeWorld(line(periods=(1,), width=4))
    w.goal(0, 1, Follow(((0, 1), (1, 1), (2, 1), (3, 1)), SEARCHING_STATE), 0.0)
    run_until(w, 3)
    w.goal(0, 2, Stand("DECISION"), 3.0)
    w.goal(0, 3, Follow(((3, 1), (2, 1), (1, 1), (0, 1)), "RETURNING"), 5.0)
    run_until(w, 8)
    w.goal(0, 4, Stand(FINISH_STATE), 8.0)
    w.end = 8.0
    assert w.done
    rec = w.record(0)
    assert (rec.cost, rec.search, rec.travel, rec.carry, rec.idle) == (8, 3, 3, 0, 2)
    assert w.result().makespan == 8 and w.result().steps == 9


def test_bad_options_are_refused():
    with pytest.raises(ValueError, match="jitter"):
        RealtimeWorld(line(), speed_jitter=-1)
    with pytest.raises(ValueError, match="no such agent"):
        RealtimeWorld(line(), stalls=((9, 1.0, 1.0),))
