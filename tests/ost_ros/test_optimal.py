"""Optimal-OST: the pruned search finds exactly what plain enumeration of all object orders ×
agent groups finds; CCP is never better than it; on a scenario the CCP comparison is the
simulated CCP run; Table 1's orders of magnitude."""

import itertools

from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid, ObjectSpec, manhattan
from ost_ros.optimal import optimal_schedule, post_search_problem, search_space_order
from ost_ros.scenario import build_scenario, generate_objects


def brute_force(cost, loc, bases, objects):
    n, best = len(cost), None
    for perm in itertools.permutations(objects):
        groups = [list(itertools.combinations(range(n), o.required)) for o in perm]
        for choice in itertools.product(*groups):
            ca, where = list(cost), list(loc)
            for o, g in zip(perm, choice):
                start = max(ca[j] + manhattan(where[j], o.location) for j in g)
                for j in g:
                    ca[j], where[j] = start + manhattan(o.location, o.destination), o.destination
            c = max(ca[j] + manhattan(where[j], bases[j]) for j in range(n))
            best = c if best is None else min(best, c)
    return best


cells = st.tuples(st.integers(0, 9), st.integers(0, 9))


@st.composite
def problems(draw):
    n = draw(st.integers(1, 3))
    m = draw(st.integers(0, 5 if n < 3 else 4))
    cost = [draw(st.integers(0, 10)) for _ in range(n)]
    loc = [draw(cells) for _ in range(n)]
    bases = [draw(cells) for _ in range(n)]
    objs = []
    for i in range(m):
        a = draw(cells)
        b = draw(cells.filter(lambda c, a=a: c != a))
        objs.append(ObjectSpec(i, a, b, draw(st.integers(1, n))))
    return list(range(n)), cost, loc, bases, objs


@settings(max_examples=120)
@given(problems())
def test_pruned_search_equals_enumeration(problem):
    ids, cost, loc, bases, objs = problem
    r = optimal_schedule(ids, cost, loc, bases, objs)
    assert r.proven and r.cost == brute_force(cost, loc, bases, objs)
    assert r.ccp_cost >= r.cost and r.gap >= 0
    # The returned plan achieves the cost it claims.
    ca, where = list(cost), list(loc)
    spec = {o.id: o for o in objs}
    for s in r.plan:
        o = spec[s.object]
        idx = [ids.index(a) for a in s.agents]
        assert len(idx) == o.required
        assert s.start == max(ca[j] + manhattan(where[j], o.location) for j in idx)
        for j in idx:
            ca[j], where[j] = s.finish, o.destination
    assert sorted(s.object for s in r.plan) == sorted(spec)
    assert max(ca[j] + manhattan(where[j], bases[j]) for j in range(len(ids))) == r.cost


def test_ccp_comparison_is_the_simulated_after_search_run():
    grid = Grid(24, 9)
    s = build_scenario(grid, generate_objects(4, 11, grid, 3), n_agents=3, nmax=3)
    r = optimal_schedule(*post_search_problem(s))
    sim = simulate(s, "ccp", CoordinationPolicy(ci=5))
    assert r.proven and r.ccp_cost == sim.makespan and r.cost <= sim.makespan


def test_node_budget_reports_unproven():
    grid = Grid(40, 12)
    s = build_scenario(grid, generate_objects(7, 2, grid, 4), n_agents=4, nmax=4)
    r = optimal_schedule(*post_search_problem(s), max_nodes=50)
    assert not r.proven and r.cost <= r.ccp_cost


def test_table1_orders():
    assert [int(search_space_order(m, 10)) for m in (10, 20, 30, 40, 50, 100)] == [26, 58, 92, 128, 164, 358]
