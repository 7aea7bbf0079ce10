"""Protocol level (§3.1, §3.2.1): Rubinstein's alternating offers.

Pure functions for the paper's formulas (Eq. 1–3, as reconstructed in the seeds README) and
a small per-agent state machine: the claim schedule, the estimate of the opponent's discount
factor from the offers received, the predicted share and the acceptance test. A 1-D
reference negotiation (``alternating_offers_1d``) checks the machinery against the closed form.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from .errors import NegotiationError


def validate_delta(delta: float, name: str = "discount factor") -> float:
    """δ must lie strictly between 0 and 1 (a claim that never shrinks never terminates)."""
    try:
        d = float(delta)
    except (TypeError, ValueError):
        raise NegotiationError(f"{name} must be a number, got {delta!r}") from None
    if not 0.0 < d < 1.0:
        raise NegotiationError(f"{name} must be in (0, 1), got {d:g}")
    return d


def claim_size(delta: float, t: int, p0: float = 1.0) -> float:
    """Eq. 1: p_t = δ^t · p0 — the claim after t own offers, starting from the whole (p0 = 1)."""
    return p0 * validate_delta(delta) ** t


def rubinstein_share(delta_first: float, delta_second: float) -> float:
    """Eq. 2: the first proposer's equilibrium share (1 − δ2) / (1 − δ1·δ2)."""
    d1, d2 = validate_delta(delta_first, "δ1"), validate_delta(delta_second, "δ2")
    return (1.0 - d2) / (1.0 - d1 * d2)


def predicted_share(delta_own: float, delta_opp_hat: float, first: bool = True) -> float:
    """Eq. 3: p̂ = (1 − δ̂_opp) / (1 − δ_own·δ̂_opp) for the first proposer.

    The responder's prediction is the complement of the proposer's equilibrium share,
    δ_own·(1 − δ̂_opp)/(1 − δ_own·δ̂_opp), so the two predictions add up to 1.
    """
    d = validate_delta(delta_own, "own δ")
    e = validate_delta(delta_opp_hat, "estimated opponent δ")
    p = (1.0 - e) / (1.0 - d * e)
    return p if first else d * p


def estimate_discount(sizes: Sequence[float], window: int = 1) -> float | None:
    """δ̂ from the sizes of the offers received, oldest first: the ratio of the last two
    (§3.2.1), or the geometric mean of the last ``window`` ratios. None while there is no
    usable estimate (fewer than two offers, or the offers did not shrink)."""
    if window < 1:
        raise NegotiationError("estimation window must be at least 1")
    s = [float(x) for x in sizes]
    if len(s) < 2:
        return None
    s = s[-(window + 1) :]
    if s[0] <= 0 or s[-1] <= 0:
        return None
    ratio = (s[-1] / s[0]) ** (1.0 / (len(s) - 1))
    return ratio if 0.0 < ratio < 1.0 else None


@dataclass
class ProtocolState:
    """One agent's protocol bookkeeping (private: δ is never sent)."""

    delta: float
    first: bool = True
    window: int = 1
    claim: float = 1.0  # current claimed fraction of the task (Eq. 1)
    offers_made: int = 0
    received: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.delta = validate_delta(self.delta)

    def next_claim(self) -> float:
        """The cap for the next own offer: the whole task first, then δ times the last claim."""
        if self.offers_made > 0:
            self.claim *= self.delta
        self.offers_made += 1
        return self.claim

    def record_claim(self, actual: float) -> None:
        """The search may offer less than the cap (§3.2.1: the size rule is not guaranteed)."""
        self.claim = min(self.claim, actual)

    def observe(self, size: float) -> None:
        """Size (fraction of the task) of the opponent's offer just received."""
        self.received.append(float(size))

    @property
    def delta_hat(self) -> float | None:
        return estimate_discount(self.received, self.window)

    def prediction(self) -> float | None:
        e = self.delta_hat
        return None if e is None else predicted_share(self.delta, e, self.first)

    def accepts(self, share: float) -> bool:
        """Accept when the evaluated share reaches the predicted one (§3.2.3)."""
        p = self.prediction()
        return p is not None and share >= p - 1e-12


@dataclass(frozen=True)
class OneDResult:
    """Outcome of a 1-D alternating-offers negotiation."""

    share_first: float
    share_second: float
    accepted_by: int  # 0 = starter, 1 = responder, -1 = time-out
    periods: int
    prediction_first: float  # Eq. 2 with the true δs
    trace: tuple[tuple[int, int, float], ...]  # (period, proposer, claim)


def alternating_offers_1d(
    delta_first: float, delta_second: float, max_periods: int = 100_000, window: int = 1
) -> OneDResult:
    """Two agents split a good of size 1. Each claims the whole at first and shrinks its claim
    by its δ at each own offer; the receiver accepts when 1 − claim reaches its prediction."""
    states = [ProtocolState(delta_first, True, window), ProtocolState(delta_second, False, window)]
    trace = []
    for t in range(max_periods):
        proposer, responder = t % 2, 1 - t % 2
        claim = states[proposer].next_claim()
        trace.append((t, proposer, claim))
        states[responder].observe(claim)
        if states[responder].accepts(1.0 - claim):
            shares = [0.0, 0.0]
            shares[proposer], shares[responder] = claim, 1.0 - claim
            return OneDResult(
                shares[0],
                shares[1],
                responder,
                t + 1,
                rubinstein_share(delta_first, delta_second),
                tuple(trace),
            )
    return OneDResult(
        float("nan"), float("nan"), -1, max_periods, rubinstein_share(delta_first, delta_second), tuple(trace)
    )
