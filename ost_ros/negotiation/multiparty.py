"""More than two negotiators (§3.3): the rounds strategy with a rotating starter and the exit
option, and "all against all" as a comparison. Also the single entry point ``negotiate``.

Agents interact only through ``Offer`` messages: each claim is encoded to numbers by the
task type and decoded by the receiver, exactly what a transport would carry.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations
from typing import Any, Sequence

import numpy as np

from .agents import AgentSpec, AreaNegotiator, TargetNegotiator
from .errors import NegotiationError
from .messages import BROADCAST, Offer
from .proposals import AreaSearch
from .rewards import global_coverage
from .tasks import AreaTask, TargetTask

STRATEGIES = ("rounds", "all-against-all")


@dataclass
class NegotiationResult:
    """Final shares (index = agent), status, counts and a per-turn trace."""

    task: AreaTask | TargetTask
    shares: list
    status: str                 # "agreed" (everyone accepted/left) or "timeout"
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
        return {"overlap": overlap / t.size, "G": global_coverage(t, self.shares),
                "covered": covered / t.size, "out": out / t.size, "rounds": float(self.rounds)}

    def to_dict(self) -> dict[str, Any]:
        return {"task": self.task.kind, "status": self.status, "rounds": self.rounds,
                "messages": self.messages, "metrics": self.metrics(),
                "shares": [list(self.task.encode(s)) for s in self.shares]}


def _snapshot(task, claims: list, exited: set[int], period: int, rnd: int, agent: int,
              kind: str, predictions: list) -> dict[str, Any]:
    inside = [task.inside(c) for c in claims]
    return {
        "round": rnd, "period": period, "agent": agent, "kind": kind,
        "shares": [task.dim(c) / task.size for c in inside],
        "predictions": list(predictions),
        "overlap": sum(task.dim(task.overlap(a, b)) for a, b in combinations(inside, 2)) / task.size,
        "G": global_coverage(task, claims), "exited": sorted(exited),
    }


def negotiate(task: AreaTask | TargetTask, agents: Sequence[AgentSpec], strategy: str = "rounds",
              seed: int = 0, max_rounds: int = 400, search: AreaSearch | None = None,
              drop_rule: str = "farthest", exit_overlap: float = 0.02,
              trace: bool = True) -> NegotiationResult:
    """Negotiate a subdivision of ``task`` among ``agents``; same seed → same result.

    exit_overlap: an area agent leaves once its claim overlaps the others' by at most this
    fraction of dim(T0). rounds: each round every active agent takes one turn, in agent order starting with agent
    (round mod R) — the starter rotates. all-against-all: each round, every ordered pair
    (i, j) holds one bilateral exchange in which i answers j's claim alone.
    """
    if strategy not in STRATEGIES:
        raise NegotiationError(f"unknown strategy {strategy!r} (expected one of {', '.join(STRATEGIES)})")
    if len(agents) == 0:
        raise NegotiationError("need at least one robot to negotiate")
    if max_rounds < 1:
        raise NegotiationError("max_rounds must be at least 1")
    rng = np.random.default_rng(seed)
    rngs = rng.spawn(len(agents))
    if isinstance(task, AreaTask):
        if not 0.0 <= exit_overlap < 1.0:
            raise NegotiationError(f"exit_overlap must be in [0, 1), got {exit_overlap:g}")
        negs = [AreaNegotiator(i, a, task, i == 0, rngs[i], search or AreaSearch(), exit_overlap)
                for i, a in enumerate(agents)]
    elif isinstance(task, TargetTask):
        negs = [TargetNegotiator(i, a, task, i == 0, rngs[i], drop_rule) for i, a in enumerate(agents)]
    else:
        raise NegotiationError(f"unknown task type {type(task).__name__}")

    r_n = len(negs)
    public = [None] * r_n            # what each agent last announced, decoded from messages
    exited: set[int] = set()
    log: list[Offer] = []
    snaps: list[dict[str, Any]] = []
    period = 0
    accepted = False

    def send(rnd: int, sender: int, receiver: int, kind: str, claim) -> None:
        nonlocal period
        msg = Offer(rnd, period, sender, receiver, kind, task.encode(claim) if claim is not None else ())
        log.append(Offer.from_dict(msg.to_dict()))   # the wire format, round-tripped
        public[sender] = task.decode(log[-1].params)
        period += 1

    def claims_now() -> list:
        return [p if p is not None else task.full() for p in public]

    rnd = 0
    for rnd in range(max_rounds):
        active = [i for i in range(r_n) if i not in exited]
        if not active or accepted:
            break
        # Rotate the starter so nobody is privileged (§3.3); two agents simply alternate.
        start = rnd % r_n if r_n > 2 else 0
        order = sorted(active, key=lambda i: (i - start) % r_n)
        unopened = [i for i in order if public[i] is None]
        if strategy == "rounds" or unopened:
            # everyone states an opening claim before anyone may judge the others' offers
            turns = [(i, None) for i in (unopened or order)]
        else:
            turns = [(i, j) for i in order for j in order if j != i] or [(order[0], None)]
        for i, j in turns:
            if i in exited or accepted:
                continue
            if j is not None and j in exited:
                continue
            others = [public[k] for k in range(r_n) if k != i and public[k] is not None]
            if j is None:
                opponents = others
            else:
                opponents = [public[k] for k in range(r_n) if public[k] is not None and (k == j or k in exited)]
            live = [k for k in range(r_n) if k != i and k not in exited]
            bilateral = len(live) == 1 and public[live[0]] is not None
            fixed = [public[k] for k in sorted(exited) if public[k] is not None]
            d = negs[i].turn(others, opponents, bilateral, alone=not live, fixed=fixed)
            if d.kind == "accept" and not live:
                send(rnd, i, BROADCAST, "exit", d.claim)
                exited.add(i)
            elif d.kind == "accept":
                # the accepting agent takes what the partner left and says so: the message
                # carries its share, the accepted offer is the partner's last one
                send(rnd, i, live[0], "accept", d.claim)
                accepted = True
                exited.update(range(r_n))
            elif d.kind == "exit":
                send(rnd, i, BROADCAST, "exit", d.claim)
                exited.add(i)
            else:
                send(rnd, i, BROADCAST if j is None else j, "offer", d.claim)
            if trace:
                snaps.append(_snapshot(task, claims_now(), exited, period, rnd, i, d.kind,
                                       [n.prediction for n in negs]))
        if len(exited) == r_n:
            break
    else:
        rnd = max_rounds - 1
    status = "agreed" if len(exited) == r_n else "timeout"
    return NegotiationResult(task, claims_now(), status, rnd + 1, len(log), snaps, log)
