"""Target offers (§4.2, §5.1): which contested points a robot drops, by a complete search."""

from itertools import combinations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.negotiation import proposals
from ost_ros.negotiation.errors import NegotiationError
from ost_ros.negotiation.optimal import EXACT_ROUTE, heuristic_route, route_length, subset_route_costs
from ost_ros.negotiation.proposals import search_target_offer
from ost_ros.negotiation.rewards import TargetReward
from ost_ros.negotiation.scenarios import MISSION_DELTAS, claim_schedule, mission_run, target_run
from ost_ros.negotiation.tasks import TargetTask

START = (0.5, 0.0)
# distances from START: 0.1, 0.2, 0.3, 0.4, 0.5 (point i at height 0.1·(i+1))
LINE = TargetTask.from_points([[0.5, 0.1 * (i + 1)] for i in range(5)])


def test_furthest_drops_the_furthest_contested_point_whatever_the_reward():
    """§4.2: "the offer update removes from the set the furthest one" — among the points someone
    else claims; the earlier rule (reward) would drop the point claimed by most partners first."""
    mine = frozenset(range(5))
    others = [frozenset({1, 3}), frozenset({1})]  # 1 is claimed twice, 3 once, 4 by nobody else
    got = search_target_offer(LINE, TargetReward(start=START), mine, 4, others, "furthest")
    assert got == mine - {3}
    got = search_target_offer(LINE, TargetReward(start=START), mine, 4, others, "reward")
    assert got == mine - {1}


def test_uncontested_points_are_never_dropped():
    mine = frozenset(range(5))
    got = search_target_offer(LINE, TargetReward(start=START), mine, 1, [frozenset({0})], "furthest")
    assert got == mine - {0}  # only 0 is contested: the claim stays above its cap


@settings(max_examples=30, deadline=None)
@given(st.integers(4, 8), st.integers(2, 3), st.integers(0, 10_000))
def test_path_rule_drop_set_is_jointly_optimal(n, k, seed):
    """The complete search ranks whole drop sets: the route left is the shortest over every set
    of k contested points (greedy one-at-a-time need not find it)."""
    rng = np.random.default_rng(seed)
    task = TargetTask.from_points(rng.random((n, 2)))
    mine = task.full()
    others = [frozenset(rng.choice(n, size=n - 1, replace=False).tolist())]
    got = search_target_offer(task, TargetReward(start=START), mine, n - k, others, "path")
    contested = sorted(mine & others[0])
    best = min(route_length(START, task.points[sorted(mine - set(d))]) for d in combinations(contested, k))
    assert route_length(START, task.points[sorted(got)]) == pytest.approx(best)
    assert len(got) == n - k and got >= mine - others[0]


def test_search_beyond_its_budget_drops_one_point_at_a_time(monkeypatch):
    monkeypatch.setattr(proposals, "SEARCH_BUDGET", 1)
    mine = frozenset(range(5))
    got = search_target_offer(LINE, TargetReward(start=START), mine, 2, [mine], "furthest")
    assert got == frozenset({0, 1})


def test_unknown_rule_is_refused():
    with pytest.raises(NegotiationError, match="unknown drop rule"):
        search_target_offer(LINE, TargetReward(), LINE.full(), 3, [], "nearest")


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 9), st.integers(0, 10_000))
def test_heuristic_route_is_a_valid_route(n, seed):
    """Never shorter than the exact shortest path; the two agree up to EXACT_ROUTE points."""
    rng = np.random.default_rng(seed)
    pts, start = rng.random((n, 2)), rng.random(2)
    exact = float(subset_route_costs(start, pts)[(1 << n) - 1])
    assert heuristic_route(start, pts) >= exact - 1e-9
    assert route_length(start, pts) == pytest.approx(exact)


def test_long_routes_use_the_heuristic():
    pts = np.random.default_rng(0).random((EXACT_ROUTE + 28, 2))
    assert route_length(START, pts) == pytest.approx(heuristic_route(START, pts))


def test_table4_readings():
    """excess_max_pct compares with the minimum-total optimum's longest route (may be negative);
    excess_minmax_pct with the min-max optimum (never negative)."""
    rows = [target_run(n, r, k) for r in (2, 3, 4) for n in (3, 5) for k in range(3)]
    assert all(x["excess_minmax_pct"] >= -1e-9 for x in rows)
    assert all(x["opt_total_max"] >= x["opt_max"] - 1e-12 for x in rows)
    assert any(x["excess_max_pct"] < 0 for x in rows)


def test_mission_swapping_delta2_and_delta3_changes_nothing():
    """§5.1's two δ settings give the same ⌊δ^t·5⌋ counts for as long as the negotiation runs,
    so the allocation cannot change (the report's finding)."""
    for layout in range(3):
        a, b = (mission_run(layout, d) for d in MISSION_DELTAS)
        assert a["status"] == b["status"] == "agreed"
        assert a["targets"] == b["targets"]
        offers = a["rounds"] + 1
        assert claim_schedule(0.877, 5, offers) == claim_schedule(0.867, 5, offers)
        assert sorted(j for s in a["targets"] for j in s) == list(range(5))
