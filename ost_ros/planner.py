"""The improved planner for CCP: Algorithm Coordination's schedule, then a bounded local search.

A schedule is read as a *list*: the objects in the order they are scheduled, each given the
n_i agents that could reach it first (ties: lower id) — exactly how Algorithm Coordination picks
a group once it has picked an object (:func:`decode`). The paper's schedule is the list in its
own order, so searching over lists starts from it and can only keep or improve its cost:

    cost = (makespan with every agent home, sum over agents of when each is free)

compared lexicographically (the second term keeps agents free early for objects not yet found).
The search moves one object to another place in the list (first improvement, from the front)
until no move improves or the budget of *object decodes* is spent. The budget is a count, never
wall time, so every agent computes the same schedule from the same knowledge (CCP's premise).

Pure and deterministic; readings in docs/interpretation.md ("The improved planner").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ost_ros.coordination import Assignment, CoordinationResult, coordinate
from ost_ros.model import Cell, ObjectSpec, arrival, arrival_np, group_period

PLANNERS = ("paper", "improved")
# Agent reaches one coordination's local search may compute at most (a placement computes one
# per agent): M = 200, N = 50 then takes ~0.2 s in all.
MAX_WORK = 150_000


def budget_for(m: int, n: int) -> int:
    """Placements for a list of m objects and n agents: enough for a small problem's search to
    settle, at most MAX_WORK agent reaches."""
    return min(MAX_WORK // max(n, 1), 80 * m * m)


def check_planner(name: str) -> str:
    if name not in PLANNERS:
        raise ValueError(f"planner must be one of {', '.join(PLANNERS)}, got {name!r}")
    return name


@dataclass(frozen=True)
class Cost:
    makespan: int  # the last agent home
    total: int  # sum over agents of when each is free

    def key(self) -> tuple[int, int]:
        return (self.makespan, self.total)


class _Problem:
    """The data :func:`decode` runs on, in plain Python lists (small N: faster than numpy)."""

    def __init__(
        self,
        agent_ids: Sequence[int],
        cost: ArrayLike,
        loc: ArrayLike,
        objects: Sequence[ObjectSpec],
        bases: ArrayLike,
        periods: Sequence[int] | None,
    ):
        self.ids = [int(a) for a in agent_ids]
        self.cost = [int(c) for c in np.asarray(cost).reshape(-1)]
        at = np.asarray(loc, dtype=np.int64).reshape(-1, 2)
        self.x, self.y = [int(v) for v in at[:, 0]], [int(v) for v in at[:, 1]]
        home = np.asarray(bases, dtype=np.int64).reshape(-1, 2)
        self.hx, self.hy = [int(v) for v in home[:, 0]], [int(v) for v in home[:, 1]]
        self.objs = sorted(objects, key=lambda o: o.id)
        self.index = {o.id: k for k, o in enumerate(self.objs)}
        self.per = None if periods is None else [int(p) for p in periods]
        self.n = len(self.ids)

    def start_state(self) -> tuple[list[int], list[int], list[int]]:
        return list(self.cost), list(self.x), list(self.y)

    def place(self, k: int, ca: list[int], xs: list[int], ys: list[int]) -> tuple[tuple[int, ...], int, int]:
        """Object k next: its group (agent indices), start and finish; updates the state."""
        o = self.objs[k]
        lx, ly = o.location
        per = self.per
        if per is None:
            reach = [c + abs(lx - x) + abs(ly - y) for c, x, y in zip(ca, xs, ys)]
        else:
            reach = [arrival(c, abs(lx - x) + abs(ly - y), p) for c, x, y, p in zip(ca, xs, ys, per)]
        group = tuple(sorted(sorted(range(self.n), key=reach.__getitem__)[: o.required]))
        m_p = max(reach[j] for j in group)
        carry = abs(lx - o.destination[0]) + abs(ly - o.destination[1])
        if per is None:
            start, finish = m_p, m_p + carry
        else:
            g = group_period([per[j] for j in group])
            start, finish = -(-m_p // g) * g, arrival(m_p, carry, g)
        dx, dy = o.destination
        for j in group:
            ca[j], xs[j], ys[j] = finish, dx, dy
        return group, start, finish

    def cost_of(self, ca: list[int], xs: list[int], ys: list[int]) -> Cost:
        per = self.per or [1] * self.n
        home = [
            arrival(c, abs(x - hx) + abs(y - hy), p)
            for c, x, y, hx, hy, p in zip(ca, xs, ys, self.hx, self.hy, per)
        ]
        return Cost(max(home) if home else 0, sum(ca))


def decode(problem: _Problem, order: Sequence[int]) -> tuple[list[Assignment], Cost]:
    """The schedule of objects (indices into ``problem.objs``) in ``order``, and its cost."""
    ca, xs, ys = problem.start_state()
    out = []
    for k in order:
        group, start, finish = problem.place(k, ca, xs, ys)
        out.append(Assignment(problem.objs[k].id, tuple(problem.ids[j] for j in group), start, finish))
    return out, problem.cost_of(ca, xs, ys)


class _Search:
    """First-improvement insertion moves over the list, with prefix states cached."""

    def __init__(self, problem: _Problem, order: list[int], budget: int):
        self.p, self.budget, self.spent = problem, budget, 0
        self.order = order
        self._prefix()

    def _prefix(self) -> None:
        """States after each prefix of the current order (prefix[i]: before position i)."""
        ca, xs, ys = self.p.start_state()
        self.states = [(list(ca), list(xs), list(ys))]
        for k in self.order:
            self.p.place(k, ca, xs, ys)
            self.states.append((list(ca), list(xs), list(ys)))
        self.spent += len(self.order)
        self.best = self.p.cost_of(ca, xs, ys).key()

    def _try(self, order: list[int], frm: int, to: int) -> tuple[int, int] | None:
        """The cost of ``order`` (equal to the current one outside ``frm``..``to``) if it beats
        the best. Once the team's state after a position equals the current list's there, the
        rest runs as before: the move changes nothing, and the decode stops."""
        ca, xs, ys = (list(v) for v in self.states[frm])
        states = self.states
        for p in range(frm, len(order)):
            self.p.place(order[p], ca, xs, ys)
            self.spent += 1
            if p >= to and ca == states[p + 1][0] and xs == states[p + 1][1] and ys == states[p + 1][2]:
                return None
        key = self.p.cost_of(ca, xs, ys).key()
        return key if key < self.best else None

    def run(self) -> list[int]:
        m = len(self.order)
        improved = True
        while improved and self.spent < self.budget:
            improved = False
            for i in range(m):
                for j in range(m):
                    if j == i or j == i + 1 or self.spent >= self.budget:
                        continue
                    order = list(self.order)
                    k = order.pop(i)
                    order.insert(j if j < i else j - 1, k)
                    if self._try(order, min(i, j), max(i, j)) is not None:
                        self.order = order
                        self._prefix()
                        improved = True
                        break
                if improved or self.spent >= self.budget:
                    break
        return self.order


# Constructive rules tried beside the paper's (weights on an object's carry length and on the
# waiting its group would do; docs/interpretation.md, "The improved planner").
RULES: tuple[tuple[float, float], ...] = (
    (0.0, 0.0),
    (0.25, 0.0),
    (0.5, 0.0),
    (0.0, 0.5),
    (0.0, 2.0),
)


def construct(problem: _Problem, carry_w: float, idle_w: float) -> list[int]:
    """A list built greedily: each round, among *all* objects left, the one minimising
    M_i − carry_w·carry_i + idle_w·(mean wait of its group), where M_i is when its n_i-th agent
    could arrive (Algorithm Coordination's M_i; it takes the minimum over the objects the agents
    select). Long carries early, groups that wait little. Ties: lower object index."""
    objs, per = problem.objs, problem.per
    m, n = len(objs), problem.n
    where = np.array([o.location for o in objs], dtype=np.int64).reshape(-1, 2)
    dest = np.array([o.destination for o in objs], dtype=np.int64).reshape(-1, 2)
    need = np.array([o.required for o in objs], dtype=np.int64)
    carry = np.abs(where - dest).sum(axis=1)
    bias = -carry_w * carry
    ca = np.array(problem.cost, dtype=np.int64)
    at = np.stack([np.array(problem.x, dtype=np.int64), np.array(problem.y, dtype=np.int64)], axis=1)
    period = None if per is None else np.array(per, dtype=np.int64)

    def reach_of(cols: np.ndarray) -> np.ndarray:
        dist = np.abs(where[:, None, 0] - at[None, cols, 0]) + np.abs(where[:, None, 1] - at[None, cols, 1])
        if period is None:
            return ca[None, cols] + dist
        return arrival_np(ca[None, cols], dist, period[None, cols])

    reach = reach_of(np.arange(n))  # (M, N); only the last group's columns change per round
    left = np.arange(m)  # objects not placed yet, ascending
    wide = np.arange(n)[None, :] < need[:, None]
    order: list[int] = []
    for _ in range(m):
        ordered = np.sort(reach[left], axis=1)
        k = need[left]
        m_i = ordered[np.arange(left.size), k - 1]
        key = m_i + bias[left]
        if idle_w:
            early = np.where(wide[left], ordered, 0).sum(axis=1)
            key = key + idle_w * (m_i - early / k)
        r = int(np.argmin(key))
        p = int(left[r])
        left = np.delete(left, r)
        order.append(p)
        group = np.sort(np.argsort(reach[p], kind="stable")[: need[p]])
        m_p = int(m_i[r])
        if period is None:
            finish = m_p + int(carry[p])
        else:
            finish = arrival(m_p, int(carry[p]), group_period([int(period[j]) for j in group]))
        ca[group] = finish
        at[group] = dest[p]
        reach[:, group] = reach_of(group)
    return order


def improve(
    agent_ids: Sequence[int],
    cost: ArrayLike,
    loc: ArrayLike,
    objects: Sequence[ObjectSpec],
    bases: Sequence[Cell] | ArrayLike,
    periods: Sequence[int] | None = None,
    budget: int | None = None,
    hint: Sequence[int] = (),
) -> CoordinationResult:
    """The improved schedule of ``objects`` (same inputs as :func:`coordinate`, plus each agent's
    base): Algorithm Coordination's list — or ``hint`` (object ids: the plan as it stood, the
    objects it lacks in the paper's order after it) when that costs less — improved by moving
    one object at a time while the budget lasts (default :func:`budget_for`). Never costlier
    than the list it starts from."""
    paper = coordinate(agent_ids, cost, loc, objects, periods)
    problem = _Problem(agent_ids, cost, loc, objects, bases, periods)
    if len(problem.objs) < 2:
        return paper
    order = [problem.index[a.object] for a in paper.schedule]
    starts = [order]
    if hint:
        first = [problem.index[i] for i in hint]
        starts.append(first + [k for k in order if k not in set(first)])
    starts.extend(construct(problem, c, w) for c, w in RULES)
    # the cheapest start (ties: the earlier in this list, the paper's first)
    order = min(starts, key=lambda o: decode(problem, o)[1].key())
    budget = budget_for(len(order), problem.n) if budget is None else budget
    search = _Search(problem, order, budget)
    best, best_key = search.run(), search.best
    # Iterated local search: while the budget lasts, perturb the best list (a deterministic
    # pseudo-random segment reversal: the same on every agent) and descend again.
    rng = np.random.default_rng(len(order))
    while search.spent < budget:
        trial = list(best)
        i, j = sorted(int(v) for v in rng.choice(len(trial) + 1, 2, replace=False))
        trial[i:j] = trial[i:j][::-1]
        search.order = trial
        search._prefix()
        got = search.run()
        if search.best < best_key:
            best, best_key = got, search.best
    schedule, _ = decode(problem, best)
    ca, xs, ys = problem.start_state()
    for k in best:
        problem.place(k, ca, xs, ys)
    return CoordinationResult(
        schedule,
        np.array(ca, dtype=np.int64),
        np.stack([np.array(xs, dtype=np.int64), np.array(ys, dtype=np.int64)], axis=1)
        if xs
        else np.zeros((0, 2), dtype=np.int64),
        paper.selections,
    )
