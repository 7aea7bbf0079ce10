"""Algorithm *Optimal-OST* (paper §2.1) over the post-search scheduling problem, with pruning.

The problem: agents free at times CA_j at cells loc_j (for a scenario: the end of the whole
search, i.e. what CCP's final coordination sees when CI ≥ M), objects o_i = (l_i, d_i, n_i). A
solution is an object sequence with a group of n_i agents for each object; executing it in order,
o_i starts when its last member arrives (max over its group of CA_j + |loc_j − l_i|), every
member is then busy until delivery (start + |l_i − d_i|) and stands at d_i. Its cost (the paper's:
the largest agent cost) is max_j (CA_j + |loc_j − base_j|) at the end: every agent home.

The paper enumerates all M! sequences × Π C(N, n_i) groups. We search the same space depth first,
and prune a branch when a lower bound on any completion is no better than the best found
(starting from the CCP schedule, which is one point of the space):
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
from dataclasses import dataclass
from typing import Sequence

from ost_ros.coordination import Assignment, coordinate
from ost_ros.model import Cell, ObjectSpec, manhattan


@dataclass
class OptimalResult:
    cost: int                  # optimal (or best found) makespan, agents home
    plan: list[Assignment]
    proven: bool               # False if the node budget ran out before the search finished
    nodes: int
    ccp_cost: int              # the CCP Coordination schedule's makespan on the same problem

    @property
    def gap(self) -> float:
        """CCP's relative excess over the optimum (0.0 = CCP is optimal)."""
        return (self.ccp_cost - self.cost) / self.cost if self.cost else 0.0


def search_space_order(n_objects: int, n_agents: int) -> float:
    """log10 of M!·(E[C(N, i)])^M, the paper's size of the Optimal-OST search space (Table 1)."""
    mean_comb = sum(math.comb(n_agents, i) for i in range(1, n_agents + 1)) / n_agents
    return (math.lgamma(n_objects + 1) / math.log(10)) + n_objects * math.log10(mean_comb)


def makespan_of(plan_cost: Sequence[int], loc: Sequence[Cell], bases: Sequence[Cell]) -> int:
    return max(c + manhattan(l, b) for c, l, b in zip(plan_cost, loc, bases))


def optimal_schedule(agent_ids: Sequence[int], cost: Sequence[int], loc: Sequence[Cell],
                     bases: Sequence[Cell], objects: Sequence[ObjectSpec],
                     max_nodes: int = 2_000_000) -> OptimalResult:
    n = len(agent_ids)
    objs = sorted(objects, key=lambda o: o.id)
    for o in objs:
        if not 1 <= o.required <= n:
            raise ValueError(f"object {o.id} needs {o.required} agents; the team has {n}")
    ca = [int(c) for c in cost]
    where: list[Cell] = [tuple(int(v) for v in p) for p in loc]
    bases = [tuple(int(v) for v in b) for b in bases]

    # The CCP schedule on the same problem: the starting incumbent and the comparison.
    ccp = coordinate(agent_ids, ca, where, objs)
    ccp_cost = makespan_of([int(c) for c in ccp.cost], [tuple(int(v) for v in p) for p in ccp.loc],
                           bases)
    best_cost = ccp_cost
    best_plan = list(ccp.schedule)

    carry = [manhattan(o.location, o.destination) for o in objs]
    home_k = [sorted(manhattan(o.destination, b) for b in bases)[o.required - 1] for o in objs]
    nodes = 0
    proven = True

    def bound(ca: list[int], where: list[Cell], left: list[int]) -> int:
        b = max(c + manhattan(w, h) for c, w, h in zip(ca, where, bases))
        for i in left:
            o = objs[i]
            reach = sorted(c + manhattan(w, o.location) for c, w in zip(ca, where))
            b = max(b, reach[o.required - 1] + carry[i] + home_k[i])
        return b

    plan: list[Assignment] = []

    def dfs(ca: list[int], where: list[Cell], left: list[int], prev: tuple[int, frozenset]) -> None:
        nonlocal best_cost, best_plan, nodes, proven
        if not left:
            c = makespan_of(ca, where, bases)
            if c < best_cost:
                best_cost, best_plan = c, list(plan)
            return
        if nodes >= max_nodes:
            proven = False
            return
        for i in left:
            o = objs[i]
            reach = [c + manhattan(w, o.location) for c, w in zip(ca, where)]
            order = sorted(range(n), key=lambda j: (reach[j], j))
            rest = [x for x in left if x != i]
            for group in itertools.combinations(order, o.required):
                # Two consecutive objects with disjoint groups commute (neither sees the other):
                # explore only the order with the lower object first.
                if i < prev[0] and prev[1].isdisjoint(group):
                    continue
                nodes += 1
                start = max(reach[j] for j in group)
                finish = start + carry[i]
                ca2, where2 = list(ca), list(where)
                for j in group:
                    ca2[j], where2[j] = finish, o.destination
                if bound(ca2, where2, rest) >= best_cost:
                    continue
                plan.append(Assignment(o.id, tuple(sorted(agent_ids[j] for j in group)), start, finish))
                dfs(ca2, where2, rest, (i, frozenset(group)))
                plan.pop()
                if nodes >= max_nodes:
                    proven = False
                    return

    if objs and bound(ca, where, list(range(len(objs)))) < best_cost:
        dfs(ca, where, list(range(len(objs))), (-1, frozenset()))
    return OptimalResult(best_cost, best_plan, proven, nodes, ccp_cost)


def post_search_problem(scenario) -> tuple[list[int], list[int], list[Cell], list[Cell], list[ObjectSpec]]:
    """The scheduling problem left once every agent has searched (CCP's final coordination with
    CI > M): everyone free at max_j L_j + 1, standing at its sweep end."""
    from ost_ros.team import TeamInfo

    team = TeamInfo.from_scenario(scenario)
    close = int(team.sweep_lengths().max())
    ends = [tuple(int(v) for v in e) for e in team.sweep_ends()]
    return (list(team.agent_ids), [close + 1] * team.size, ends, list(team.bases),
            list(scenario.objects))
