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
from .proposals import AreaSearch, drop_targets, propose_area, ring_coords
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


@dataclass
class AreaNegotiator:
    """Area negotiator: shrinking polygon claims, Rubinstein acceptance between two, exit
    option among more (see ``turn``)."""

    agent_id: int
    spec: AgentSpec
    task: AreaTask
    first: bool
    rng: np.random.Generator
    search: AreaSearch = field(default_factory=AreaSearch)
    exit_overlap: float = 0.02  # exit when own overlap ≤ this fraction of dim(T0)

    def __post_init__(self) -> None:
        reward = self.spec.reward or AreaReward()
        if not isinstance(reward, AreaReward):
            raise NegotiationError(f"agent {self.agent_id}: an area task needs an AreaReward")
        self.reward: AreaReward = reward
        self.state = ProtocolState(self.spec.delta, self.first)
        self.claim: Polygon = Polygon()
        self.prediction: float | None = None

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
        size = self.task.size
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
            # nobody left to bargain with: the rest is ours, except what our private
            # constraints forbid; if that is less than our claim, leave with the claim
            got = self.free_piece(others, region)
            if self.reward.forbidden is not None and self.reward.constraint_violation(got) > 0.0:
                got = hole_free(largest_polygon(got.difference(self.reward.forbidden)))
            if self.task.dim(got) >= self.task.dim(self.claim):
                self.claim = got
                return Decision("accept", got)
            return Decision("exit", self.claim)
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
    rule: str = "farthest"

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
        self.claim = drop_targets(self.task, self.reward, self.claim, cap, list(opponents), self.rule)
        return Decision("offer", self.claim)
