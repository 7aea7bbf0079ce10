"""NCP: the slot negotiation's rules on hand-computed cases, and as properties on random runs —
never a deadlock, every object delivered by exactly n_i agents, every agent holds the same
schedule, planned = executed, the event engine equals the step engine; a silent negotiator is
timed out and the others conclude without it; a peer's illegal move is detected and ignored."""

import numpy as np
import pytest
from hypothesis import given, settings

from ost_ros.coordination import Assignment, CoordinationPolicy, order_groups
from ost_ros.engines import simulate, simulate_events
from ost_ros.engines.step import run_steps
from ost_ros.model import Grid, ObjectSpec, manhattan
from ost_ros.negotiation.messages import NegotiationOffer
from ost_ros.negotiation.slots import NegotiationSettings, SlotNegotiation, claim_cap, decide, protected
from ost_ros.protocols import make_agents
from ost_ros.protocols.ncp import SPEC as NCP
from ost_ros.scenario import build_scenario, generate_objects, generate_scenario
from tests.strategies import policies, scenarios


def test_claim_cap_shrinks_geometrically():
    assert [claim_cap(0.5, r, 8) for r in range(5)] == [8, 4, 2, 1, 0]
    assert claim_cap(0.8, 0, 1) == 1 and claim_cap(0.8, 1, 1) == 0


def test_protected_are_the_cheapest_claimers():
    # 3 agents, 2 objects. Object 0 needs 2: claimers 0, 1, 2 with costs 5, 3, 3 -> agents 1, 2
    # (tie 3/3 to the lower index). Object 1 needs 1: claimers 0, 2 (1 dropped) -> agent 2.
    claims = np.array([[1, 1], [1, 0], [1, 1]], dtype=bool)
    reach = np.array([[5, 3, 3], [9, 1, 4]])
    prot = protected(claims, reach, np.array([2, 1]), np.ones(3, dtype=bool))
    assert prot.tolist() == [[False, False], [True, False], [True, True]]
    # an agent that left the negotiation neither counts nor is protected
    alive = np.array([True, True, False])
    prot = protected(claims, reach, np.array([2, 1]), alive)
    assert prot.tolist() == [[True, True], [True, False], [False, False]]


def test_decide_drops_the_farthest_unprotected_contested_object():
    claims = np.ones((2, 3), dtype=bool)  # both claim all three (n_i = 1 each)
    reach = np.array([[1, 9], [2, 1], [5, 8]])  # C_ij: agent 0 is cheaper for 0 and 2
    need = np.array([1, 1, 1])
    alive = np.ones(2, dtype=bool)
    # agent 1, cap 1: contested unprotected = {0, 2}; farthest by its key drops first
    kind, row = decide(1, claims, alive, need, reach, np.array([9, 1, 8]), cap=1)
    assert kind == "offer" and row.tolist() == [False, True, False]
    # cap not binding: the claim stays
    kind, row = decide(1, claims, alive, need, reach, np.array([9, 1, 8]), cap=3)
    assert kind == "offer" and row.tolist() == [True, True, True]
    # nothing contested: exit with the claim
    claims = np.array([[1, 0, 1], [0, 1, 0]], dtype=bool)
    kind, row = decide(0, claims, alive, need, reach, np.zeros(3), cap=0)
    assert kind == "exit" and row.tolist() == [True, False, True]


def test_order_groups_hand_computed():
    # Two agents at (0,0) and (10,0), both free at 2. Object 0 at (4,0)->(4,3) by both:
    # M = max(2+4, 2+6) = 8, finish 11. Object 1 at (10,1)->(10,2) by agent 1 alone: M = 3,
    # so it goes first (finish 4); then object 0: agent 1 from (10,2) at 4 -> 4+8 = 12.
    objs = [ObjectSpec(0, (4, 0), (4, 3), 2), ObjectSpec(1, (10, 1), (10, 2), 1)]
    r = order_groups([0, 1], [2, 2], [(0, 0), (10, 0)], objs, {0: (0, 1), 1: (1,)})
    assert r.schedule == [Assignment(1, (1,), 3, 4), Assignment(0, (0, 1), 12, 15)]
    with pytest.raises(ValueError, match="object 0 needs 2"):
        order_groups([0, 1], [2, 2], [(0, 0), (10, 0)], objs, {0: (0,), 1: (1,)})


def test_settings_are_checked():
    for bad in (dict(delta=1.0), dict(delta=0), dict(timeout_rounds=0), dict(max_rounds=0)):
        with pytest.raises(ValueError):
            NegotiationSettings(**bad)


def check_run(scenario, result):
    assert result.completed, result.error
    assert result.rejections == [] and result.warnings == [] and result.agreement
    assert result.makespan == result.predicted_makespan  # planned = executed
    planned = {a.object: a for a in result.schedule}
    assert sorted(planned) == [o.id for o in scenario.objects]
    for rec, obj in zip(result.objects, scenario.objects):
        a = planned[obj.id]
        assert len(set(rec.agents)) == obj.required == len(a.agents)
        assert (rec.start, rec.delivered) == (a.start, a.finish)


@settings(max_examples=120, deadline=None)
@given(scenarios(agents=(1, 6), objects=(0, 9)), policies)
def test_ncp_never_deadlocks_and_delivers_everything(scenario, policy):
    trace = []
    result = simulate(
        scenario, "ncp", policy, on_step=lambda world, actions: trace.append(dict(world.positions))
    )
    check_run(scenario, result)
    start = {a.id: a.base for a in scenario.agents}
    for before, after in zip([start] + trace, trace):
        assert all(manhattan(before[i], after[i]) <= 1 for i in after)
    # the event engine is the same run, event for event
    ev = simulate_events(scenario, "ncp", policy)
    assert ev.to_dict() == result.to_dict() and ev.schedule == result.schedule


@pytest.mark.slow
def test_paper_sized_ncp_run_equals_event_engine():
    s = generate_scenario(10, 20, 7)
    for ci in (1, 20):
        a = simulate(s, "ncp", CoordinationPolicy(ci=ci))
        check_run(s, a)
        assert simulate_events(s, "ncp", CoordinationPolicy(ci=ci)).to_dict() == a.to_dict()


def run_agents(scenario, agents, policy):
    return run_steps(scenario, agents)


def test_silent_negotiator_is_timed_out_and_the_others_conclude():
    s = build_scenario(Grid(30, 12), generate_objects(8, 3, Grid(30, 12), 2), n_agents=4, nmax=2)
    policy = CoordinationPolicy(ci=3)
    agents = make_agents(s, "ncp", policy, NegotiationSettings(timeout_rounds=2))
    NCP.silence(agents[2], 0)
    r = run_agents(s, agents, policy)
    assert r.completed and r.agreement and r.rejections == []
    assert all(2 not in a.agents for a in r.schedule)  # it never got a slot
    assert any("agent(s) 2 silent for 2 rounds" in w for w in r.warnings)
    assert sorted(a.object for a in r.schedule) == [o.id for o in s.objects]


def test_illegal_move_is_detected_and_ignored():
    objs = [ObjectSpec(0, (1, 1), (2, 2), 1), ObjectSpec(1, (5, 1), (6, 2), 1)]
    reach = np.array([[1, 4], [6, 2]])
    neg = SlotNegotiation.open(1, objs, reach)
    st = NegotiationSettings()
    # round 0: agent 0 claims both; agent 1 claims object 7, which is not negotiated
    neg.apply(
        {
            0: NegotiationOffer(10, 0, 1, 0, "offer", (0, 1)),
            1: NegotiationOffer(11, 0, 1, 0, "offer", (0, 7)),
        },
        (10, 11),
        st,
    )
    assert neg.missing.tolist() == [0, 1] and "agent 11: malformed" in neg.notes[-1]
    # round 1: agent 0 drops object 0, for which it is protected (cheapest claimer)
    neg.apply(
        {0: NegotiationOffer(10, 1, 1, 1, "offer", (1,)), 1: NegotiationOffer(11, 1, 1, 1, "offer", (0, 1))},
        (10, 11),
        st,
    )
    assert "protected" in neg.notes[-1] and neg.claims[0].tolist() == [True, True]
    assert not neg.done
