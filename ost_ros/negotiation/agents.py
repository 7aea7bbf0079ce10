"""One negotiator: protocol state + private reward + proposal search, for one task type.

An agent only ever sees its partners' current claims (decoded from their messages) and
answers with a decision: a new offer, accepting the partner's offer (it then takes what the
others left), or leaving with its current claim (the exit option).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from shapely.geometry import Polygon

from .errors import NegotiationError
from .proposals import AreaSearch, propose_area, ring_coords, search_target_offer
from .protocol import ProtocolState, validate_delta
from .rewards import AreaReward, TargetReward
from .tasks import AreaTask, TargetTask, hole_free, largest_polygon


@dataclass(frozen=True)
class AgentSpec:
    """A robot in the negotiation: its discount factor and its private reward (None: the
    task type's default of §4)."""

    delta: float
    reward: AreaReward | TargetReward | None = None
    name: str = ""

    def __post_init__(self) -> None:
        validate_delta(self.delta, f"discount factor of {self.name or 'agent'}")


@dataclass(frozen=True)
class Decision:
    """What an agent does on its turn."""

    kind: str  # "offer" | "accept" | "exit"
    claim: object  # the agent's claim after this turn (geometry or index set)


STOPPING_RULES = ("paper", "overlap")


@dataclass
class AreaNegotiator:
    """Area negotiator: shrinking polygon claims; when to stop is ``stopping``:

    * ``paper`` (§3.2.1, §3.3): an agent is satisfied when the share the others leave it
      reaches its prediction p̂ (Eq. 3, δ̂ from the shrinking union of the *negotiating*
      partners' offers, both as fractions of the region still being negotiated); satisfied, it
      accepts (two left) or takes the exit option (more). Offers are the search's rings as they
      are — overlap and area outside T0 are whatever the protocol leaves.
    * ``overlap`` (this library's earlier rule, kept for the OST search areas): also accept or
      exit once the own claim overlaps the others' by at most ``exit_overlap`` of dim(T0);
      offers are clipped to the open region.
    """

    agent_id: int
    spec: AgentSpec
    task: AreaTask
    first: bool
    rng: np.random.Generator
    search: AreaSearch = field(default_factory=AreaSearch)
    exit_overlap: float = 0.02  # ``overlap`` rule: exit when own overlap ≤ this fraction of dim(T0)
    stopping: str = "paper"

    def __post_init__(self) -> None:
        reward = self.spec.reward or AreaReward()
        if not isinstance(reward, AreaReward):
            raise NegotiationError(f"agent {self.agent_id}: an area task needs an AreaReward")
        self.reward: AreaReward = reward
        if self.stopping not in STOPPING_RULES:
            raise NegotiationError(
                f"unknown stopping rule {self.stopping!r} (expected one of {', '.join(STOPPING_RULES)})"
            )
        self.state = ProtocolState(self.spec.delta, self.first)
        self.claim: Polygon = Polygon()
        self.prediction: float | None = None
        self.evaluated: float | None = None  # the share the others' offers leave it (paper rule)
        self._region_area = self.task.size

    def open_region(self, fixed: Sequence[Polygon]):
        """T0 minus the shares of agents that have left: what is still being negotiated."""
        return self.task.t0.difference(self.task.union(list(fixed))) if fixed else self.task.t0

    def free_piece(self, others: Sequence[Polygon], region) -> Polygon:
        """What this agent gets if it accepts the others' current offers: the piece of the
        open region nobody else claims that holds most of its own claim (the largest piece
        if it claims nothing there). Holes are cut away (offers are single rings), so the
        result intersects nobody's claim."""
        free = region.difference(self.task.union(list(others))) if others else region
        pieces = [free] if isinstance(free, Polygon) else list(getattr(free, "geoms", []))
        pieces = [p for p in pieces if isinstance(p, Polygon) and not p.is_empty]
        if not pieces:
            return Polygon()
        best = max(pieces, key=lambda p: (p.intersection(self.claim).area, p.area))
        return hole_free(best)

    def turn(
        self,
        others: Sequence[Polygon],
        opponents: Sequence[Polygon],
        bilateral: bool,
        alone: bool = False,
        fixed: Sequence[Polygon] = (),
    ) -> Decision:
        """One turn. others: every other agent's current claim (incl. those who left);
        opponents: the claims this turn answers (all others, or one in all-against-all);
        bilateral: exactly one partner still negotiating; alone: nobody else is; fixed: the
        shares of agents that left."""
        if self.state.offers_made == 0:  # opening: the biggest possible share, the whole task
            self.state.next_claim()
            self.claim = Polygon(ring_coords(self.task.t0, self.search.n_vertices))
            if self.reward.forbidden is not None and self.reward.constraint_violation(self.claim) > 0.0:
                # the biggest share *it can take*: the task minus its forbidden zone
                self.claim = hole_free(largest_polygon(self.task.t0.difference(self.reward.forbidden)))
            return Decision("offer", self.claim)
        region = self.open_region(fixed)
        if region.area <= 1e-12:
            # the others that left took everything: nothing to negotiate for
            self.claim = Polygon()
            return Decision("exit", self.claim)
        if alone:
            return self._alone(others, region)
        if self.stopping == "paper":
            return self._turn_paper(others, opponents, bilateral, fixed, region)
        return self._turn_overlap(others, opponents, bilateral, region)

    def _alone(self, others: Sequence[Polygon], region) -> Decision:
        """Nobody left to bargain with: the rest is ours, except what our private constraints
        forbid; if that is less than our claim, leave with the claim."""
        got = self.free_piece(others, region)
        if self.reward.forbidden is not None and self.reward.constraint_violation(got) > 0.0:
            got = hole_free(largest_polygon(got.difference(self.reward.forbidden)))
        if self.task.dim(got) >= self.task.dim(self.claim):
            self.claim = got
            return Decision("accept", got)
        return Decision("exit", self.claim)

    def _turn_paper(
        self,
        others: Sequence[Polygon],
        opponents: Sequence[Polygon],
        bilateral: bool,
        fixed: Sequence[Polygon],
        region,
    ) -> Decision:
        """§3.2.1/§3.3.1: satisfied when the evaluated share reaches p̂, all relative to the
        region still being negotiated; else the next offer, δ times the last (Eq. 1)."""
        open_area = float(region.area)
        if abs(open_area - self._region_area) > 1e-12:
            # someone left: the good is now the rest, and offers of the old good say nothing
            # about how fast the remaining partners concede on the new one
            self._region_area = open_area
            self.state.received.clear()
        # the offers still on the table: a departed agent's share (in ``fixed``, the very same
        # object as in ``opponents``) is no longer an offer
        live = [o for o in opponents if not any(o is f for f in fixed)]
        received = self.task.dim(self.task.union(list(live)).intersection(region)) / open_area
        if not self.state.received or abs(received - self.state.received[-1]) > 1e-12:
            self.state.observe(received)
        self.prediction = self.state.prediction()
        got = self.free_piece(others, region)
        self.evaluated = self.task.dim(got) / open_area
        if self.reward.constraint_violation(got) == 0.0 and self.state.accepts(self.evaluated):
            self.claim = got
            return Decision("accept" if bilateral else "exit", got)
        return self._offer_unclipped(others, region)

    def _offer_unclipped(self, others: Sequence[Polygon], region) -> Decision:
        """The next claim (Eq. 1) as the search's ring, not cut to the region."""
        size = self.task.size
        cap = min(self.state.next_claim() * size, float(region.area))
        self.claim = propose_area(
            self.task, self.reward, self.claim, cap, list(others), self.rng, self.search, region, False
        )
        self.state.record_claim(self.task.dim(self.task.inside(self.claim)) / size)
        return Decision("offer", self.claim)

    def _turn_overlap(
        self, others: Sequence[Polygon], opponents: Sequence[Polygon], bilateral: bool, region
    ) -> Decision:
        """The ``overlap`` rule: Rubinstein's test between two, plus leaving once the own claim
        hardly overlaps anyone's (offers clipped to the open region)."""
        size = self.task.size
        received = self.task.dim(self.task.inside(self.task.union(list(opponents)))) / size
        # Only a changed offer is news: with a rotating starter an agent may move twice in a
        # row, and re-reading the same offer would fake a discount factor of 1.
        if not self.state.received or abs(received - self.state.received[-1]) > 1e-12:
            self.state.observe(received)
        self.prediction = self.state.prediction()
        got = self.free_piece(others, region)
        own_overlap = sum(self.task.dim(self.task.overlap(self.claim, o)) for o in others)
        feasible = self.reward.constraint_violation(got) == 0.0
        if bilateral:
            # Rubinstein's test (§3.2.3) — or the claims no longer collide: accept the
            # partner's offer and take the rest (leaving would strand what it cannot take)
            if feasible and (
                self.state.accepts(self.task.dim(got) / size) or own_overlap <= self.exit_overlap * size
            ):
                self.claim = got
                return Decision("accept", got)
        elif own_overlap <= self.exit_overlap * size and feasible:
            # exit option (§3.3): take the free piece around our claim and leave
            self.claim = got
            return Decision("exit", got)
        cap = self.state.next_claim() * size
        self.claim = propose_area(
            self.task, self.reward, self.claim, cap, list(others), self.rng, self.search, region
        )
        self.state.record_claim(self.task.dim(self.claim) / size)
        return Decision("offer", self.claim)


@dataclass
class TargetNegotiator:
    """Target-point negotiator (§4.2): drops contested points as its claim shrinks and leaves
    as soon as its claim intersects nobody's."""

    agent_id: int
    spec: AgentSpec
    task: TargetTask
    first: bool
    rng: np.random.Generator
    rule: str = "furthest"

    def __post_init__(self) -> None:
        target_reward = self.spec.reward or TargetReward()
        if not isinstance(target_reward, TargetReward):
            raise NegotiationError(f"agent {self.agent_id}: a target task needs a TargetReward")
        self.reward: TargetReward = target_reward
        self.state = ProtocolState(self.spec.delta, self.first)
        self.claim: frozenset[int] = frozenset()
        self.prediction: float | None = None

    def turn(
        self,
        others: Sequence[frozenset[int]],
        opponents: Sequence[frozenset[int]],
        bilateral: bool,
        alone: bool = False,
        fixed: Sequence[frozenset[int]] = (),
    ) -> Decision:
        if self.state.offers_made == 0:
            self.state.next_claim()
            # the biggest share this robot can take: everything it is allowed to visit
            self.claim = frozenset(self.task.full() - self.reward.forbidden)
            return Decision("offer", self.claim)
        # §4.2: no discount-factor test; leave as soon as the claim intersects nobody's.
        if not (self.claim & self.task.union(list(others))):
            return Decision("exit", self.claim)
        # The claim drops by one point each time δ^t·N passes the next integer down (§4), so a
        # robot can end with no point at all when there are more robots than targets.
        cap = math.floor(self.state.next_claim() * self.task.n + 1e-9)
        self.claim = search_target_offer(self.task, self.reward, self.claim, cap, list(opponents), self.rule)
        return Decision("offer", self.claim)
