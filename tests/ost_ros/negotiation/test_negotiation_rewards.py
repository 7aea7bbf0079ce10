"""Private rewards and G against values computed by hand."""

import numpy as np
import pytest
import shapely
from shapely.geometry import box

from ost_ros.negotiation.rewards import AreaReward, TargetReward, global_coverage, ill_shape
from ost_ros.negotiation.tasks import AreaTask, TargetTask


def test_area_reward_section_4_1_by_hand():
    t = AreaTask(box(0, 0, 1, 1))
    s, other = box(0, 0, 0.5, 1), box(0.25, 0, 1, 1)
    # dim 0.5, out 0, overlap 0.25, ill = perimeter 3 / area 0.5 = 6
    g = AreaReward().value(t, s, [other])
    assert g == pytest.approx(0.5 - 0 - 2 * 0.25 - 0.2 * 6)
    assert ill_shape(s) == pytest.approx(6.0)


def test_area_outside_t0_is_penalised():
    t = AreaTask(box(0, 0, 1, 1))
    s = box(-0.5, 0, 0.5, 1)  # half outside
    r = AreaReward(w_ill=0.0)
    assert r.value(t, s, []) == pytest.approx(0.5 - 0.5)  # value inside − out
    literal = AreaReward(w_ill=0.0, value_inside=False)
    assert literal.value(t, s, []) == pytest.approx(1.0 - 0.5)  # dim(S) − dim(S \ T0)


def test_nfz_example_section_2_2_by_hand():
    """§2.2: α = β = γ = 1, λ = 1000, dim(NFZ) = 0.03 inside the share of size 0.259."""
    t0 = box(0, 0, 1, 0.668)
    s_small, s_big = box(0, 0, 0.259 / 0.668, 0.668), box(0.259 / 0.668, 0, 0.668 / 0.668, 0.668)
    nfz = box(0.05, 0.05, 0.05 + 0.15, 0.05 + 0.2)  # 0.03, inside s_small
    t = AreaTask(t0)
    r1 = AreaReward(w_overlap=1, w_ill=0)
    r2 = AreaReward(w_overlap=1, w_ill=0, forbidden=nfz, w_forbidden=1000)
    assert r1.value(t, s_small, [s_big]) == pytest.approx(0.259)  # paper: 0.26
    assert r1.value(t, s_big, [s_small]) == pytest.approx(0.409)  # paper: 0.41
    assert r2.value(t, s_big, [s_small]) == pytest.approx(0.409)  # paper: 0.41
    assert r2.value(t, s_small, [s_big]) == pytest.approx(0.259 - 30.0)  # paper prints −119.74
    assert r2.constraint_violation(s_small) == pytest.approx(0.03)
    assert global_coverage(t, [s_small, s_big]) == pytest.approx(0.668)


def test_batch_values_match_scalar_values():
    t = AreaTask(box(0, 0, 1, 1))
    others = [box(0.5, 0.5, 1.2, 1.0)]
    r = AreaReward(forbidden=box(0, 0, 0.1, 0.1))
    cands = [box(0, 0, 0.6, 0.6), box(0.3, 0.3, 1.1, 0.9), shapely.Polygon([(0, 0), (1, 1), (0, 1), (1, 0)])]
    batch = r.batch_values(t, np.array(cands, dtype=object), others)
    for c, v in zip(cands[:2], batch[:2]):
        assert v == pytest.approx(r.value(t, c, others))
    assert batch[2] == -np.inf  # self-intersecting candidate


def test_target_reward_by_hand():
    t = TargetTask.from_points([[0.5, 1.0], [0.5, 0.5], [1.0, 0.0]])
    mine, other = frozenset({0, 1, 2}), frozenset({2})
    assert TargetReward().value(t, mine, [other]) == pytest.approx(3 - 1)
    # §5.1 path term: start (0.5, 0) → (0.5, 0.5) → (0.5, 1): 1.0; best route over all three:
    # (1,0) first costs 0.5 + hypot(0.5,0.5) + 0.5
    with_path = TargetReward(w_path=1.0)
    assert with_path.value(t, frozenset({0, 1}), []) == pytest.approx(2 - 1.0)
    assert with_path.value(t, mine, []) == pytest.approx(3 - (0.5 + np.hypot(0.5, 0.5) + 0.5))
    assert TargetReward(forbidden=frozenset({1})).value(t, mine, []) == pytest.approx(3 - 1000)


def test_global_coverage_counts_pairwise_overlap_once():
    t = AreaTask(box(0, 0, 1, 1))
    shares = [box(0, 0, 0.6, 1), box(0.4, 0, 1, 1)]
    assert global_coverage(t, shares) == pytest.approx(0.6 + 0.6 - 0.2)
    tt = TargetTask.from_points([[0, 1], [1, 1], [1, 0]])
    assert global_coverage(tt, [frozenset({0, 1}), frozenset({1, 2})]) == pytest.approx(3.0)
