from hypothesis import given, settings, strategies as st
from ost_ros.engines import simulate, simulate_events
from ost_ros.coordination import CoordinationPolicy
from tests.strategies import scenarios
from tests.ost_ros.protocols.test_failures import failing_runs

@settings(max_examples=200, deadline=None)
@given(scenarios(agents=(1, 6), objects=(0, 8)))
def test_auction(s):
    r = simulate(s, "auction")
    assert r.completed and r.agreement and not r.rejections and not r.warnings, r.warnings
    assert r.predicted_makespan == r.makespan
    assert simulate_events(s, "auction").to_dict() == r.to_dict()

@settings(max_examples=200, deadline=None)
@given(run=failing_runs())
def test_auction_fail(run):
    s, policy, failures = run
    r = simulate(s, "auction", failures=failures)
    survivors = s.n_agents - len(failures)
    assert not r.rejections and not r.warnings and r.agreement, r.warnings
    for o, spec in zip(r.objects, s.objects):
        if spec.required <= survivors:
            assert o.delivered is not None and len(o.agents) == spec.required
    if r.predicted_makespan is not None:
        assert r.predicted_makespan == r.makespan

import dataclasses
@settings(max_examples=300, deadline=None)
@given(run=failing_runs())
def test_coord_fail(run):
    s, policy, failures = run
    policy = dataclasses.replace(policy, organisation="coordinator")
    r = simulate(s, "ccp", policy, failures=failures)
    survivors = s.n_agents - len(failures)
    assert not r.rejections and not r.warnings and r.agreement, r.warnings
    for o, spec in zip(r.objects, s.objects):
        if spec.required <= survivors:
            assert o.delivered is not None and len(o.agents) == spec.required
    if r.predicted_makespan is not None:
        assert r.predicted_makespan == r.makespan

@settings(max_examples=300, deadline=None)
@given(run=failing_runs())
def test_ncp_fail(run):
    s, policy, failures = run
    r = simulate(s, "ncp", policy, failures=failures)
    survivors = s.n_agents - len(failures)
    assert not r.rejections and not r.warnings and r.agreement, r.warnings
    for o, spec in zip(r.objects, s.objects):
        if spec.required <= survivors:
            assert o.delivered is not None and len(o.agents) == spec.required
    if r.predicted_makespan is not None:
        assert r.predicted_makespan == r.makespan
