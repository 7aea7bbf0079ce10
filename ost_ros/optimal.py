"""Algorithm *Optimal-OST* (paper §2.1) over the post-search scheduling problem, with pruning.

The problem: agents free at times CA_j at cells loc_j (for a scenario: the end of the whole
search, i.e. what CCP's final coordination sees when CI ≥ M), objects o_i = (l_i, d_i, n_i). A
solution is an object sequence with a group of n_i agents for each object; executing it in order,
o_i starts when its last member arrives (max over its group of CA_j + |loc_j − l_i|), every
member is then busy until delivery (start + |l_i − d_i|) and stands at d_i. Its cost (the paper's:
the largest agent cost) is max_j (CA_j + |loc_j − base_j|) at the end: every agent home.

The paper enumerates all M! sequences × Π C(N, n_i) groups. We search the same space depth first,
and prune a branch when a lower bound on any completion is no better than the best found
(starting from the better of the CCP schedule and the improved planner's, both points of the
space):
- an agent's final cost is at least its current CA_j + |loc_j − base_j| (triangle inequality);
- a remaining object starts no earlier than the n_i-th smallest CA_j + |loc_j − l_i|, and then
  needs |l_i − d_i| to carry and the n_i-th smallest |d_i − base_j| for its carriers to get home.
Groups are tried cheapest first, so good solutions come early. Two consecutive objects whose
groups are disjoint commute, so only the order with the lower id first is explored (partial-order
reduction; exact). Exact for small M and N.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from ost_ros.coordination import Assignment, coordinate
from ost_ros.model import Cell, ObjectSpec, manhattan
from ost_ros.planner import improve


@dataclass
class OptimalResult:
    cost: int  # optimal (or best found) makespan, agents home
    plan: list[Assignment]
    proven: bool  # False if the node budget ran out before the search finished
    nodes: int
    ccp_cost: int  # the CCP Coordination schedule's makespan on the same problem
    improved_cost: int  # the improved planner's (ost_ros.planner) on the same problem

    @property
    def gap(self) -> float:
        """CCP's relative excess over the optimum (0.0 = CCP is optimal)."""
        return (self.ccp_cost - self.cost) / self.cost if self.cost else 0.0

    @property
    def improved_gap(self) -> float:
        """The improved planner's relative excess over the optimum."""
        return (self.improved_cost - self.cost) / self.cost if self.cost else 0.0


def search_space_order(n_objects: int, n_agents: int) -> float:
    """log10 of M!·(E[C(N, i)])^M, the paper's size of the Optimal-OST search space (Table 1)."""
    mean_comb = sum(math.comb(n_agents, i) for i in range(1, n_agents + 1)) / n_agents
    return (math.lgamma(n_objects + 1) / math.log(10)) + n_objects * math.log10(mean_comb)


def makespan_of(plan_cost: Sequence[int], loc: Sequence[Cell], bases: Sequence[Cell]) -> int:
    return max(c + manhattan(at, b) for c, at, b in zip(plan_cost, loc, bases))


def optimal_schedule(
    agent_ids: Sequence[int],
    cost: Sequence[int],
    loc: Sequence[Cell],
    bases: Sequence[Cell],
    objects: Sequence[ObjectSpec],
    max_nodes: int = 2_000_000,
) -> OptimalResult:
    n = len(agent_ids)
    objs = sorted(objects, key=lambda o: o.id)
    for o in objs:
        if not 1 <= o.required <= n:
            raise ValueError(f"object {o.id} needs {o.required} agents; the team has {n}")
    ca = [int(c) for c in cost]
    where: list[Cell] = [(int(p[0]), int(p[1])) for p in loc]
    homes: list[Cell] = [(int(b[0]), int(b[1])) for b in bases]
    # The CCP schedule and the improved planner's on the same problem: the comparisons, and the
    # better of the two is the starting incumbent.
    ccp = coordinate(agent_ids, ca, where, objs)
    ccp_cost = makespan_of([int(c) for c in ccp.cost], [(int(p[0]), int(p[1])) for p in ccp.loc], homes)
    better = improve(agent_ids, ca, where, objs, homes)
    improved_cost = makespan_of(
        [int(c) for c in better.cost], [(int(p[0]), int(p[1])) for p in better.loc], homes
    )
    start_cost, start_plan = min(
        (ccp_cost, ccp.schedule), (improved_cost, better.schedule), key=lambda c: c[0]
    )
    search = _BranchAndBound(list(agent_ids), homes, objs, max_nodes, start_cost, list(start_plan))
    left = list(range(len(objs)))
    if objs and search.bound(ca, where, left) < search.best_cost:
        search.dfs(ca, where, left, (-1, frozenset()))
    return OptimalResult(
        search.best_cost, search.best_plan, search.proven, search.nodes, ccp_cost, improved_cost
    )


class _BranchAndBound:
    """Depth-first over (next object, its group), pruned by a makespan lower bound."""

    def __init__(
        self,
        agent_ids: list[int],
        bases: list[Cell],
        objs: list[ObjectSpec],
        max_nodes: int,
        best_cost: int,
        best_plan: list[Assignment],
    ):
        self.ids, self.bases, self.objs, self.max_nodes = agent_ids, bases, objs, max_nodes
        self.best_cost, self.best_plan = best_cost, best_plan
        self.carry = [manhattan(o.location, o.destination) for o in objs]
        self.home_k = [sorted(manhattan(o.destination, b) for b in bases)[o.required - 1] for o in objs]
        self.nodes = 0
        self.proven = True
        self.plan: list[Assignment] = []

    def bound(self, ca: list[int], where: list[Cell], left: list[int]) -> int:
        b = max(c + manhattan(w, h) for c, w, h in zip(ca, where, self.bases))
        for i in left:
            o = self.objs[i]
            reach = sorted(c + manhattan(w, o.location) for c, w in zip(ca, where))
            b = max(b, reach[o.required - 1] + self.carry[i] + self.home_k[i])
        return b

    def dfs(self, ca: list[int], where: list[Cell], left: list[int], prev: tuple[int, frozenset]) -> None:
        if not left:
            c = makespan_of(ca, where, self.bases)
            if c < self.best_cost:
                self.best_cost, self.best_plan = c, list(self.plan)
            return
        if self.nodes >= self.max_nodes:
            self.proven = False
            return
        for i in left:
            if not self._branch(i, ca, where, left, prev):
                return

    def _branch(
        self, i: int, ca: list[int], where: list[Cell], left: list[int], prev: tuple[int, frozenset]
    ) -> bool:
        """Every group for object i next; False once the node budget is spent."""
        o = self.objs[i]
        reach = [c + manhattan(w, o.location) for c, w in zip(ca, where)]
        order = sorted(range(len(ca)), key=lambda j: (reach[j], j))
        rest = [x for x in left if x != i]
        for group in itertools.combinations(order, o.required):
            # Two consecutive objects with disjoint groups commute (neither sees the other):
            # explore only the order with the lower object first.
            if i < prev[0] and prev[1].isdisjoint(group):
                continue
            self.nodes += 1
            start = max(reach[j] for j in group)
            finish = start + self.carry[i]
            ca2, where2 = list(ca), list(where)
            for j in group:
                ca2[j], where2[j] = finish, o.destination
            if self.bound(ca2, where2, rest) >= self.best_cost:
                continue
            self.plan.append(Assignment(o.id, tuple(sorted(self.ids[j] for j in group)), start, finish))
            self.dfs(ca2, where2, rest, (i, frozenset(group)))
            self.plan.pop()
            if self.nodes >= self.max_nodes:
                self.proven = False
                return False
        return True


def post_search_problem(scenario) -> tuple[list[int], list[int], list[Cell], list[Cell], list[ObjectSpec]]:
    """The scheduling problem left once every agent has searched (CCP's final coordination with
    CI > M): everyone free at max_j L_j + 1, standing at its sweep end."""
    from ost_ros.team import TeamInfo

    team = TeamInfo.from_scenario(scenario)
    close = int(team.sweep_lengths().max())
    ends: list[Cell] = [(int(e[0]), int(e[1])) for e in team.sweep_ends()]
    return (list(team.agent_ids), [close + 1] * team.size, ends, list(team.bases), list(scenario.objects))
