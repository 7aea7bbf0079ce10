"""Algorithm Coordination: hand-computed cases, ties, and the numpy version against a plain
transcription of the paper's pseudo-code."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ost_ros.coordination import Assignment, CoordinationPolicy, coordinate
from ost_ros.model import ObjectSpec, manhattan


def reference(ids, cost, loc, objects):
    """The paper's §3.3 steps written as plainly as possible (loops, no numpy)."""
    cost = dict(zip(ids, cost))
    loc = dict(zip(ids, (tuple(x) for x in loc)))
    left = sorted(objects, key=lambda o: o.id)
    schedule, selections = [], []
    while left:
        c = {(o.id, j): cost[j] + manhattan(loc[j], o.location) for o in left for j in ids}
        picks = {j: min(left, key=lambda o: (c[o.id, j], o.id)) for j in ids}
        selections.append([picks[j].id for j in ids])
        selected = sorted({o.id: o for o in picks.values()}.values(), key=lambda o: o.id)
        m = {o.id: sorted(c[o.id, j] for j in ids)[o.required - 1] for o in selected}
        opt = min(selected, key=lambda o: (m[o.id], o.id))
        group = sorted(sorted(ids, key=lambda j: (c[opt.id, j], j))[: opt.required])
        finish = m[opt.id] + manhattan(opt.location, opt.destination)
        for j in group:
            cost[j], loc[j] = finish, opt.destination
        schedule.append(Assignment(opt.id, tuple(group), m[opt.id], finish))
        left.remove(opt)
    return schedule, [cost[j] for j in ids], [loc[j] for j in ids], selections


def test_hand_computed_two_agents_two_objects():
    # C(o0) = (0+2, 5+8) = (2, 13); C(o1) = (0+8, 5+2) = (8, 7).
    # Round 1: A0 picks o0, A1 picks o1; M0 = 2, M1 = 8 -> o0 by A0, done at 2+3 = 5.
    # Round 2: C(o1) = (5+9, 7) -> M1 = 14, both agents, done at 15.
    objs = [ObjectSpec(0, (2, 0), (2, 3), 1), ObjectSpec(1, (8, 0), (8, 1), 2)]
    r = coordinate([0, 1], [0, 5], [(0, 0), (10, 0)], objs)
    assert r.schedule == [Assignment(0, (0,), 2, 5), Assignment(1, (0, 1), 14, 15)]
    assert r.cost.tolist() == [15, 15]
    assert r.loc.tolist() == [[8, 1], [8, 1]]
    assert r.selections.tolist() == [[0, 1], [1, 1]]


def test_group_ties_go_to_lower_agent_id():
    # A2 is on the object; A0 and A1 both reach it at 2: A0 joins (lower id).
    r = coordinate([0, 1, 2], [0, 0, 0], [(0, 0), (4, 0), (2, 0)], [ObjectSpec(5, (2, 0), (2, 1), 2)])
    assert r.schedule == [Assignment(5, (0, 2), 2, 3)]
    assert r.cost.tolist() == [3, 0, 3]


def test_selection_ties_go_to_lower_object_id():
    # Both objects are one step away: the agent selects (and gets) object 3 first.
    objs = [ObjectSpec(7, (0, 1), (0, 5), 1), ObjectSpec(3, (1, 0), (4, 0), 1)]
    r = coordinate([0], [10], [(0, 0)], objs)
    assert [a.object for a in r.schedule] == [3, 7]
    assert r.schedule[0] == Assignment(3, (0,), 11, 14)
    # from (4, 0) at 14 to (0, 1): 5 steps, carried 4 cells
    assert r.schedule[1] == Assignment(7, (0,), 19, 23)


def test_opt_is_min_over_selected_objects_only():
    # Agent 0 selects o1 (distance 1); o0 is nobody's selection even though its M would be
    # smaller for the pair, so it waits for a later round.
    objs = [ObjectSpec(0, (5, 0), (5, 1), 1), ObjectSpec(1, (1, 0), (1, 1), 1)]
    r = coordinate([0], [0], [(0, 0)], objs)
    assert [a.object for a in r.schedule] == [1, 0]


def test_object_needing_more_agents_than_team_is_an_error():
    with pytest.raises(ValueError, match="needs 3 agents"):
        coordinate([0, 1], [0, 0], [(0, 0), (0, 0)], [ObjectSpec(0, (1, 1), (2, 2), 3)])


def test_empty_batch():
    r = coordinate([0, 1], [3, 4], [(0, 0), (1, 1)], [])
    assert r.schedule == [] and r.cost.tolist() == [3, 4]


cells = st.tuples(st.integers(0, 30), st.integers(0, 30))


@st.composite
def instances(draw):
    n = draw(st.integers(1, 6))
    ids = sorted(draw(st.sets(st.integers(0, 50), min_size=n, max_size=n)))
    cost = draw(st.lists(st.integers(0, 40), min_size=n, max_size=n))
    loc = draw(st.lists(cells, min_size=n, max_size=n))
    m = draw(st.integers(0, 7))
    oids = draw(st.sets(st.integers(0, 99), min_size=m, max_size=m))
    objs = []
    for oid in oids:
        at, d = draw(cells), draw(cells)
        objs.append(ObjectSpec(oid, at, d, draw(st.integers(1, n))))
    return ids, cost, loc, objs


@given(instances())
def test_numpy_matches_the_papers_pseudocode(inst):
    ids, cost, loc, objs = inst
    got = coordinate(ids, cost, loc, objs)
    schedule, c, free_loc, sel = reference(ids, cost, loc, objs)
    assert got.schedule == schedule
    assert got.cost.tolist() == c
    assert [tuple(x) for x in got.loc.tolist()] == free_loc
    assert got.selections.tolist() == sel


@given(instances())
def test_schedule_invariants(inst):
    ids, cost, loc, objs = inst
    r = coordinate(ids, cost, loc, objs)
    by_id = {o.id: o for o in objs}
    assert sorted(a.object for a in r.schedule) == sorted(by_id)  # each object once
    free = dict(zip(ids, cost))
    where = dict(zip(ids, (tuple(x) for x in loc)))
    for a in r.schedule:
        o = by_id[a.object]
        assert len(set(a.agents)) == o.required  # exactly n_i agents
        arrivals = [free[j] + manhattan(where[j], o.location) for j in a.agents]
        assert max(arrivals) == a.start  # start = last arrival
        assert a.finish == a.start + manhattan(o.location, o.destination)
        for j in a.agents:  # no agent double-booked
            assert free[j] <= a.start
            free[j], where[j] = a.finish, o.destination


def test_policy_triggers():
    assert CoordinationPolicy(ci=3).due(5, 3, 0.1, 0.2)
    assert not CoordinationPolicy(ci=3).due(5, 2, 0.1, 0.2)
    assert CoordinationPolicy(interval=10).due(9, 1, 0, 0)
    assert not CoordinationPolicy(interval=10).due(10, 1, 0, 0)
    assert not CoordinationPolicy(interval=10).due(9, 0, 0, 0)
    assert CoordinationPolicy(area_fraction=0.25).due(7, 1, 0.24, 0.26)
    assert not CoordinationPolicy(area_fraction=0.25).due(7, 1, 0.26, 0.3)
    for bad in (dict(ci=0), dict(interval=0), dict(area_fraction=1.5), dict(interval=2, area_fraction=0.5)):
        with pytest.raises(ValueError):
            CoordinationPolicy(**bad)


@given(
    st.integers(-(2**40), 2**40),
    st.lists(st.integers(0, 200), max_size=6).map(tuple),
    st.integers(-(2**40), 2**40),
    st.integers(-(2**40), 2**40),
    st.booleans(),
)
def test_an_assignments_text_is_the_dataclass_one(obj, agents, start, finish, numpy_ints):
    """Assignment writes its own repr (a robot writes the schedule's for each digest): the
    text the generated one wrote, numpy integers included."""
    import dataclasses

    import numpy as np

    Ref = dataclasses.make_dataclass("Assignment", ["object", "agents", "start", "finish"], frozen=True)
    if numpy_ints:
        start, finish = np.int64(start), np.int64(finish)
    assert repr(Assignment(obj, agents, start, finish)) == repr(Ref(obj, agents, start, finish))
