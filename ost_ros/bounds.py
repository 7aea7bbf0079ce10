"""A lower bound on the makespan of any run of a scenario (CCP or HCP), computable for any size.

Valid for every protocol of this repository, because they share what the bound relies on (derived
in docs/interpretation.md): each agent walks its whole sweep path (L_j moves, in order) and
then returns to its base; an object is unknown, hence unmoved, until some sweep has sensed it; it
moves only with n_i agents on its cell, one cell per step; every carrier returns to its base.

- search:  T ≥ L_j + |end_j − base_j|                                   for every agent j;
- object:  T ≥ max(f_i, R_i) + |l_i − d_i| + H_i                        for every object i, where
  f_i = the first index at which any sweep path covers l_i (the earliest it can be sensed),
  R_i = the n_i-th smallest |base_j − l_i| (n_i agents must get there), and
  H_i = the n_i-th smallest |d_i − base_j| (its n_i carriers must get home);
- work:    N·T ≥ Σ_j L_j + Σ_i n_i·|l_i − d_i|   (sweep and carry steps are disjoint per agent).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ost_ros.model import Scenario
from ost_ros.sensing import first_sensings, sweep_paths


@dataclass(frozen=True)
class LowerBound:
    value: int
    search: int
    objects: int
    work: int

    @property
    def binding(self) -> str:
        """Which term gives the bound."""
        return max((self.search, "search"), (self.objects, "object"), (self.work, "work"))[1]


def lower_bound(scenario: Scenario) -> LowerBound:
    paths = sweep_paths(scenario)
    bases = np.array([a.base for a in scenario.agents], dtype=np.int64).reshape(-1, 2)
    lengths = np.array([len(p) - 1 for p in paths], dtype=np.int64)
    ends = np.array([p[-1] for p in paths], dtype=np.int64).reshape(-1, 2)
    search = int(np.max(lengths + np.abs(ends - bases).sum(axis=1)))
    n = len(scenario.agents)
    objs = scenario.objects
    obj_term, work = 0, int(lengths.sum())
    if objs:
        loc = np.array([o.location for o in objs], dtype=np.int64)
        dest = np.array([o.destination for o in objs], dtype=np.int64)
        need = np.array([o.required for o in objs], dtype=np.int64)
        carry = np.abs(loc - dest).sum(axis=1)
        first = first_sensings(scenario)
        f = np.where(first >= 0, first, np.iinfo(np.int64).max).min(axis=0)
        reach = np.sort(np.abs(loc[:, None, :] - bases[None, :, :]).sum(axis=2), axis=1)
        home = np.sort(np.abs(dest[:, None, :] - bases[None, :, :]).sum(axis=2), axis=1)
        rows = np.arange(len(objs))
        r_i, h_i = reach[rows, need - 1], home[rows, need - 1]
        obj_term = int(np.max(np.maximum(f, r_i) + carry + h_i))
        work += int((need * carry).sum())
    work_term = -(-work // n)
    return LowerBound(max(search, obj_term, work_term), search, obj_term, work_term)
