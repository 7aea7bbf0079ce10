"""Algorithm *Coordination* of the cost-balanced protocol (paper §3.3), and its triggers (§3.1).

Readings (see docs/interpretation.md):
- C_ij = CA_j + dist(loc_j, l_i): the time agent j could reach object i, Manhattan distance;
- every agent selects its min-C object (ties: lower object id);
- M_i = the n_i-th smallest C_ij over all agents: when o_i's group could be complete;
- Opt = the selected object with minimum M_i (ties: lower object id);
- its group = the n_p agents with smallest C_pj (ties: lower agent id); each sets
  CA := M_p + dist(l_p, d_p) and loc := d_p.

The function is pure and deterministic: every agent runs it on the same inputs and obtains the
same schedule, which is what lets CCP agree without further communication.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ost_ros.model import ObjectSpec, arrival, arrival_np, group_period

if TYPE_CHECKING:
    from ost_ros.team import TeamInfo

# Larger than any reachable cost, small enough that sums never overflow int64.
_FAR = np.int64(1) << 60


@dataclass(frozen=True)
class Assignment:
    """One scheduled object: its group, when carrying starts (M_p; with slower agents the first
    step ≥ M_p the whole group can move in) and when it is delivered."""

    object: int
    agents: tuple[int, ...]
    start: int
    finish: int

    def __repr__(self) -> str:
        # The text the dataclass would write, a third of its cost: a robot writes the whole
        # schedule's for each coordination's digest (docs/benchmarks.md)
        return f"Assignment(object={self.object!r}, agents={self.agents!r}, start={self.start!r}, finish={self.finish!r})"


@dataclass
class CoordinationResult:
    schedule: list[Assignment]
    cost: np.ndarray  # CA_j after scheduling, per agent (same order as the input)
    loc: np.ndarray  # (N, 2) location of each agent when it becomes free
    selections: np.ndarray  # (rounds, N): object id each agent selected in each round


def _reach(
    cost: np.ndarray, loc: np.ndarray, where: np.ndarray, period: np.ndarray | None = None
) -> np.ndarray:
    """C[i, j] = cost_j + |where_i - loc_j|_1 for objects i (rows) and agents j (columns); for
    agents of period k, when the d moves started at cost_j are done (``arrival``)."""
    dist = np.abs(where[:, None, 0] - loc[None, :, 0]) + np.abs(where[:, None, 1] - loc[None, :, 1])
    if period is None:
        return cost[None, :] + dist
    return arrival_np(cost[None, :], dist, period[None, :])


def carry_times(m_p: int, carry: int, periods: Sequence[int] | np.ndarray) -> tuple[int, int]:
    """(start, finish) of a carry whose group is complete at m_p: the group moves in the steps
    all its members can move in (unit speed: m_p, m_p + carry)."""
    k = group_period(periods)
    start = -(-m_p // k) * k
    return start, arrival(m_p, carry, k)


def coordinate(
    agent_ids: Sequence[int],
    cost: ArrayLike,
    loc: ArrayLike,
    objects: Sequence[ObjectSpec],
    periods: Sequence[int] | None = None,
) -> CoordinationResult:
    """Schedule ``objects`` on the agents whose free time is ``cost`` and position ``loc``.

    ``agent_ids`` must be ascending (the tie-break order). Returns the schedule in scheduling
    order. Cost per round is O(M·N) numpy work on the agents just assigned. ``periods``: each
    agent moves every k steps (None: the paper's unit speed).
    """
    ids = np.asarray(agent_ids, dtype=np.int64)
    if ids.size and np.any(np.diff(ids) <= 0):
        raise ValueError("agent ids must be strictly ascending")
    ca = np.array(cost, dtype=np.int64).reshape(-1)  # CA_j, updated as objects are scheduled
    at = np.array(loc, dtype=np.int64).reshape(-1, 2)  # loc_j, likewise
    n = ids.size
    if ca.size != n or at.shape[0] != n:
        raise ValueError("agent_ids, cost and loc must have one entry per agent")
    objs = sorted(objects, key=lambda o: o.id)
    m = len(objs)
    selections = np.full((m, n), -1, dtype=np.int64)
    if m == 0:
        return CoordinationResult([], ca, at, selections)
    need = np.array([o.required for o in objs], dtype=np.int64)
    if need.max() > n or need.min() < 1:
        bad = next(o for o in objs if not 1 <= o.required <= n)
        raise ValueError(f"object {bad.id} needs {bad.required} agents; the team has {n}")
    obj_ids = np.array([o.id for o in objs], dtype=np.int64)
    where = np.array([o.location for o in objs], dtype=np.int64)
    dest = np.array([o.destination for o in objs], dtype=np.int64)
    carry = np.abs(where - dest).sum(axis=1)

    per = None if periods is None else np.asarray(periods, dtype=np.int64).reshape(-1)
    if per is not None and (per.size != n or np.any(per < 1)):
        raise ValueError("periods must give every agent a period >= 1")
    reach = _reach(ca, at, where, per)  # (M, N); rows of scheduled objects are set to _FAR
    alive = np.ones(m, dtype=bool)
    schedule: list[Assignment] = []
    for r in range(m):
        # Step 1: every agent selects its cost-optimal object (argmin: first = lowest id).
        choice = np.argmin(reach, axis=0)
        selections[r] = obj_ids[choice]
        # Step 2: M_i for each selected object; Opt = the smallest (first = lowest id).
        cand = np.unique(choice)
        ordered = np.sort(reach[cand], axis=1)
        m_i = ordered[np.arange(cand.size), need[cand] - 1]
        k = int(np.argmin(m_i))
        p, m_p = int(cand[k]), int(m_i[k])
        # Step 3: the n_p cheapest agents (stable sort: ties to the lower agent id).
        group = np.sort(np.argsort(reach[p], kind="stable")[: need[p]])
        start, finish = carry_times(m_p, int(carry[p]), () if per is None else per[group])
        ca[group] = finish
        at[group] = dest[p]
        schedule.append(Assignment(int(obj_ids[p]), tuple(int(a) for a in ids[group]), start, finish))
        alive[p] = False
        # Only the group's columns changed; scheduled rows stay out of every argmin.
        reach[:, group] = np.where(
            alive[:, None], _reach(ca[group], at[group], where, None if per is None else per[group]), _FAR
        )
        reach[p] = _FAR
    return CoordinationResult(schedule, ca, at, selections)


def order_groups(
    agent_ids: Sequence[int],
    cost: ArrayLike,
    loc: ArrayLike,
    objects: Sequence[ObjectSpec],
    groups: dict[int, tuple[int, ...]],
    periods: Sequence[int] | None = None,
) -> CoordinationResult:
    """Schedule objects whose groups are already agreed (NCP): Algorithm Coordination's steps 2
    and 3 with the group of each object fixed.

    Each round, M_i = max over o_i's group of C_ij (when its last member could arrive); the
    object with the smallest M_i (ties: lower id) is scheduled next and its group's CA and loc
    updated exactly as in :func:`coordinate`. One global order that every group member follows,
    so execution cannot deadlock and starts exactly when planned.
    """
    ids = np.asarray(agent_ids, dtype=np.int64)
    ca = np.array(cost, dtype=np.int64).reshape(-1)  # CA_j, updated as objects are scheduled
    at = np.array(loc, dtype=np.int64).reshape(-1, 2)  # loc_j, likewise
    index = {int(a): k for k, a in enumerate(ids)}
    objs = sorted(objects, key=lambda o: o.id)
    m = len(objs)
    if m == 0:
        return CoordinationResult([], ca, at, np.zeros((0, ids.size), dtype=np.int64))
    member = np.zeros((m, ids.size), dtype=bool)
    for r, o in enumerate(objs):
        g = groups.get(o.id, ())
        if len(g) != o.required or len(set(g)) != len(g) or any(a not in index for a in g):
            raise ValueError(f"object {o.id} needs {o.required} distinct team members, got {list(g)}")
        member[r, [index[a] for a in g]] = True
    obj_ids = np.array([o.id for o in objs], dtype=np.int64)
    where = np.array([o.location for o in objs], dtype=np.int64)
    dest = np.array([o.destination for o in objs], dtype=np.int64)
    carry = np.abs(where - dest).sum(axis=1)
    per = None if periods is None else np.asarray(periods, dtype=np.int64).reshape(-1)
    reach = _reach(ca, at, where, per)
    alive = np.ones(m, dtype=bool)
    schedule: list[Assignment] = []
    for _ in range(m):
        m_i = np.where(member, reach, -1).max(axis=1)
        m_i[~alive] = _FAR
        p = int(np.argmin(m_i))  # first minimum: the lower object id
        m_p = int(m_i[p])
        group = np.flatnonzero(member[p])
        start, finish = carry_times(m_p, int(carry[p]), () if per is None else per[group])
        ca[group] = finish
        at[group] = dest[p]
        schedule.append(Assignment(int(obj_ids[p]), tuple(int(a) for a in ids[group]), start, finish))
        alive[p] = False
        reach[:, group] = _reach(ca[group], at[group], where, None if per is None else per[group])
    return CoordinationResult(schedule, ca, at, np.zeros((0, ids.size), dtype=np.int64))


# ----------------------------------------------------------------------------- triggers


ORGANISATIONS = ("distributed", "coordinator")


@dataclass(frozen=True)
class CoordinationPolicy:
    """When to coordinate (paper §3.1). One trigger is active; the end of the whole search
    always triggers a final coordination of whatever is left.

    - ``ci``: when the number of found-but-unscheduled objects reaches CI (the paper's choice);
    - ``interval``: every T time steps (common clock);
    - ``area_fraction``: each time another fraction f of the whole area has been searched.
    """

    ci: int = 1
    interval: int | None = None
    area_fraction: float | None = None
    # Who runs Algorithm Coordination (paper §3): every agent on shared knowledge
    # (``distributed``, CCP's point), or the lowest-id agent alone, which broadcasts the schedule
    # (``coordinator``: one step later, so schedules then start a step later too).
    organisation: str = "distributed"

    def __post_init__(self) -> None:
        if self.organisation not in ORGANISATIONS:
            raise ValueError(
                f"organisation must be one of {', '.join(ORGANISATIONS)}, got {self.organisation!r}"
            )
        if self.ci < 1:
            raise ValueError(f"CI must be at least 1, got {self.ci}")
        if self.interval is not None and self.interval < 1:
            raise ValueError(f"interval must be at least 1 step, got {self.interval}")
        if self.area_fraction is not None and not 0 < self.area_fraction <= 1:
            raise ValueError(f"area fraction must be in (0, 1], got {self.area_fraction}")
        if self.interval is not None and self.area_fraction is not None:
            raise ValueError("choose one trigger: interval or area fraction")

    @property
    def name(self) -> str:
        if self.interval is not None:
            name = f"interval={self.interval}"
        elif self.area_fraction is not None:
            name = f"area={self.area_fraction:g}"
        else:
            name = f"CI={self.ci}"
        return name if self.organisation == "distributed" else f"{name}, coordinator"

    @property
    def centralised(self) -> bool:
        return self.organisation == "coordinator"

    def due(self, t: int, unscheduled: int, searched_before: float, searched_now: float) -> bool:
        """Whether a coordination point is reached in step ``t`` (before the final one).

        ``searched_before``/``searched_now``: the fraction of the whole sweep done at the
        previous and at this step (all agents compute it the same way from the common clock).
        """
        if unscheduled == 0:
            return False
        if self.interval is not None:
            return (t + 1) % self.interval == 0
        if self.area_fraction is not None:
            f = self.area_fraction
            return int(searched_now / f + 1e-9) > int(searched_before / f + 1e-9)
        return unscheduled >= self.ci

    def due_in(self, t: int, unscheduled: int, team: TeamInfo) -> bool:
        """:meth:`due` with the team's searched fractions, computed only for the area trigger
        (a comm module asks in every step; the other triggers never read them)."""
        if self.area_fraction is None or self.interval is not None or unscheduled == 0:
            return self.due(t, unscheduled, 0.0, 0.0)
        return self.due(t, unscheduled, team.searched_fraction(t - 1), team.searched_fraction(t))

    def next_due(self, t: int, unscheduled: int, team: TeamInfo) -> int | None:
        """The first step s >= t at which :meth:`due` holds while nothing new is found (None:
        never) — the step a comm module next coordinates on its own."""
        if unscheduled == 0:
            return None
        if self.interval is not None:
            return t + (-(t + 1)) % self.interval
        if self.area_fraction is None:
            return t if unscheduled >= self.ci else None
        end = int(team.sweep_lengths().max()) + 1  # from here on the fraction stays 1
        if t > end:
            return None
        ts = np.arange(t, end + 1)
        now, before = team.searched_fractions(ts), team.searched_fractions(ts - 1)
        f = self.area_fraction
        # a superset (loose tolerance); the exact test decides
        for s in ts[np.floor(now / f + 1e-6) > np.floor(before / f - 1e-6)]:
            s = int(s)
            if self.due_in(s, unscheduled, team):
                return s
        return None
