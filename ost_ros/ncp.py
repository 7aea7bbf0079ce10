"""NCP: the negotiation-based cooperation protocol — object allocation by the target-points
negotiation of Rossi et al. (§4.2) inside the Object-Sorting Task.

At a coordination point (the same triggers as CCP) the found, unscheduled objects are not
scheduled by Algorithm Coordination but *negotiated*: an object that needs n_i agents is n_i
carrying slots at one place, and every agent claims slots.

- Round 0: every agent opens by claiming a slot of every object (its biggest possible share).
- Each round every active agent sends one :class:`NegotiationOffer` (its claim) to everyone;
  all moves of a round are simultaneous and are read one step later, so a round is one step.
- Claim size (Eq. 1, the §4 target rule): the claim may hold at most ⌊δ^r · B⌋ objects in round
  r (B objects negotiated); an agent over its cap drops *contested* objects (claimed by more than
  n_i agents), the farthest first by its private reward — how far the object is from where its
  current commitments leave it, plus the carry (the paper's "drop the farthest point").
- Simultaneous drops must not strand an object: of an object's claimers, the n_i that could
  reach it first (public cost C_ij = CA_j + dist, as in CCP; ties: lower agent index) are
  *protected* and never drop it this round. So every object keeps ≥ n_i claimers.
- Exit option (§3.3): an agent whose claim is contested nowhere leaves with it (kind ``exit``).
  When every agent has left, each object has exactly n_i claimers: the agreed groups.
- Time-out: an active agent that sends nothing for ``timeout_rounds`` rounds is dropped from the
  negotiation and the others start it again without it (if they can still staff every object).
- The groups are then ordered by :func:`~ost_ros.coordination.order_groups` (one global order,
  CA/loc updated as in CCP) and executed exactly like a CCP schedule.

Every decision uses only public state (the offers received) plus the deciding agent's own
reward, so every agent's copy of the negotiation state is the same, offer for offer; an offer
that breaks the rules (a claim that grows, drops a protected object, leaves while contested)
is logged and treated as no answer.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ost_msgs_py.messages import NegotiationOffer, ObjectFound, SearchDone, Selection
from ost_ros.agent import CcpAgent
from ost_ros.comm import CcpComm, CommState
from ost_ros.coordination import CoordinationPolicy, order_groups
from ost_ros.model import arrival_np
from ost_ros.negotiation.protocol import claim_size, validate_delta
from ost_ros.team import TeamInfo

_FAR = np.int64(1) << 60


@dataclass(frozen=True)
class NegotiationSettings:
    """NCP parameters, the same for every agent (they shape the public protocol)."""

    delta: float = 0.8          # claim discount per round (Eq. 1)
    timeout_rounds: int = 3     # rounds without an answer before an agent is dropped
    max_rounds: int = 200       # then the negotiation is closed by the protection rule

    def __post_init__(self) -> None:
        validate_delta(self.delta, "NCP discount factor")
        if self.timeout_rounds < 1:
            raise ValueError(f"NCP time-out must be at least 1 round, got {self.timeout_rounds}")
        if self.max_rounds < 1:
            raise ValueError(f"NCP max rounds must be at least 1, got {self.max_rounds}")


def claim_cap(delta: float, r: int, size: int) -> int:
    """Objects an agent may claim in round ``r``: ⌊δ^r · B⌋ (the whole batch in round 0)."""
    return int(math.floor(claim_size(delta, r, float(size)) + 1e-9))


def protected(claims: np.ndarray, reach: np.ndarray, need: np.ndarray,
              alive: np.ndarray) -> np.ndarray:
    """(N, B) mask: claimer j of object i is among the n_i claimers ranked first by (size of
    j's whole claim, C_ij, j) — the least loaded keep their slots, then the cheapest.

    ``claims`` (N, B) bool, ``reach`` (B, N) public costs C_ij, ``need`` (B,), ``alive`` (N,):
    agents still in the negotiation (a dropped agent's claims do not count).
    """
    n, b = claims.shape
    live = claims & alive[:, None]
    load = live.sum(axis=1).astype(np.int64)
    # one integer key: load first, then the reach (both far below 2**40 in any grid here)
    key = np.where(live, load[:, None] * (np.int64(1) << 40) + reach.T, _FAR)   # (N, B)
    order = np.argsort(key, axis=0, kind="stable")            # ties: the lower agent index
    rank = np.empty_like(order)
    rank[order, np.arange(b)[None, :]] = np.arange(n)[:, None]
    return live & (rank < need[None, :])


def decide(k: int, claims: np.ndarray, alive: np.ndarray, need: np.ndarray, reach: np.ndarray,
           drop_key: np.ndarray, cap: int, prot: np.ndarray | None = None) -> tuple[str, np.ndarray]:
    """Agent k's move in a round: ("exit", claim) if nothing it claims is contested, else
    ("offer", claim) after dropping the farthest unprotected contested objects down to ``cap``.

    ``drop_key`` (B,) is k's private reward term (larger = worse to keep); ``prot``: the
    :func:`protected` mask if already computed for this round.
    """
    mine = claims[k]
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
    objects: tuple[int, ...]           # ascending object ids (column order)
    need: np.ndarray                   # (B,) n_i
    reach: np.ndarray                  # (B, N) C_ij at the start (public, as in CCP)
    carry: np.ndarray                  # (B,) dist(l_i, d_i)
    claims: np.ndarray                 # (N, B) bool: the last claim each agent announced
    alive: np.ndarray                  # (N,) still in the negotiation (not timed out)
    exited: np.ndarray                 # (N,) left with its claim
    missing: np.ndarray                # (N,) consecutive rounds without a valid answer
    round: int = 0                     # the round whose moves are read next
    base: int = 0                      # the round the current attempt opened in
    forced: bool = False               # closed by max_rounds, not by agreement
    notes: list[str] = field(default_factory=list)
    _prot: np.ndarray | None = None    # protected() of the current round, once computed

    @classmethod
    def open(cls, number: int, objects: list, reach: np.ndarray) -> "SlotNegotiation":
        n, b = reach.shape[1], len(objects)
        return cls(number, tuple(o.id for o in objects),
                   np.array([o.required for o in objects], dtype=np.int64), reach,
                   np.array([abs(o.location[0] - o.destination[0]) + abs(o.location[1] - o.destination[1])
                             for o in objects], dtype=np.int64),
                   np.ones((n, b), dtype=bool), np.ones(n, dtype=bool), np.zeros(n, dtype=bool),
                   np.zeros(n, dtype=np.int64))

    @property
    def active(self) -> np.ndarray:
        return self.alive & ~self.exited

    def cap(self, settings: NegotiationSettings) -> int:
        return claim_cap(settings.delta, self.round - self.base, len(self.objects))

    def move(self, k: int, settings: NegotiationSettings) -> tuple[str, np.ndarray]:
        """Agent k's move for round ``self.round`` (k's private reward: farthest from it)."""
        return decide(k, self.claims, self.alive, self.need, self.reach,
                      self.drop_key(k), self.cap(settings), self.protected_now())

    def protected_now(self) -> np.ndarray:
        """:func:`protected` for the current claims (computed once per round)."""
        if self._prot is None:
            self._prot = protected(self.claims, self.reach, self.need, self.alive)
        return self._prot

    def drop_key(self, k: int) -> np.ndarray:
        """Agent k's private reward of keeping each object (larger = drop first): how much later
        than the object's n_i-th fastest claimer it would arrive — a slot where it would keep
        the group waiting costs the team most."""
        live = self.claims & self.alive[:, None]
        key = np.where(live.T, self.reach, _FAR)                      # (B, N)
        nth = np.sort(key, axis=1)[np.arange(len(self.need)), self.need - 1]
        return self.reach[:, k] - nth

    def _check(self, k: int, msg: NegotiationOffer, agent_id: int, prot: np.ndarray,
               counts: np.ndarray) -> np.ndarray | None:
        """The claim row of a valid move of agent k, else None (with a note saying why)."""
        col = {oid: c for c, oid in enumerate(self.objects)}
        if msg.kind not in ("offer", "exit") or any(o not in col for o in msg.offer) \
                or len(set(msg.offer)) != len(msg.offer):
            self.notes.append(f"agent {agent_id}: malformed move in negotiation {self.number} "
                              f"round {self.round}; ignored")
            return None
        row = np.zeros(len(self.objects), dtype=bool)
        row[[col[o] for o in msg.offer]] = True
        prev = self.claims[k]
        prot = prot[k]
        why = None
        if np.any(row & ~prev):
            why = "claims an object it had dropped"
        elif np.any(prev & prot & ~row):
            why = "dropped an object it must keep (protected)"
        elif np.any(prev & ~row & (counts <= self.need)):
            why = "dropped an uncontested object"
        elif msg.kind == "exit" and np.any(row & (counts > self.need)):
            why = "left while its claim is contested"
        if why:
            self.notes.append(f"agent {agent_id}: move in negotiation {self.number} round "
                              f"{self.round} {why}; ignored")
            return None
        return row

    def apply(self, moves: dict[int, NegotiationOffer], agent_ids: tuple[int, ...],
              settings: NegotiationSettings) -> None:
        """Read the moves of round ``self.round`` (index → message), all at once."""
        expected = np.flatnonzero(self.active)
        new_claims = self.claims.copy()
        prot = self.protected_now()
        counts = (self.claims & self.alive[:, None]).sum(axis=0)
        for k in expected:
            msg = moves.get(int(k))
            row = None if msg is None else self._check(int(k), msg, agent_ids[k], prot, counts)
            if row is None:
                self.missing[k] += 1
                continue
            self.missing[k] = 0
            new_claims[k] = row
            self.exited[k] = msg.kind == "exit"
        self.claims = new_claims
        self._prot = None
        self.round += 1
        late = np.flatnonzero(self.active & (self.missing >= settings.timeout_rounds))
        if late.size:
            alive = self.alive.copy()
            alive[late] = False
            if alive.sum() >= self.need.max():
                # Conclude without them: the others open again, claiming everything.
                names = ", ".join(str(agent_ids[k]) for k in late)
                self.notes.append(f"negotiation {self.number}: agent(s) {names} silent for "
                                  f"{settings.timeout_rounds} rounds; going on without them")
                self.alive = alive
                self.claims[:] = True
                self._prot = None
                self.exited[:] = False
                self.missing[:] = 0
                self.base = self.round
        if self.round - self.base >= settings.max_rounds and self.active.any():
            self.forced = True
            self.notes.append(f"negotiation {self.number}: no agreement after "
                              f"{settings.max_rounds} rounds; closed by the protection rule")

    @property
    def done(self) -> bool:
        return self.forced or not self.active.any()

    def groups(self, agent_ids: tuple[int, ...]) -> dict[int, tuple[int, ...]]:
        """Object id → its agreed group (when forced: the protected claimers)."""
        owners = protected(self.claims, self.reach, self.need, self.alive) if self.forced \
            else self.claims & self.alive[:, None]
        return {oid: tuple(agent_ids[k] for k in np.flatnonzero(owners[:, c]))
                for c, oid in enumerate(self.objects)}


@dataclass
class NcpComm(CcpComm):
    """Comm module of an NCP agent: CCP's shared knowledge, negotiation instead of Coordination."""

    settings: NegotiationSettings = field(default_factory=NegotiationSettings)
    mute_from: int | None = None        # fault injection: send no negotiation moves from this step
    # The agents whose moves this module sends: itself. The event engine runs one module that
    # speaks for everyone (every module holds the same public state, so the moves are the same).
    voices: tuple[int, ...] | None = None
    negotiation: SlotNegotiation | None = None
    negotiations: int = 0
    moves_sent: int = 0

    def receive(self, t: int, messages: list) -> None:
        moves: dict[int, NegotiationOffer] = {}
        for msg in messages:
            if isinstance(msg, ObjectFound):
                self.note_found(msg.object, msg.t)
            elif isinstance(msg, SearchDone):
                if msg.sender in self.team.agent_ids:
                    self.searched.add(msg.sender)
            elif isinstance(msg, NegotiationOffer):
                self._take_move(msg, moves)
            elif isinstance(msg, Selection):
                self.warnings.append(f"agent {msg.sender}: a CCP selection in an NCP run; ignored")
        if self.state is CommState.CLOSED:
            return
        if self.negotiation is not None:
            self._negotiate(t, moves)
        if self.negotiation is None:
            all_searched = len(self.searched) == self.team.size
            if self.unscheduled and (all_searched or self.policy.due(
                    t, len(self.unscheduled), self.team.searched_fraction(t - 1),
                    self.team.searched_fraction(t))):
                self._open(t)
            elif all_searched and not self.unscheduled:
                self.state = CommState.CLOSED
                self.predicted_makespan = self._predict_makespan(t)

    def _take_move(self, msg: NegotiationOffer, moves: dict[int, NegotiationOffer]) -> None:
        neg = self.negotiation
        if msg.sender not in self.team.agent_ids:
            self.warnings.append(f"negotiation move from agent {msg.sender}, not in the team; ignored")
            return
        if neg is None or msg.negotiation != neg.number or msg.round != neg.round:
            self.warnings.append(f"agent {msg.sender}: move for negotiation {msg.negotiation} "
                                 f"round {msg.round} out of turn; ignored")
            return
        k = self.team.index(msg.sender)
        if k in moves and moves[k] != msg:
            self.warnings.append(f"agent {msg.sender}: two different moves in one round; kept the first")
            return
        moves[k] = msg

    def _open(self, t: int) -> None:
        """A coordination point: negotiate every found, unscheduled object."""
        self.state = CommState.NEGOTIATING
        cost, loc = self.costs(t)
        batch = [self.objects[i] for i in sorted(self.unscheduled)]
        self.unscheduled.clear()
        where = np.array([o.location for o in batch], dtype=np.int64).reshape(-1, 2)
        reach = arrival_np(cost[None, :], np.abs(where[:, None, :] - loc[None, :, :]).sum(axis=2),
                           self.team.period_array()[None, :])
        self.negotiations += 1
        self.negotiation = SlotNegotiation.open(self.negotiations, batch, reach)
        self._send_move(t)

    def _negotiate(self, t: int, moves: dict[int, NegotiationOffer]) -> None:
        neg = self.negotiation
        neg.apply(moves, self.team.agent_ids, self.settings)
        self.warnings.extend(neg.notes)
        neg.notes.clear()
        if not neg.done:
            self._send_move(t)
            return
        # Agreed: every agent orders the same groups the same way (a CCP schedule).
        cost, loc = self.costs(t)
        batch = [self.objects[i] for i in neg.objects]
        result = order_groups(self.team.agent_ids, cost, loc, batch, neg.groups(self.team.agent_ids),
                              self.team.speed_periods)
        for a in result.schedule:
            members = [self.team.index(j) for j in a.agents]
            self.free_at[members] = a.finish
            self.free_loc[members] = self.objects[a.object].destination
        self.schedule.extend(result.schedule)
        self.coordinations += 1
        self.negotiation = None
        self.state = CommState.LISTENING

    def _send_move(self, t: int) -> None:
        neg = self.negotiation
        if self.mute_from is not None and t >= self.mute_from:
            return
        for agent in self.voices or (self.me,):
            k = self.team.index(agent)
            if not neg.active[k]:
                continue
            kind, row = neg.move(k, self.settings)
            ids = tuple(neg.objects[c] for c in np.flatnonzero(row))
            self._outbox.append(NegotiationOffer(agent, t, neg.number, neg.round, kind, ids))
            self.moves_sent += 1

    @property
    def busy(self) -> bool:
        """A negotiation is under way: every step until it ends carries moves."""
        return self.negotiation is not None


class NcpAgent(CcpAgent):
    """A robot running NCP: CCP's agent (search, motion) with the negotiating comm module."""

    protocol = "ncp"

    def __init__(self, agent_id: int, team: TeamInfo, policy: CoordinationPolicy | None = None,
                 settings: NegotiationSettings | None = None, mute_from: int | None = None):
        super().__init__(agent_id, team, policy)
        self.comm = NcpComm(agent_id, team, policy or CoordinationPolicy(),
                            settings=settings or NegotiationSettings(), mute_from=mute_from)
