"""The makespan lower bound: hand-computed terms on a tiny scenario, and never above any run's
makespan (every protocol of the registry, under every trigger kind it has) on random scenarios."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate_events
from ost_ros.model import Grid, ObjectSpec
from ost_ros.protocols import REGISTRY
from ost_ros.scenario import build_scenario, generate_scenario
from tests.strategies import scenarios


def test_hand_computed_terms():
    # 5x3, one agent sweeping row 1 from (0, 1) to (4, 1): L = 4, home 4 -> search term 8.
    # Object (2, 2) -> (2, 0): sensed first at index 1, reach 3, carry 2, home from (2, 0) 3:
    # object term max(1, 3) + 2 + 3 = 8. Work: 4 + 1*2 = 6.
    s = build_scenario(Grid(5, 3), [ObjectSpec(0, (2, 2), (2, 0), 1)], n_agents=1)
    b = lower_bound(s)
    assert (b.search, b.objects, b.work, b.value) == (8, 8, 6, 8)
    assert simulate_events(s, "ccp").makespan >= b.value


@settings(max_examples=150)
@given(scenarios(width=(4, 40), height=(3, 16), agents=(1, 8), objects=(0, 14)), st.integers(1, 15))
def test_bound_never_exceeds_a_run(scenario, ci):
    """Of any protocol of the registry, under each kind of trigger where it has triggers."""
    b = lower_bound(scenario).value
    for proto, spec in REGISTRY.items():
        triggered = (CoordinationPolicy(ci=ci), CoordinationPolicy(interval=ci))
        for policy in triggered if spec.capabilities.triggers else (CoordinationPolicy(),):
            assert simulate_events(scenario, proto, policy).makespan >= b


@pytest.mark.slow
def test_paper_sized_bound_is_valid_and_close():
    s = generate_scenario(10, 50, 3)
    b = lower_bound(s)
    ccp = simulate_events(s, "ccp", CoordinationPolicy(ci=50)).makespan
    assert b.value <= ccp and b.value > ccp / 4
