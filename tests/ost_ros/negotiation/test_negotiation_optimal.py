"""Exact target allocation against brute force on tiny cases."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.negotiation.errors import NegotiationError
from ost_ros.negotiation.optimal import (
    brute_force_allocation,
    optimal_allocation,
    route_length,
    subset_route_costs,
)


def test_route_length_collinear():
    # start (0,0), points on a line: best open path goes out once
    assert route_length((0, 0), np.array([[3, 0], [1, 0], [2, 0]])) == pytest.approx(3.0)
    assert route_length((0, 0), np.zeros((0, 2))) == 0.0
    c = subset_route_costs((0, 0), np.array([[1, 0], [-1, 0]]))
    assert list(c) == pytest.approx([0, 1, 1, 3])


@settings(max_examples=30, deadline=None)
@given(
    st.integers(1, 3),
    st.integers(1, 4),
    st.integers(0, 10_000),
    st.booleans(),
    st.sampled_from(["total", "max"]),
)
def test_branch_and_bound_equals_brute_force(robots, n, seed, same_start, objective):
    rng = np.random.default_rng(seed)
    pts = rng.random((n, 2))
    starts = [(0.5, 0.0)] * robots if same_start else rng.random((robots, 2))
    best = optimal_allocation(starts, pts, objective)
    value = best.total if objective == "total" else best.max_individual
    assert value == pytest.approx(brute_force_allocation(starts, pts, objective))
    # a partition of the targets
    assert sorted(j for s in best.shares for j in s) == list(range(n))


def test_min_max_spreads_the_work():
    pts = np.array([[0.0, 1.0], [1.0, 1.0]])
    total = optimal_allocation([(0.5, 0)] * 2, pts, "total")
    mx = optimal_allocation([(0.5, 0)] * 2, pts, "max")
    assert mx.max_individual < total.max_individual or len([s for s in total.shares if s]) == 2
    assert len([s for s in mx.shares if s]) == 2


def test_bad_solver_input():
    with pytest.raises(NegotiationError, match="at least one robot"):
        optimal_allocation([], [[0, 0]])
    with pytest.raises(NegotiationError, match="objective"):
        optimal_allocation([(0, 0)], [[0, 1]], "median")
