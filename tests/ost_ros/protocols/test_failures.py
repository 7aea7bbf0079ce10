"""Robot failures in the core (every protocol of the registry that recovers, under each
organisation it runs): the recovery
arithmetic by hand, a hand-checked run with a carrier failing mid-carry, and the promises as
properties on random scenarios — with at least n_max survivors every object is still delivered,
survivors agree, and (shared-schedule protocols) planned = executed after the last recovery;
with fewer, the run ends saying which objects could not be moved and why."""

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros import protocols
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid, ObjectSpec, moves_between
from ost_ros.protocols.shared.recovery import Sweep, drop_cell, remaining_sweep
from ost_ros.scenario import build_scenario
from ost_ros.search import route
from tests.strategies import policies, scenarios


def test_moves_between_counts_movable_steps():
    assert moves_between(0, 5) == 5
    assert moves_between(3, 3) == 0 and moves_between(4, 2) == 0
    assert moves_between(0, 5, 2) == 3  # steps 0, 2, 4
    assert moves_between(1, 7, 3) == 2  # steps 3, 6
    assert moves_between(3, 4, 3) == 1


def test_drop_cell_follows_the_carry_route():
    # carried from (0, 0) toward (3, 2) since step 10 (x first, then y); failure in step 12:
    # moved in steps 10 and 11
    assert drop_cell((0, 0), (3, 2), 10, 12) == (2, 0)
    assert drop_cell((0, 0), (3, 2), 10, 10) == (0, 0)
    assert drop_cell((0, 0), (3, 2), 10, 99) == (3, 2)
    assert drop_cell((0, 0), (3, 2), 10, 14, period=2) == (2, 0)  # steps 10 and 12


def test_remaining_sweep_and_take_over():
    path = tuple(route([(0, 1), (5, 1)]))  # 6 cells, finish at step 5
    sw = Sweep(7, path, 0, 5)
    assert remaining_sweep(sw, 0) == path  # failed before sensing anything
    assert remaining_sweep(sw, 2) == path[2:]  # stood on path[2] in step 2, unsensed
    assert remaining_sweep(sw, 5) == path[5:]  # on the last cell, SearchDone not sent
    assert remaining_sweep(sw, 6) == ()  # done in step 5
    t = Sweep.take_over(3, (2, 4), 20, path[2:])
    assert t.path[0] == (2, 4) and t.path[t.walk :] == path[2:]
    assert t.walk == 3 and t.start == 20 and t.finish == 20 + 3 + 3


def two_robot_carry():
    # 9x3 grid, 3 robots (3x1 partition), one object needing 2 robots, carried far.
    return build_scenario(Grid(9, 3), [ObjectSpec(0, (1, 1), (8, 2), 2)], n_agents=3, nmax=2)


def test_carrier_failing_mid_carry_leaves_the_object_where_it_was_held():
    s = two_robot_carry()
    base = simulate(s, policy=CoordinationPolicy(ci=1))
    (a,) = base.schedule
    dead, t = a.agents[0], a.start + 2  # two cells carried, then a carrier fails
    r = simulate(s, policy=CoordinationPolicy(ci=1), failures={dead: t})
    assert r.completed and r.agreement and not r.rejections and not r.warnings
    assert r.failures == [{"agent": dead, "step": t}]
    (again,) = r.schedule
    assert dead not in again.agents and again.start > t
    assert r.objects[0].delivered == again.finish and dead not in r.objects[0].agents
    assert r.agents[dead].cost is None
    assert r.predicted_makespan == r.makespan > base.makespan


def test_dead_searcher_cells_are_swept_by_a_survivor():
    # One object in robot 2's subarea; robot 2 fails at once: somebody else must find it.
    s = build_scenario(Grid(9, 3), [ObjectSpec(0, (7, 1), (0, 0), 1)], n_agents=3, nmax=1)
    r = simulate(s, policy=CoordinationPolicy(ci=1), failures={2: 0})
    assert r.completed and r.found[0] > 0
    assert r.objects[0].agents[0] != 2


def test_too_few_survivors_end_with_a_report():
    s = two_robot_carry()
    r = simulate(s, policy=CoordinationPolicy(ci=1), failures={0: 0, 1: 0})
    assert not r.completed and r.makespan is not None
    assert r.objects[0].delivered is None
    assert "objects [0] need up to 2 robots and 1 survive" in r.error


def test_bad_failures_are_refused():
    s = two_robot_carry()
    with pytest.raises(ValueError, match="no such agent"):
        simulate(s, failures={9: 3})
    with pytest.raises(ValueError, match="non-negative"):
        simulate(s, failures={0: -1})
    with pytest.raises(ValueError, match="step engine"):
        simulate(s, failures={0: 3}, engine="event")


@st.composite
def failing_runs(draw):
    s = draw(scenarios(agents=(2, 6), objects=(0, 7)))
    policy = draw(policies)
    horizon = simulate(s, policy=policy).makespan
    spare = s.n_agents - max((o.required for o in s.objects), default=1)
    ids = [a.id for a in s.agents]
    k = draw(st.integers(0 if spare < 1 else 1, max(spare, 0) + 1))
    dead = draw(st.permutations(ids))[: min(k, len(ids) - 1)]
    return s, policy, {a: draw(st.integers(0, horizon)) for a in dead}


# Every protocol of the registry that recovers, under each organisation it runs (CCP's
# coordinator organisation: the next coordinator is the lowest surviving id).
RECOVERING = [
    (spec.name, organisation)
    for spec in protocols.REGISTRY.values()
    if spec.capabilities.recovers_failures
    for organisation in spec.capabilities.organisations
]


@pytest.mark.parametrize("protocol, organisation", RECOVERING)
@settings(max_examples=120)
@given(run=failing_runs())
def test_failures_never_lose_an_object_the_survivors_can_carry(protocol, organisation, run):
    s, policy, failures = run
    policy = dataclasses.replace(policy, organisation=organisation)
    r = simulate(s, protocol, policy, failures=failures)
    survivors = s.n_agents - len(failures)
    assert not r.rejections and not r.warnings and r.agreement
    for o, spec in zip(r.objects, s.objects):
        if spec.required <= survivors:
            assert o.delivered is not None and len(o.agents) == spec.required
        # a group with a dead member delivered before it died
        if o.delivered is not None:
            assert all(o.delivered <= failures[a] for a in set(o.agents) & set(failures))
    assert r.completed == all(o.delivered is not None for o in r.objects)
    if not protocols.get(protocol).capabilities.team_knowledge:  # HCP: no shared schedule,
        return  # nothing predicted; its staffing decisions are agreed
    # planned = executed after the last recovery (none if the run ended before it closed)
    if r.predicted_makespan is not None:
        assert r.predicted_makespan == r.makespan
    else:
        assert max(failures.values()) >= r.makespan - 2


@settings(max_examples=40)
@given(failing_runs(), st.lists(st.integers(1, 3), min_size=6, max_size=6))
def test_failures_in_a_heterogeneous_team(run, periods):
    from ost_ros.model import AgentSpec

    s, policy, failures = run
    agents = [AgentSpec(a.id, a.base, periods[k]) for k, a in enumerate(s.agents)]
    s = build_scenario(s.grid, list(s.objects), partition=s.partition, agents=agents, nmax=s.nmax)
    r = simulate(s, policy=policy, failures=failures)
    survivors = s.n_agents - len(failures)
    assert not r.rejections and not r.warnings and r.agreement
    assert all(o.delivered is not None for o, spec in zip(r.objects, s.objects) if spec.required <= survivors)


def test_hcp_heir_takes_over_a_dead_owner_and_what_it_held():
    # Robot 2 dies at once: robot 0 (lowest id) inherits its subarea and finds its object there.
    s = build_scenario(Grid(9, 3), [ObjectSpec(0, (7, 1), (0, 0), 1)], n_agents=3, nmax=1)
    r = simulate(s, "hcp", failures={2: 0})
    assert r.completed and r.objects[0].agents == (0,)
    # Robot 1 dies while helping carry robot 0's object: robot 0 asks again, robot 2 comes.
    s = two_robot_carry()
    base = simulate(s, "hcp")
    g = base.objects[0]
    dead = next(a for a in g.agents if a != 0) if 0 in g.agents else g.agents[-1]
    r = simulate(s, "hcp", failures={dead: g.start + 2})
    assert r.completed and dead not in r.objects[0].agents and not r.warnings
