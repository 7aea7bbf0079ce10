"""The improved planner for CCP: Algorithm Coordination's schedule, then a bounded local search.

A schedule is read as a *list*: the objects in the order they are scheduled, each given the
n_i agents that could reach it first (ties: lower id) — exactly how Algorithm Coordination picks
a group once it has picked an object (:func:`decode`) — unless the list names another group of
n_i agents for it (the optimum often needs one: a group that starts later, or leaves the agent
free first where it stands). The paper's schedule is the list in its own order, so searching
over lists starts from it and can only keep or improve its cost:

    cost = (makespan with every agent home, sum over agents of when each is free)

compared lexicographically (the second term keeps agents free early for objects not yet found).
The search starts from the cheapest of the paper's list, the plan as it stood and greedy lists
built by other rules (:data:`RULES`). A short list gets an iterated local search (descents over
every move of one object, swap of two and change of one group member, between random kicks); a
long one threshold accepting over random moves. Random draws come from a generator defined here
(:class:`_Rng`) seeded by the problem's size, and the budget is a count of *object placements*,
never wall time, so every agent computes the same schedule from the same knowledge (CCP's
premise) on any machine.

Pure and deterministic; readings in docs/interpretation.md ("The improved planner").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ost_ros.coordination import Assignment, CoordinationResult, coordinate
from ost_ros.model import Cell, ObjectSpec, arrival, arrival_np, group_period, manhattan

PLANNERS = ("paper", "improved")
# Agent reaches one coordination's local search may compute at most (a placement computes one
# per agent): M = 200, N = 50 then takes ~0.3 s in all, the greedy starts included.
MAX_WORK = 150_000
PER_M2 = 640  # a short list's budget: placements per m²
ROUNDS = 6  # threshold accepting: the search's parts, each from the best solution so far
WARM = 300  # placements per m² from which a list gets the iterated local search
KICKS = 2  # iterated local search: random moves between two descents
NEAR = 8  # a near move: within this many places


def budget_for(m: int, n: int) -> int:
    """Placements for a list of m objects and n agents: PER_M2·m² (a short list's iterated local
    search), at most MAX_WORK agent reaches."""
    return min(MAX_WORK // max(n, 1), PER_M2 * m * m)


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
        # per object: location, destination, carry length, group size
        self.spec = [
            (*o.location, *o.destination, manhattan(o.location, o.destination), o.required) for o in self.objs
        ]

    def start_state(self) -> tuple[list[int], list[int], list[int]]:
        return list(self.cost), list(self.x), list(self.y)

    def place(
        self, k: int, ca: list[int], xs: list[int], ys: list[int], group: tuple[int, ...] | None = None
    ) -> tuple[tuple[int, ...], int, int]:
        """Object k next: its group (agent indices; default: the n_k that reach it first, ties:
        lower index), start and finish; updates the state."""
        lx, ly, dx, dy, carry, need = self.spec[k]
        per = self.per
        if group is None:
            if per is None:
                reach = [c + abs(lx - x) + abs(ly - y) for c, x, y in zip(ca, xs, ys)]
            else:
                reach = [arrival(c, abs(lx - x) + abs(ly - y), p) for c, x, y, p in zip(ca, xs, ys, per)]
            if need == 1:
                m_p = min(reach)
                group = (reach.index(m_p),)
            else:
                ranked = sorted(range(self.n), key=reach.__getitem__)
                m_p = reach[ranked[need - 1]]
                group = tuple(sorted(ranked[:need]))
        elif per is None:
            m_p = max(ca[j] + abs(lx - xs[j]) + abs(ly - ys[j]) for j in group)
        else:
            m_p = max(arrival(ca[j], abs(lx - xs[j]) + abs(ly - ys[j]), per[j]) for j in group)
        if per is None:
            start, finish = m_p, m_p + carry
        else:
            g = group_period([per[j] for j in group])
            start, finish = -(-m_p // g) * g, arrival(m_p, carry, g)
        for j in group:
            ca[j], xs[j], ys[j] = finish, dx, dy
        return group, start, finish

    def ranked(self, k: int, ca: list[int], xs: list[int], ys: list[int]) -> list[int]:
        """Agent indices by when they could reach object k (ties: lower index)."""
        lx, ly = self.spec[k][:2]
        if self.per is None:
            reach = [c + abs(lx - x) + abs(ly - y) for c, x, y in zip(ca, xs, ys)]
        else:
            reach = [arrival(c, abs(lx - x) + abs(ly - y), p) for c, x, y, p in zip(ca, xs, ys, self.per)]
        return sorted(range(self.n), key=reach.__getitem__)

    def cost_of(self, ca: list[int], xs: list[int], ys: list[int]) -> Cost:
        if not ca:
            return Cost(0, 0)
        if self.per is None:
            last = max(c + abs(x - hx) + abs(y - hy) for c, x, y, hx, hy in zip(ca, xs, ys, self.hx, self.hy))
        else:
            last = max(
                arrival(c, abs(x - hx) + abs(y - hy), p)
                for c, x, y, hx, hy, p in zip(ca, xs, ys, self.hx, self.hy, self.per)
            )
        return Cost(last, sum(ca))


Groups = dict[int, tuple[int, ...]]  # object index -> its group, where not the n_i first to reach it


def _exchanged(
    groups: Groups, k: int, ranked: list[int], need: int, out: int, pick: Callable[[int], int]
) -> Groups:
    """``groups`` with object k's group (default: the ``need`` first of ``ranked``) given member
    number ``out`` exchanged for one of the three agents not in it that reach k first (the
    ``pick(count)``-th)."""
    first = tuple(sorted(ranked[:need]))
    group = groups.get(k, first)
    leaving = group[out]
    others = [a for a in ranked if a not in group][:3]
    chosen = tuple(sorted([a for a in group if a != leaving] + [others[pick(len(others))]]))
    new = dict(groups)
    if chosen == first:
        new.pop(k, None)
    else:
        new[k] = chosen
    return new


def decode(
    problem: _Problem, order: Sequence[int], groups: Groups | None = None
) -> tuple[list[Assignment], Cost]:
    """The schedule of objects (indices into ``problem.objs``) in ``order``, each with its group
    in ``groups`` or else the n_i agents that reach it first, and its cost."""
    ca, xs, ys = problem.start_state()
    out = []
    chosen = groups or {}
    for k in order:
        group, start, finish = problem.place(k, ca, xs, ys, chosen.get(k))
        out.append(Assignment(problem.objs[k].id, tuple(problem.ids[j] for j in group), start, finish))
    return out, problem.cost_of(ca, xs, ys)


class _Rng:
    """SplitMix64: a generator defined here, bit for bit, so that every agent on every machine and
    Python or numpy version draws the same numbers from the same seed."""

    MASK = (1 << 64) - 1

    def __init__(self, seed: int):
        self.state = seed & self.MASK

    def below(self, k: int) -> int:
        """A number in 0..k-1."""
        self.state = (self.state + 0x9E3779B97F4A7C15) & self.MASK
        z = self.state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & self.MASK
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & self.MASK
        return (z ^ (z >> 31)) % k


State = tuple[list[int], list[int], list[int]]


class _Search:
    """Moves over (list, groups), with the team's state after each prefix of the current list
    cached: a move re-decodes from the first position it changes, and stops as soon as the state
    is again the current list's (the rest runs as before)."""

    def __init__(self, problem: _Problem, order: list[int], budget: int, groups: Groups | None = None):
        self.p, self.budget, self.spent = problem, budget, 0
        self.order, self.groups = order, dict(groups or {})
        self._prefix()

    def _prefix(self) -> None:
        """States after each prefix of the current order (states[i]: before position i)."""
        ca, xs, ys = self.p.start_state()
        self.states: list[State] = [(list(ca), list(xs), list(ys))]
        for k in self.order:
            self.p.place(k, ca, xs, ys, self.groups.get(k))
            self.states.append((list(ca), list(xs), list(ys)))
        self.spent += len(self.order)
        self.key = self.p.cost_of(ca, xs, ys).key()

    def _eval(
        self, order: list[int], groups: Groups, frm: int, to: int
    ) -> tuple[tuple[int, int], list[State]]:
        """The cost of ``order`` with ``groups`` (equal to the current solution outside positions
        ``frm``..``to``) and the states after positions frm, frm + 1, … up to where they are the
        current solution's again."""
        ca, xs, ys = (list(v) for v in self.states[frm])
        states = self.states
        new: list[State] = []
        place, get = self.p.place, groups.get
        for p in range(frm, len(order)):
            k = order[p]
            place(k, ca, xs, ys, get(k))
            self.spent += 1
            after = states[p + 1]
            if p >= to and ca == after[0] and xs == after[1] and ys == after[2]:
                return self.key, new
            new.append((list(ca), list(xs), list(ys)))
        return self.p.cost_of(ca, xs, ys).key(), new

    def _adopt(
        self, order: list[int], groups: Groups, frm: int, key: tuple[int, int], new: list[State]
    ) -> None:
        self.order, self.groups, self.key = order, groups, key
        self.states[frm + 1 : frm + 1 + len(new)] = new

    def _neighbour(self, rng: _Rng) -> tuple[list[int], Groups, int, int]:
        """A random move, and the first and last positions it changes: an object elsewhere, two
        objects swapped (half of these within ``NEAR`` places), a run of two or three objects
        elsewhere, or an object given another group (a member exchanged for one of the three
        agents not in it that could reach it first)."""
        order, groups, m = list(self.order), self.groups, len(self.order)
        kind = rng.below(8)
        if kind >= 6:
            p = rng.below(m)
            k = order[p]
            need = self.p.spec[k][5]
            if need < self.p.n:
                ranked = self.p.ranked(k, *self.states[p])
                self.spent += 1
                return order, _exchanged(groups, k, ranked, need, rng.below(need), rng.below), p, p
        i = rng.below(m)
        if kind & 1 and m > 2 * NEAR + 1:
            j = min(max(i + rng.below(2 * NEAR + 1) - NEAR, 0), m - 1)
            if j == i:
                j = i + 1 if i + 1 < m else i - 1
        else:
            j = rng.below(m - 1)
            j += j >= i
        if kind < 2:
            order[i], order[j] = order[j], order[i]
            return order, groups, min(i, j), max(i, j)
        if kind < 4 and m > 3:
            size = 2 + rng.below(2)
            i = min(i, m - size)
            run = order[i : i + size]
            del order[i : i + size]
            j = min(j, len(order))
            order[j:j] = run
            return order, groups, min(i, j), max(i, j) + size - 1
        k = order.pop(i)
        order.insert(j, k)
        return order, groups, min(i, j), max(i, j)

    def _moves(self, rng: _Rng) -> list[tuple[int, int, int, int]]:
        """Every move, shuffled: an object elsewhere (0, from, to), two objects swapped (1, i, j),
        an object's group with its a-th member exchanged for the b-th of the three agents not in
        it that could reach it first (2, position, a, b)."""
        m, n = len(self.order), self.p.n
        moves = [(0, i, j, 0) for i in range(m) for j in range(m) if j != i]
        moves += [(1, i, j, 0) for i in range(m) for j in range(i + 1, m)]
        for p in range(m):
            k = self.order[p]
            need = self.p.spec[k][5]
            if need < n:
                moves += [(2, p, a, b) for a in range(need) for b in range(min(n - need, 3))]
        for x in range(len(moves) - 1, 0, -1):
            y = rng.below(x + 1)
            moves[x], moves[y] = moves[y], moves[x]
        return moves

    def _apply(self, mv: tuple[int, int, int, int]) -> tuple[list[int], Groups, int, int]:
        """The solution after move ``mv``, and the first and last positions it changes."""
        kind, i, j, b = mv
        order, groups = list(self.order), self.groups
        if kind == 0:
            k = order.pop(i)
            order.insert(j, k)
            return order, groups, min(i, j), max(i, j)
        if kind == 1:
            order[i], order[j] = order[j], order[i]
            return order, groups, i, j
        k = order[i]
        need = self.p.spec[k][5]
        ranked = self.p.ranked(k, *self.states[i])
        self.spent += 1
        return order, _exchanged(groups, k, ranked, need, j, lambda _: b), i, i

    def iterated(self, rng: _Rng, kicks: int, slack: int) -> tuple[list[int], Groups]:
        """Iterated local search while the budget lasts: descend (first improvement over every
        move of :meth:`_moves`, in a shuffled order), then kick the solution (``kicks`` random
        moves of :meth:`_neighbour`) and descend again. The search goes on from the new local
        optimum if its makespan is within ``slack`` of the best's, else from the best. Returns the
        best solution seen (never costlier than the start)."""
        best, best_groups, best_key, best_states = self.order, self.groups, self.key, list(self.states)
        while self.spent < self.budget:
            improved = True
            while improved and self.spent < self.budget:
                improved = False
                for mv in self._moves(rng):
                    if self.spent >= self.budget:
                        break
                    order, groups, frm, to = self._apply(mv)
                    key, new = self._eval(order, groups, frm, to)
                    if key < self.key:
                        self._adopt(order, groups, frm, key, new)
                        improved = True
                        break
            if self.key < best_key:
                best, best_groups, best_key, best_states = (
                    self.order,
                    self.groups,
                    self.key,
                    list(self.states),
                )
            elif self.key[0] >= best_key[0] + slack:
                self.order, self.groups, self.key = best, best_groups, best_key
                self.states = list(best_states)
            for _ in range(kicks):
                if self.spent >= self.budget:
                    break
                order, groups, frm, to = self._neighbour(rng)
                key, new = self._eval(order, groups, frm, to)
                self._adopt(order, groups, frm, key, new)
        return best, best_groups

    def anneal(self, rng: _Rng, rounds: int, threshold: int) -> tuple[list[int], Groups]:
        """Threshold accepting while the budget lasts, in ``rounds`` equal parts, each from the
        best solution so far: a move is taken if it costs no more than the current solution, or
        if its makespan exceeds the current one's by less than a threshold that falls linearly
        from ``threshold`` to 0 over the part. Returns the best solution seen (never costlier
        than the start)."""
        best, best_groups, best_key, best_states = self.order, self.groups, self.key, list(self.states)
        left = self.budget - self.spent
        for r in range(rounds):
            if r:  # (a state list is never changed in place: the copy's entries stay valid)
                self.order, self.groups, self.key = best, best_groups, best_key
                self.states = list(best_states)
            end = self.budget if r == rounds - 1 else self.spent + left // rounds
            span = max(end - self.spent, 1)
            while self.spent < end:
                order, groups, frm, to = self._neighbour(rng)
                key, new = self._eval(order, groups, frm, to)
                limit = threshold * (end - self.spent) // span
                if key <= self.key or key[0] < self.key[0] + limit:
                    self._adopt(order, groups, frm, key, new)
                    if key < best_key:
                        best, best_groups, best_key, best_states = order, groups, key, list(self.states)
        return best, best_groups


# Constructive rules tried beside the paper's (weights on an object's carry length, on the
# waiting its group would do and on how far its carriers would be from home after it;
# docs/interpretation.md, "The improved planner").
RULES: tuple[tuple[float, float, float], ...] = tuple(
    (carry, idle, home)
    for carry, idle in ((0.0, 0.0), (0.25, 0.0), (0.0, 0.5), (0.25, 1.0))
    for home in (0.5, 1.0)
)


def construct(problem: _Problem, carry_w: float, idle_w: float, home_w: float = 0.0) -> list[int]:
    """A list built greedily: each round, among *all* objects left, the one minimising
    M_i − carry_w·carry_i + idle_w·(mean wait of its group) − home_w·back_i, where M_i is when
    its n_i-th agent could arrive (Algorithm Coordination's M_i; it takes the minimum over the
    objects the agents select) and back_i the n_i-th smallest distance from its destination to
    an agent's base. Long carries early, groups that wait little, objects that leave their
    carriers far from home early (the makespan counts the way home). Ties: lower object index."""
    objs, per = problem.objs, problem.per
    m, n = len(objs), problem.n
    where = np.array([o.location for o in objs], dtype=np.int64).reshape(-1, 2)
    dest = np.array([o.destination for o in objs], dtype=np.int64).reshape(-1, 2)
    need = np.array([o.required for o in objs], dtype=np.int64)
    carry = np.abs(where - dest).sum(axis=1)
    bias = -carry_w * carry
    if home_w and m:
        bases = np.stack([np.array(problem.hx, dtype=np.int64), np.array(problem.hy, dtype=np.int64)], axis=1)
        back = np.sort(np.abs(dest[:, None, :] - bases[None, :, :]).sum(axis=2), axis=1)
        bias = bias - home_w * back[np.arange(m), need - 1]
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
    starts.extend(construct(problem, *rule) for rule in RULES)
    # the cheapest start (ties: the earlier in this list, the paper's first)
    order = min(starts, key=lambda o: decode(problem, o)[1].key())
    m = len(order)
    budget = budget_for(m, problem.n) if budget is None else budget
    search = _Search(problem, order, budget)
    # Random draws from a generator seeded by the problem's size: the same on every agent.
    rng = _Rng(m * 1_000_003 + problem.n)
    if budget >= WARM * m * m:
        # a short list: iterated local search over the whole neighbourhood
        best, groups = search.iterated(rng, KICKS, search.key[0] // 40)
    else:
        # a long one: threshold accepting over random moves, the threshold 5 % of the makespan
        # scaled down by the share of WARM·m² placements the budget allows
        threshold = search.key[0] * budget // (20 * WARM * m * m)
        best, groups = search.anneal(rng, ROUNDS, threshold)
    schedule, _ = decode(problem, best, groups)
    ca, xs, ys = problem.start_state()
    for k in best:
        problem.place(k, ca, xs, ys, groups.get(k))
    return CoordinationResult(
        schedule,
        np.array(ca, dtype=np.int64),
        np.stack([np.array(xs, dtype=np.int64), np.array(ys, dtype=np.int64)], axis=1)
        if xs
        else np.zeros((0, 2), dtype=np.int64),
        paper.selections,
    )
