"""Protocol level: Eq. 1–3, δ estimation and Rubinstein's closed form in one dimension."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.negotiation.errors import NegotiationError
from ost_ros.negotiation.protocol import (
    ProtocolState,
    alternating_offers_1d,
    claim_size,
    estimate_discount,
    predicted_share,
    rubinstein_share,
    validate_delta,
)


def test_rubinstein_share_hand_value():
    # Fig. 4: δ1 = 0.95, δ2 = 0.955 → (1 − 0.955) / (1 − 0.95·0.955) = 0.045 / 0.09275
    assert rubinstein_share(0.95, 0.955) == pytest.approx(0.045 / 0.09275, rel=1e-12)
    assert rubinstein_share(0.98, 0.98) == pytest.approx(1 / 1.98)


def test_claim_schedule_eq1():
    assert claim_size(0.9, 0) == 1.0
    assert claim_size(0.9, 3) == pytest.approx(0.729)
    assert claim_size(0.5, 2, p0=0.74) == pytest.approx(0.185)


@given(st.floats(0.01, 0.99), st.floats(0.01, 0.99))
def test_predictions_of_both_sides_add_up_to_one(d_own, d_opp):
    first = predicted_share(d_own, d_opp, first=True)
    second = predicted_share(d_opp, d_own, first=False)
    assert first == pytest.approx(rubinstein_share(d_own, d_opp))
    assert first + second == pytest.approx(1.0)


def test_estimate_discount_from_last_offers():
    assert estimate_discount([1.0, 0.9]) == pytest.approx(0.9)
    assert estimate_discount([1.0, 0.9, 0.81, 0.729]) == pytest.approx(0.9)
    assert estimate_discount([1.0, 0.5, 0.45], window=1) == pytest.approx(0.9)
    assert estimate_discount([1.0, 0.5, 0.25], window=2) == pytest.approx(0.5)
    assert estimate_discount([0.7]) is None  # one offer: nothing to compare
    assert estimate_discount([0.5, 0.5]) is None  # not shrinking: no estimate
    with pytest.raises(NegotiationError):
        estimate_discount([1, 0.9], window=0)


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.3, 1.5, float("nan"), "x", None])
def test_delta_outside_unit_interval_is_refused(bad):
    with pytest.raises(NegotiationError, match=r"discount factor|δ"):
        validate_delta(bad)
    with pytest.raises(ValueError):  # the library error is a ValueError
        ProtocolState(bad)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.99, 0.999), st.floats(0.99, 0.999))
def test_one_dimensional_shares_converge_to_rubinstein(d1, d2):
    """1-D alternating offers with δ-shrinking claims and Eq. 3 acceptance end within 1 % of
    Rubinstein's equilibrium share (Eq. 2) for the starter and the responder."""
    res = alternating_offers_1d(d1, d2)
    assert res.accepted_by in (0, 1)
    p = rubinstein_share(d1, d2)
    assert math.isclose(res.share_first, p, rel_tol=0.01)
    assert math.isclose(res.share_second, 1 - p, rel_tol=0.01)
    assert res.share_first + res.share_second == pytest.approx(1.0)


def test_more_patient_agent_gets_more():
    patient_first = alternating_offers_1d(0.995, 0.99)
    impatient_first = alternating_offers_1d(0.99, 0.995)
    assert patient_first.share_first > 0.5 > impatient_first.share_first


def test_time_out_reports_no_agreement():
    res = alternating_offers_1d(0.999, 0.999, max_periods=10)
    assert res.accepted_by == -1 and res.periods == 10 and math.isnan(res.share_first)
