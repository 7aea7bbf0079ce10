"""Slot negotiation: the target-points protocol (§4.2) with targets that need several robots.

Each target (an OST object) is n_i *slots* at one place, and every robot claims slots. The moves of
a round are simultaneous (every active negotiator sends one offer per round, all read together),
which is what a lockstep team can do; the rules keep every target staffed:

- Round 0: every agent claims a slot of every target (its biggest possible share).
- Claim size (Eq. 1, :func:`~ost_ros.negotiation.protocol.claim_size`): the claim may hold at
  most ⌊δ^r · B⌋ targets in round r (B targets negotiated); an agent over its cap drops
  *contested* targets (claimed by more than n_i agents), the farthest first by its private reward
  — how much later than the target's n_i-th fastest claimer it would arrive (the paper's "drop
  the farthest point").
- Simultaneous drops must not strand a target: of a target's claimers, the n_i ranked first by
  (claim size, public cost C_ij, index) are *protected* and never drop it this round.
- Exit option (§3.3): an agent whose claim is contested nowhere leaves with it (kind ``exit``);
  when every agent has left, each target has exactly n_i claimers: the agreed groups.
- Time-out: an active agent that sends nothing valid for ``timeout_rounds`` rounds is dropped and
  the others start again without it (if they can still staff every target).

Every decision uses only public state (the offers received) plus the deciding agent's own reward,
so every agent's copy of :class:`SlotNegotiation` is the same, offer for offer; a move that breaks
the rules (a claim that grows, drops a protected target, leaves while contested) is logged and
treated as no answer. NCP (:mod:`ost_ros.protocols.ncp`) runs it over the OST's messages;
:func:`negotiate_slots` runs it standalone (``ost negotiate run --task slots``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ost_ros.messages import ObjectInfo
from ost_ros.model import Scenario, arrival_np
from ost_ros.negotiation.messages import NegotiationOffer

from .errors import NegotiationError
from .protocol import claim_size, validate_delta

_FAR = np.int64(1) << 60


@dataclass(frozen=True)
class NegotiationSettings:
    """NCP parameters, the same for every agent (they shape the public protocol)."""

    delta: float = 0.8  # claim discount per round (Eq. 1)
    timeout_rounds: int = 3  # rounds without an answer before an agent is dropped
    max_rounds: int = 200  # then the negotiation is closed by the protection rule

    def __post_init__(self) -> None:
        validate_delta(self.delta, "NCP discount factor")
        if self.timeout_rounds < 1:
            raise NegotiationError(f"NCP time-out must be at least 1 round, got {self.timeout_rounds}")
        if self.max_rounds < 1:
            raise NegotiationError(f"NCP max rounds must be at least 1, got {self.max_rounds}")


def claim_cap(delta: float, r: int, size: int) -> int:
    """Objects an agent may claim in round ``r``: ⌊δ^r · B⌋ (the whole batch in round 0)."""
    return math.floor(claim_size(delta, r, float(size)) + 1e-9)


def protected(claims: np.ndarray, reach: np.ndarray, need: np.ndarray, alive: np.ndarray) -> np.ndarray:
    """(N, B) mask: claimer j of object i is among the n_i claimers ranked first by (size of
    j's whole claim, C_ij, j) — the least loaded keep their slots, then the cheapest.

    ``claims`` (N, B) bool, ``reach`` (B, N) public costs C_ij, ``need`` (B,), ``alive`` (N,):
    agents still in the negotiation (a dropped agent's claims do not count).
    """
    n, b = claims.shape
    live = claims & alive[:, None]
    load = live.sum(axis=1).astype(np.int64)
    # one integer key: load first, then the reach (both far below 2**40 in any grid here)
    key = np.where(live, load[:, None] * (np.int64(1) << 40) + reach.T, _FAR)  # (N, B)
    order = np.argsort(key, axis=0, kind="stable")  # ties: the lower agent index
    rank = np.empty_like(order)
    rank[order, np.arange(b)[None, :]] = np.arange(n)[:, None]
    return live & (rank < need[None, :])


def decide(
    k: int,
    claims: np.ndarray,
    alive: np.ndarray,
    need: np.ndarray,
    reach: np.ndarray,
    drop_key: np.ndarray,
    cap: int,
    prot: np.ndarray | None = None,
    counts: np.ndarray | None = None,
) -> tuple[str, np.ndarray]:
    """Agent k's move in a round: ("exit", claim) if nothing it claims is contested, else
    ("offer", claim) after dropping the farthest unprotected contested objects down to ``cap``.

    ``drop_key`` (B,) is k's private reward term (larger = worse to keep); ``prot``: the
    :func:`protected` mask, ``counts`` the live claimers per object, if already computed for
    this round.
    """
    mine = claims[k]
    if counts is None:
        counts = (claims & alive[:, None]).sum(axis=0)
    contested = mine & (counts > need)
    if not contested.any():
        return "exit", mine.copy()
    excess = int(mine.sum()) - cap
    if excess <= 0:
        return "offer", mine.copy()
    if prot is None:
        prot = protected(claims, reach, need, alive)
    can = np.flatnonzero(contested & ~prot[k])
    if can.size == 0:
        return "offer", mine.copy()
    # farthest first; equal keys: the higher object index goes first (lower ids are kept)
    order = can[np.lexsort((-can, -drop_key[can]))]
    row = mine.copy()
    row[order[:excess]] = False
    return "offer", row


@dataclass
class SlotNegotiation:
    """The public state of one negotiation — identical in every agent's comm module."""

    number: int
    objects: tuple[int, ...]  # ascending object ids (column order)
    need: np.ndarray  # (B,) n_i
    reach: np.ndarray  # (B, N) C_ij at the start (public, as in CCP)
    carry: np.ndarray  # (B,) dist(l_i, d_i)
    claims: np.ndarray  # (N, B) bool: the last claim each agent announced
    alive: np.ndarray  # (N,) still in the negotiation (not timed out)
    exited: np.ndarray  # (N,) left with its claim
    missing: np.ndarray  # (N,) consecutive rounds without a valid answer
    round: int = 0  # the round whose moves are read next
    base: int = 0  # the round the current attempt opened in
    forced: bool = False  # closed by max_rounds, not by agreement
    notes: list[str] = field(default_factory=list)
    # Of the current round's claims, computed once (every agent's move reads them): protected(),
    # the live claimers per object, and each object's n_i-th smallest reach among them.
    _prot: np.ndarray | None = None
    _counts: np.ndarray | None = None
    _nth: np.ndarray | None = None
    _col: dict[int, int] | None = None  # object id → its column

    @classmethod
    def open(
        cls, number: int, objects: list, reach: np.ndarray, alive: np.ndarray | None = None
    ) -> SlotNegotiation:
        """Negotiation ``number`` of ``objects`` among the agents of ``alive`` (default: all)."""
        n, b = reach.shape[1], len(objects)
        return cls(
            number,
            tuple(o.id for o in objects),
            np.array([o.required for o in objects], dtype=np.int64),
            reach,
            np.array(
                [
                    abs(o.location[0] - o.destination[0]) + abs(o.location[1] - o.destination[1])
                    for o in objects
                ],
                dtype=np.int64,
            ),
            np.ones((n, b), dtype=bool),
            np.ones(n, dtype=bool) if alive is None else alive.copy(),
            np.zeros(n, dtype=bool),
            np.zeros(n, dtype=np.int64),
        )

    @property
    def active(self) -> np.ndarray:
        return self.alive & ~self.exited

    def cap(self, settings: NegotiationSettings) -> int:
        return claim_cap(settings.delta, self.round - self.base, len(self.objects))

    def move(self, k: int, settings: NegotiationSettings) -> tuple[str, np.ndarray]:
        """Agent k's move for round ``self.round`` (k's private reward: farthest from it)."""
        return decide(
            k,
            self.claims,
            self.alive,
            self.need,
            self.reach,
            self.drop_key(k),
            self.cap(settings),
            self.protected_now(),
            self.counts_now(),
        )

    def protected_now(self) -> np.ndarray:
        """:func:`protected` for the current claims (computed once per round)."""
        if self._prot is None:
            self._prot = protected(self.claims, self.reach, self.need, self.alive)
        return self._prot

    def counts_now(self) -> np.ndarray:
        """Live claimers per object for the current claims (computed once per round)."""
        if self._counts is None:
            self._counts = (self.claims & self.alive[:, None]).sum(axis=0)
        return self._counts

    def _new_claims(self) -> None:
        self._prot = self._counts = self._nth = None

    def drop_key(self, k: int) -> np.ndarray:
        """Agent k's private reward of keeping each object (larger = drop first): how much later
        than the object's n_i-th fastest claimer it would arrive — a slot where it would keep
        the group waiting costs the team most."""
        if self._nth is None:
            live = self.claims & self.alive[:, None]
            key = np.where(live.T, self.reach, _FAR)  # (B, N)
            self._nth = np.sort(key, axis=1)[np.arange(len(self.need)), self.need - 1]
        return self.reach[:, k] - self._nth

    def _check(
        self, k: int, msg: NegotiationOffer, agent_id: int, prot: np.ndarray, counts: np.ndarray
    ) -> np.ndarray | None:
        """The claim row of a valid move of agent k, else None (with a note saying why)."""
        if self._col is None:
            self._col = {oid: c for c, oid in enumerate(self.objects)}
        col = self._col
        if (
            msg.kind not in ("offer", "exit")
            or any(o not in col for o in msg.offer)
            or len(set(msg.offer)) != len(msg.offer)
        ):
            self.notes.append(
                f"agent {agent_id}: malformed move in negotiation {self.number} round {self.round}; ignored"
            )
            return None
        row = np.zeros(len(self.objects), dtype=bool)
        row[[col[o] for o in msg.offer]] = True
        prev = self.claims[k]
        prot = prot[k]
        why = None
        dropped = prev & ~row
        # ndarray.any(), not np.any(): this runs for every move of every round
        if (row & ~prev).any():
            why = "claims an object it had dropped"
        elif (dropped & prot).any():
            why = "dropped an object it must keep (protected)"
        elif (dropped & (counts <= self.need)).any():
            why = "dropped an uncontested object"
        elif msg.kind == "exit" and (row & (counts > self.need)).any():
            why = "left while its claim is contested"
        if why:
            self.notes.append(
                f"agent {agent_id}: move in negotiation {self.number} round {self.round} {why}; ignored"
            )
            return None
        return row

    def apply(
        self, moves: dict[int, NegotiationOffer], agent_ids: tuple[int, ...], settings: NegotiationSettings
    ) -> None:
        """Read the moves of round ``self.round`` (index → message), all at once."""
        expected = np.flatnonzero(self.active)
        new_claims = self.claims.copy()
        prot = self.protected_now()
        counts = self.counts_now()
        for k in expected:
            msg = moves.get(int(k))
            row = None if msg is None else self._check(int(k), msg, agent_ids[k], prot, counts)
            if row is None:
                self.missing[k] += 1
                continue
            self.missing[k] = 0
            new_claims[k] = row
            self.exited[k] = msg is not None and msg.kind == "exit"
        self.claims = new_claims
        self._new_claims()
        self.round += 1
        late = np.flatnonzero(self.active & (self.missing >= settings.timeout_rounds))
        if late.size:
            alive = self.alive.copy()
            alive[late] = False
            if alive.sum() >= self.need.max():
                # Conclude without them: the others open again, claiming everything.
                names = ", ".join(str(agent_ids[k]) for k in late)
                self.notes.append(
                    f"negotiation {self.number}: agent(s) {names} silent for "
                    f"{settings.timeout_rounds} rounds; going on without them"
                )
                self.alive = alive
                self.claims[:] = True
                self._new_claims()
                self.exited[:] = False
                self.missing[:] = 0
                self.base = self.round
        if self.round - self.base >= settings.max_rounds and self.active.any():
            self.forced = True
            self.notes.append(
                f"negotiation {self.number}: no agreement after "
                f"{settings.max_rounds} rounds; closed by the protection rule"
            )

    @property
    def done(self) -> bool:
        return self.forced or not self.active.any()

    def groups(self, agent_ids: tuple[int, ...]) -> dict[int, tuple[int, ...]]:
        """Object id → its agreed group (when forced: the protected claimers)."""
        owners = (
            protected(self.claims, self.reach, self.need, self.alive)
            if self.forced
            else self.claims & self.alive[:, None]
        )
        return {
            oid: tuple(agent_ids[k] for k in np.flatnonzero(owners[:, c]))
            for c, oid in enumerate(self.objects)
        }


def negotiate_slots(
    objects: Sequence[ObjectInfo],
    reach: np.ndarray,
    agent_ids: Sequence[int],
    settings: NegotiationSettings | None = None,
    silent: Mapping[int, int] | None = None,
) -> tuple[SlotNegotiation, int]:
    """Run one slot negotiation to its end, every agent moving by the rules each round; returns
    the final state (``groups``) and the number of moves sent. ``reach`` (B, N): the public cost
    C_ij of agent j reaching target i. ``silent``: agent id -> the round from which it sends
    nothing (fault injection). The same code NCP's comm modules run, one round per step."""
    settings = settings or NegotiationSettings()
    ids = tuple(agent_ids)
    if reach.shape != (len(objects), len(ids)):
        raise NegotiationError(f"reach must be {len(objects)} targets x {len(ids)} agents, got {reach.shape}")
    if objects and max(o.required for o in objects) > len(ids):
        raise NegotiationError("a target needs more robots than negotiate")
    neg = SlotNegotiation.open(1, list(objects), reach)
    sent = 0
    while not neg.done:
        moves = {}
        for k in np.flatnonzero(neg.active):
            if silent and neg.round >= silent.get(ids[k], neg.round + 1):
                continue
            kind, row = neg.move(int(k), settings)
            moves[int(k)] = NegotiationOffer(
                ids[k],
                neg.round,
                neg.number,
                neg.round,
                kind,
                tuple(neg.objects[c] for c in np.flatnonzero(row)),
            )
        sent += len(moves)
        neg.apply(moves, ids, settings)
    return neg, sent


def after_search(scenario: Scenario) -> tuple[list[ObjectInfo], np.ndarray, tuple[int, ...]]:
    """The negotiation NCP opens once every robot has searched (CI > M): every object, and each
    robot's public cost C_ij of reaching it from the end of its sweep, free the step after the
    last search ends. Returns (objects, reach (B, N), agent ids)."""
    from ost_ros.team import TeamInfo

    team = TeamInfo.from_scenario(scenario)
    close = int(team.sweep_lengths().max())
    where = np.array([o.location for o in scenario.objects], dtype=np.int64).reshape(-1, 2)
    ends = team.sweep_ends()
    dist = np.abs(where[:, None, :] - ends[None, :, :]).sum(axis=2)
    reach = arrival_np(
        np.full(team.size, close + 1, dtype=np.int64)[None, :], dist, team.period_array()[None, :]
    )
    return list(scenario.objects), reach, team.agent_ids
