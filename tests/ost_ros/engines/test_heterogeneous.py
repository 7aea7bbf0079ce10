"""Heterogeneous teams (agents of period k move one cell every k steps): the paper's promises
still hold for every protocol of the registry that runs them (CCP, NCP, ...) — no deadlock,
nothing illegal, planned = executed — and the event engine is the same run as the step engine;
HCP refuses such a team with a clear error."""

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy, coordinate
from ost_ros.engines import simulate, simulate_events
from ost_ros.model import AgentSpec, Grid, ObjectSpec, arrival, can_move, group_period
from ost_ros.protocols import REGISTRY
from ost_ros.scenario import (
    ScenarioError,
    build_scenario,
    dump_scenario,
    generate_objects,
    scenario_from_dict,
    scenario_to_dict,
)
from tests.strategies import policies, scenarios


def test_arrival_and_group_period():
    assert [arrival(0, d, 1) for d in (0, 1, 5)] == [0, 1, 5]
    # period 3 from t0 = 4: moves in steps 6, 9 -> done at 10
    assert arrival(4, 2, 3) == 10 and arrival(6, 1, 3) == 7 and arrival(4, 0, 3) == 4
    assert group_period([2, 3]) == 6 and group_period([1, 1]) == 1
    assert can_move(6, 3) and not can_move(7, 3)


def test_hand_computed_slow_agent():
    # One agent of period 2 on a 5x3 grid: the sweep (0,1)->(4,1) is 4 moves in steps
    # 0, 2, 4, 6 -> search ends at 7. The object at (2,2) is sensed from (1,1), reached by the
    # move of step 0, at t = 1. CI=1: coordinated in step 1, CA = max(2, 7) = 7 at (4,1): 3 moves (steps 8, 10,
    # 12) -> at (2,2) at 13; carry 2 cells to (2,0) in steps 14, 16 -> delivered 17; home
    # (0,1) is 3 moves: steps 18, 20, 22 -> 23.
    s = build_scenario(Grid(5, 3), [ObjectSpec(0, (2, 2), (2, 0), 1)], agents=[AgentSpec(0, (0, 1), 2)])
    r = simulate(s, policy=CoordinationPolicy(ci=1))
    assert r.completed and r.rejections == []
    assert r.found == {0: 1}
    assert (r.schedule[0].start, r.schedule[0].finish) == (14, 17)
    assert (r.makespan, r.predicted_makespan) == (23, 23)
    a = r.agents[0]
    assert (a.search, a.travel, a.carry) == (4, 6, 2) and a.idle == 23 - 12
    assert simulate_events(s, "ccp", CoordinationPolicy(ci=1)).to_dict() == r.to_dict()


@st.composite
def hetero(draw):
    s = draw(scenarios(agents=(1, 6), objects=(0, 8)))
    periods = [draw(st.sampled_from([1, 1, 2, 3])) for _ in s.agents]
    agents = [dataclasses.replace(a, period=k) for a, k in zip(s.agents, periods)]
    return build_scenario(s.grid, s.objects, partition=s.partition, agents=agents, nmax=s.nmax)


# every protocol of the registry that runs robots of unequal speeds
UNEQUAL = [n for n, spec in REGISTRY.items() if spec.capabilities.heterogeneous]


@settings(max_examples=150, deadline=None)
@given(hetero(), policies, st.sampled_from(UNEQUAL))
def test_heterogeneous_runs_keep_the_promises(scenario, policy, protocol):
    r = simulate(scenario, protocol, policy)
    assert r.completed, r.error
    assert r.rejections == [] and r.warnings == [] and r.agreement
    assert r.makespan == r.predicted_makespan
    planned = {a.object: a for a in r.schedule}
    for rec in r.objects:
        assert (rec.start, rec.delivered) == (planned[rec.id].start, planned[rec.id].finish)
    ev = simulate_events(scenario, protocol, policy)
    assert ev.to_dict() == r.to_dict()
    assert r.makespan >= lower_bound(scenario).value  # the unit-speed bound stays valid


def test_slower_team_is_slower_and_coordination_knows_it():
    objs = generate_objects(6, 3, Grid(30, 12), 2)
    fast = build_scenario(Grid(30, 12), objs, n_agents=4, nmax=2)
    slow = build_scenario(
        Grid(30, 12), objs, nmax=2, agents=[dataclasses.replace(a, period=2) for a in fast.agents]
    )
    assert simulate(slow).makespan > simulate(fast).makespan
    # period 3, 2 cells away (moves in steps 0, 3: there at 4) loses to unit speed, 3 cells away
    # (there at 3); at unit speed for both it would win
    o = ObjectSpec(0, (5, 0), (6, 0), 1)
    r = coordinate([0, 1], [0, 0], [(3, 0), (2, 0)], [o], periods=[3, 1])
    assert coordinate([0, 1], [0, 0], [(3, 0), (2, 0)], [o]).schedule[0].agents == (0,)
    assert r.schedule[0].agents == (1,)


def test_period_in_files_and_errors():
    s = build_scenario(Grid(10, 6), [], agents=[AgentSpec(0, (0, 1), 3), AgentSpec(1, (5, 1))])
    again = scenario_from_dict(scenario_to_dict(s))
    assert again.periods == (3, 1) and "period: 3" in dump_scenario(s)
    d = scenario_to_dict(s)
    d["agents"][0]["period"] = 0
    with pytest.raises(ScenarioError, match=r"agents\[0\].period"):
        scenario_from_dict(d)
    with pytest.raises(ValueError, match="hcp runs unit-speed teams only"):
        simulate(s, "hcp")
