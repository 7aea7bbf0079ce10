"""More than two negotiators (§3.3): the rounds strategy with a rotating starter and the exit
option, and "all against all" as a comparison. Also the single entry point ``negotiate``.

Agents interact only through ``Offer`` messages: each claim is encoded to numbers by the
task type and decoded by the receiver, exactly what a transport would carry.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import combinations
from typing import Any

import numpy as np

from .agents import AgentSpec, AreaNegotiator, TargetNegotiator
from .errors import NegotiationError
from .messages import BROADCAST, Offer
from .proposals import AreaSearch, check_drop_rule
from .rewards import global_coverage
from .tasks import AreaTask, TargetTask

STRATEGIES = ("rounds", "all-against-all")


@dataclass
class NegotiationResult:
    """Final shares (index = agent), status, counts and a per-turn trace."""

    task: AreaTask | TargetTask
    shares: list
    status: str  # "agreed" (everyone accepted/left) or "timeout"
    rounds: int
    messages: int
    trace: list[dict[str, Any]] = field(default_factory=list)
    log: list[Offer] = field(default_factory=list)

    def metrics(self) -> dict[str, float]:
        """Overlap, G, covered and out, as fractions of dim(T0) (G in task units)."""
        t = self.task
        inside = [t.inside(s) for s in self.shares]
        overlap = sum(t.dim(t.overlap(a, b)) for a, b in combinations(inside, 2))
        covered = t.dim(t.union(inside))
        out = t.dim(t.outside(t.union(list(self.shares))))
        return {
            "overlap": overlap / t.size,
            "G": global_coverage(t, self.shares),
            "covered": covered / t.size,
            "out": out / t.size,
            "rounds": float(self.rounds),
        }

    def to_dict(self) -> dict[str, Any]:
        return {
            "task": self.task.kind,
            "status": self.status,
            "rounds": self.rounds,
            "messages": self.messages,
            "metrics": self.metrics(),
            "shares": [list(self.task.encode(s)) for s in self.shares],
        }


def _snapshot(
    task,
    claims: list,
    exited: set[int],
    period: int,
    rnd: int,
    agent: int,
    kind: str,
    predictions: list,
    evaluated: list,
) -> dict[str, Any]:
    inside = [task.inside(c) for c in claims]
    return {
        "round": rnd,
        "period": period,
        "agent": agent,
        "kind": kind,
        "shares": [task.dim(c) / task.size for c in inside],
        "predictions": list(predictions),
        "evaluated": list(evaluated),
        "overlap": sum(task.dim(task.overlap(a, b)) for a, b in combinations(inside, 2)) / task.size,
        "G": global_coverage(task, claims),
        "exited": sorted(exited),
    }


def negotiate(
    task: AreaTask | TargetTask,
    agents: Sequence[AgentSpec],
    strategy: str = "rounds",
    seed: int = 0,
    max_rounds: int = 400,
    search: AreaSearch | None = None,
    drop_rule: str = "furthest",
    exit_overlap: float = 0.02,
    trace: bool = True,
    stopping: str = "paper",
) -> NegotiationResult:
    """Negotiate a subdivision of ``task`` among ``agents``; same seed → same result.

    stopping (areas): ``paper`` — an agent accepts or leaves when the share the others leave it
    reaches its Rubinstein prediction (Eq. 3); ``overlap`` — also once its claim overlaps the
    others' by at most ``exit_overlap`` of dim(T0), with claims clipped to T0 (``AreaNegotiator``).
    drop_rule (targets): ``furthest`` (§4.2), ``path`` (§5.1) or ``reward``.
    rounds: each round every active agent takes one turn, in agent order starting with agent
    (round mod R) — the starter rotates. all-against-all: each round, every ordered pair
    (i, j) holds one bilateral exchange in which i answers j's claim alone.
    """
    if strategy not in STRATEGIES:
        raise NegotiationError(f"unknown strategy {strategy!r} (expected one of {', '.join(STRATEGIES)})")
    if len(agents) == 0:
        raise NegotiationError("need at least one robot to negotiate")
    if max_rounds < 1:
        raise NegotiationError("max_rounds must be at least 1")
    negs = _negotiators(task, agents, seed, search, drop_rule, exit_overlap, stopping)
    session = _Session(task, negs, trace)
    rnd = 0
    for rnd in range(max_rounds):
        active = [i for i in range(session.size) if i not in session.exited]
        if not active or session.accepted:
            break
        session.round(rnd, active, strategy)
        if len(session.exited) == session.size:
            break
    else:
        rnd = max_rounds - 1
    status = "agreed" if len(session.exited) == session.size else "timeout"
    return NegotiationResult(
        task, session.claims_now(), status, rnd + 1, len(session.log), session.snaps, session.log
    )


def _negotiators(
    task: AreaTask | TargetTask,
    agents: Sequence[AgentSpec],
    seed: int,
    search: AreaSearch | None,
    drop_rule: str,
    exit_overlap: float,
    stopping: str,
) -> list:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise NegotiationError(f"seed must be a non-negative integer, got {seed!r}")
    rngs = np.random.default_rng(seed).spawn(len(agents))
    if isinstance(task, AreaTask):
        if not 0.0 <= exit_overlap < 1.0:
            raise NegotiationError(f"exit_overlap must be in [0, 1), got {exit_overlap:g}")
        return [
            AreaNegotiator(i, a, task, i == 0, rngs[i], search or AreaSearch(), exit_overlap, stopping)
            for i, a in enumerate(agents)
        ]
    if isinstance(task, TargetTask):
        check_drop_rule(drop_rule)  # before the first turn, not at the first drop
        return [TargetNegotiator(i, a, task, i == 0, rngs[i], drop_rule) for i, a in enumerate(agents)]
    raise NegotiationError(f"unknown task type {type(task).__name__}")


class _Session:
    """The public state of a negotiation: what each agent last announced (decoded from its
    messages), who has left, the message log."""

    def __init__(self, task: AreaTask | TargetTask, negs: list, trace: bool):
        self.task, self.negs, self.trace = task, negs, trace
        self.size = len(negs)
        self.public: list[Any] = [None] * self.size
        self.exited: set[int] = set()
        self.log: list[Offer] = []
        self.snaps: list[dict[str, Any]] = []
        self.period = 0
        self.accepted = False

    def send(self, rnd: int, sender: int, receiver: int, kind: str, claim: Any) -> None:
        task = self.task
        msg = Offer(rnd, self.period, sender, receiver, kind, task.encode(claim) if claim is not None else ())
        self.log.append(Offer.from_dict(msg.to_dict()))  # the wire format, round-tripped
        self.public[sender] = task.decode(self.log[-1].params)
        self.period += 1

    def claims_now(self) -> list:
        return [p if p is not None else self.task.full() for p in self.public]

    def round(self, rnd: int, active: list[int], strategy: str) -> None:
        r_n = self.size
        # Rotate the starter so nobody is privileged (§3.3); two agents simply alternate.
        start = rnd % r_n if r_n > 2 else 0
        order = sorted(active, key=lambda i: (i - start) % r_n)
        unopened = [i for i in order if self.public[i] is None]
        if strategy == "rounds" or unopened:
            # everyone states an opening claim before anyone may judge the others' offers
            turns: list[tuple[int, int | None]] = [(i, None) for i in (unopened or order)]
        else:
            turns = [(i, j) for i in order for j in order if j != i] or [(order[0], None)]
        for i, j in turns:
            if i in self.exited or self.accepted or (j is not None and j in self.exited):
                continue
            self.turn(rnd, i, j)

    def turn(self, rnd: int, i: int, j: int | None) -> None:
        """Agent i answers everyone's claims (j None) or agent j's alone."""
        public, exited, r_n = self.public, self.exited, self.size
        others = [public[k] for k in range(r_n) if k != i and public[k] is not None]
        if j is None:
            opponents = others
        else:
            opponents = [public[k] for k in range(r_n) if public[k] is not None and (k == j or k in exited)]
        live = [k for k in range(r_n) if k != i and k not in exited]
        bilateral = len(live) == 1 and public[live[0]] is not None
        fixed = [public[k] for k in sorted(exited) if public[k] is not None]
        d = self.negs[i].turn(others, opponents, bilateral, alone=not live, fixed=fixed)
        if d.kind == "accept" and not live:
            self.send(rnd, i, BROADCAST, "exit", d.claim)
            exited.add(i)
        elif d.kind == "accept":
            # the accepting agent takes what the partner left and says so: the message
            # carries its share, the accepted offer is the partner's last one
            self.send(rnd, i, live[0], "accept", d.claim)
            self.accepted = True
            exited.update(range(r_n))
        elif d.kind == "exit":
            self.send(rnd, i, BROADCAST, "exit", d.claim)
            exited.add(i)
        else:
            self.send(rnd, i, BROADCAST if j is None else j, "offer", d.claim)
        if self.trace:
            self.snaps.append(
                _snapshot(
                    self.task,
                    self.claims_now(),
                    exited,
                    self.period,
                    rnd,
                    i,
                    d.kind,
                    [n.prediction for n in self.negs],
                    [getattr(n, "evaluated", None) for n in self.negs],
                )
            )
