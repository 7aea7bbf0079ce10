"""The reference simulator: a hand-computed run, and the paper's promises as properties on random
small scenarios (every object delivered once by n_i agents at once, one cell per step, no
deadlock, planned = executed)."""

from hypothesis import given, settings

from ost_ros.coordination import Assignment, CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid, ObjectSpec, manhattan
from ost_ros.scenario import build_scenario, generate_objects
from tests.strategies import policies, scenarios


def one_agent_scenario():
    # 5x3 grid, one pass along row 1 from (0, 1) to (4, 1): the search takes 4 steps.
    return build_scenario(Grid(5, 3), [ObjectSpec(0, (2, 2), (2, 0), 1)], n_agents=1)


def test_hand_computed_run_ci1():
    # Found at t=1 (sensed from (1, 1)). Coordinated in step 1: CA = max(1+1, search end 4) = 4
    # at (4, 1); C = 4 + 3 = 7 -> carry 7..9. Back at base (0, 1) at 9 + 3 = 12.
    r = simulate(one_agent_scenario(), policy=CoordinationPolicy(ci=1))
    assert r.found == {0: 1}
    assert r.schedule == [Assignment(0, (0,), 7, 9)]
    assert (r.makespan, r.predicted_makespan, r.last_delivery) == (12, 12, 9)
    a = r.agents[0]
    assert (a.cost, a.search, a.travel, a.carry, a.idle) == (12, 4, 6, 2, 0)
    assert r.objects[0].to_dict() == {"id": 0, "agents": [0], "start": 7, "delivered": 9}


def test_hand_computed_run_after_whole_search():
    # CI=5 > M: coordinated when the search ends (step 4), so CA = 5: carry 8..10, home at 13.
    r = simulate(one_agent_scenario(), policy=CoordinationPolicy(ci=5))
    assert r.schedule == [Assignment(0, (0,), 8, 10)]
    assert (r.makespan, r.predicted_makespan) == (13, 13)
    assert r.agents[0].idle == 1


def test_no_objects_everyone_searches_and_returns():
    s = build_scenario(Grid(12, 6), [], n_agents=2)
    r = simulate(s)
    assert r.completed and r.makespan == r.predicted_makespan and r.last_delivery == 0


@settings(max_examples=150)
@given(scenarios(), policies)
def test_paper_promises_hold(scenario, policy):
    trace = []
    result = simulate(
        scenario, policy=policy, on_step=lambda world, actions: trace.append(dict(world.positions))
    )
    # No deadlock, nothing illegal, every agent agrees on the schedule.
    assert result.completed, result.error
    assert result.rejections == [] and result.warnings == [] and result.agreement
    # No agent ever moves more than one cell per step.
    start = {a.id: a.base for a in scenario.agents}
    for before, after in zip([start] + trace, trace):
        assert all(manhattan(before[i], after[i]) <= 1 for i in after)
    # Every agent ends at its base.
    assert trace == [] or all(trace[-1][a.id] == a.base for a in scenario.agents)
    # Every object delivered exactly once, by exactly n_i agents at once, as planned.
    planned = {a.object: a for a in result.schedule}
    assert sorted(planned) == [o.id for o in scenario.objects]
    for o, rec in zip(scenario.objects, result.objects):
        assert rec.id == o.id and len(rec.agents) == o.required
        assert rec.agents == planned[o.id].agents
        assert (rec.start, rec.delivered) == (planned[o.id].start, planned[o.id].finish)
        assert rec.delivered - rec.start == manhattan(o.location, o.destination)
    # Planned = executed for the whole run.
    assert result.makespan == result.predicted_makespan


def test_deterministic():
    s = build_scenario(Grid(30, 12), generate_objects(8, 5, Grid(30, 12), 3), n_agents=3, nmax=3)
    assert simulate(s).to_dict() == simulate(s).to_dict()


def test_step_limit_reports_incomplete():
    s = build_scenario(Grid(30, 12), generate_objects(4, 5, Grid(30, 12), 2), n_agents=2, nmax=2)
    r = simulate(s, max_steps=10)
    assert not r.completed and r.makespan is None and "not finished after 10 steps" in r.error
