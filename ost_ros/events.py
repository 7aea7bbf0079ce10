"""Event-driven engine: the same runs as the step simulator, without stepping every agent every
step. Results are identical to :func:`ost_ros.simulator.simulate` (property-tested event by event).

- **CCP** (planned = executed): a schedule fully determines execution, so the run is computed
  from its events alone. Found times come from the sweeps (agent j stands on ``path_j[t]`` at
  time t ≤ L_j and senses its 3×3); the comm module itself (:class:`~ost_ros.comm.CcpComm`) is
  fed the step's messages only at the steps where something can happen (a find, a search end, an
  interval or area trigger); then each agent's timeline (travel, hold, carry, return) follows
  from its assignments.
- **HCP** (decisions depend on who is where when): the real agents and world are stepped, but
  whenever every agent is *quiet* — walking, sweeping with nothing new in sensor range, holding,
  carrying, waiting — and no message is in flight, the engine jumps to the next step at which
  some agent decides something, moving agents, objects and the per-agent accounts in bulk.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ost_msgs_py.messages import ObjectFound, SearchDone
from ost_ros.comm import CcpComm
from ost_ros.coordination import CoordinationPolicy
from ost_ros.hcp import HcpState
from ost_ros.model import Cell, Scenario, arrival, arrival_np, manhattan
from ost_ros.ncp import NcpComm, NegotiationSettings
from ost_ros.result import AgentRecord, ObjectRecord, RunResult
from ost_ros.search import agent_plan, route
from ost_ros.team import TeamInfo
from ost_ros.world import World


def sweep_paths(scenario: Scenario) -> list[np.ndarray]:
    """Each agent's cell-by-cell search path ((L_j + 1) × 2): it stands on row t at time t."""
    return list(_paths(scenario.subareas, tuple(a.base for a in scenario.agents),
                       tuple(a.sweep for a in scenario.agents)))


@lru_cache(maxsize=8)
def _paths(areas: tuple, bases: tuple, sweeps: tuple) -> tuple[np.ndarray, ...]:
    # A study runs many object sets on one team: the sweeps are computed once per team.
    out = []
    for area, base, sweep in zip(areas, bases, sweeps):
        path = np.array(route(agent_plan(area, base, sweep)), dtype=np.int64).reshape(-1, 2)
        path.flags.writeable = False
        out.append(path)
    return tuple(out)


def first_sensing(path: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """For each cell, the first index of ``path`` whose 3×3 block covers it (-1: never)."""
    if len(cells) == 0:
        return np.zeros(0, dtype=np.int64)
    out = np.full(len(cells), -1, dtype=np.int64)
    lo, hi = path.min(axis=0) - 1, path.max(axis=0) + 1
    near = np.all((cells >= lo) & (cells <= hi), axis=1)
    for k in np.flatnonzero(near):
        cover = np.max(np.abs(path - cells[k]), axis=1) <= 1
        hit = int(np.argmax(cover))
        if cover[hit]:
            out[k] = hit
    return out


# ----------------------------------------------------------------------------- CCP


def _trigger_steps(team: TeamInfo, policy: CoordinationPolicy, end: int) -> set[int]:
    """Steps t < end at which the interval or area trigger can fire (the CI trigger fires only
    at finds, which are events anyway)."""
    if policy.interval is not None:
        return set(range(policy.interval - 1, end, policy.interval))
    if policy.area_fraction is not None and end > 0:
        moves = team.sweep_moves()
        total = int(moves.sum())
        if total == 0:
            return set()
        ts = np.arange(end)
        steps = -(-ts[:, None] // team.period_array()[None, :])   # movable steps before t
        done = np.minimum(moves[None, :], steps).sum(axis=1) / total
        before = np.concatenate([[0.0], done[:-1]])  # fraction at max(t-1, 0)
        f = policy.area_fraction
        # A superset (loose tolerance): the comm module makes the exact decision at these steps.
        fire = np.floor(done / f + 1e-6) > np.floor(before / f - 1e-6)
        return set(int(t) for t in ts[fire])
    return set()


@lru_cache(maxsize=4)
def _ccp_sensing(scenario: Scenario) -> tuple[TeamInfo, list[np.ndarray], np.ndarray, np.ndarray]:
    """Team, sweep paths, each object's found time and how many agents sense it then (one
    scenario is typically run under several triggers: computed once)."""
    team = TeamInfo.from_scenario(scenario)
    paths = sweep_paths(scenario)
    locs = np.array([o.location for o in scenario.objects], dtype=np.int64).reshape(-1, 2)
    # first[j, i]: when agent j first senses object i during its search (-1: never): it stands
    # on path[idx] from arrival(0, idx, k_j) on (k_j = 1: time = index).
    first = np.array([first_sensing(p, locs) for p in paths], dtype=np.int64).reshape(len(paths), -1)
    k = team.period_array()[:, None]
    first = np.where(first >= 0, arrival_np(np.zeros_like(first), first, k), -1)
    masked = np.where(first >= 0, first, np.iinfo(np.int64).max)
    if not scenario.objects:
        return team, paths, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    found = masked.min(axis=0)
    return team, paths, found, (masked == found[None, :]).sum(axis=0)


def simulate_ccp(scenario: Scenario, policy: CoordinationPolicy,
                 ncp: NegotiationSettings | None = None) -> RunResult:
    """CCP (one comm module stands for all: they agree by construction) or, with ``ncp``, NCP
    (every agent's comm module, fed each step while a negotiation runs: moves are messages)."""
    team, paths, found, finders = _ccp_sensing(scenario)
    ids = team.agent_ids
    lengths = [int(x) for x in team.sweep_lengths()]       # when each search ends
    walked = [int(x) for x in team.sweep_moves()]          # the cells it walks
    periods = [int(x) for x in team.period_array()]
    objs = list(scenario.objects)

    events: dict[int, list] = {}
    for i, o in enumerate(objs):
        events.setdefault(int(found[i]), []).append(ObjectFound(-1, int(found[i]), o))
    for j, length in enumerate(lengths):
        events.setdefault(length, []).append(SearchDone(ids[j], length))
    close = max(lengths)
    for t in _trigger_steps(team, policy, close):
        events.setdefault(t, [])
    if ncp is None:
        comms = [CcpComm(ids[0], team, policy)]
    else:   # one NCP module holding the public state and making every agent's move
        comms = [NcpComm(ids[0], team, policy, settings=ncp, voices=ids)]
    comm = comms[0]
    moves = 0
    pending = sorted(events)
    k, t, inflight = 0, -1, []
    while k < len(pending) or inflight or (ncp is not None and comm.busy):
        # A step with news: the next event, or the very next step while moves are in flight.
        t = t + 1 if inflight or (ncp is not None and comm.busy) else pending[k]
        while k < len(pending) and pending[k] <= t:
            k += 1
        inbox = inflight + events.get(t, [])
        for c in comms:
            c.receive(t, inbox)
        inflight = [m for c in comms for m in c.drain()] if ncp is not None else []
        for c in comms:
            c.drain()
        moves += len(inflight)
        if comm.closed and not inflight:
            break
    if ncp is not None:
        closed_at = t
    else:
        closed_at = close

    # Each agent's timeline from its assignments (planned = executed).
    records: list[AgentRecord] = []
    free = list(lengths)
    loc: list[Cell] = [tuple(int(v) for v in p[-1]) for p in paths]
    travel = [0] * len(ids)
    carry = [0] * len(ids)
    spec = {o.id: o for o in objs}
    for a in comm.schedule:
        for agent in a.agents:
            j = team.index(agent)
            o = spec[a.object]
            travel[j] += manhattan(loc[j], o.location)
            carry[j] += manhattan(o.location, o.destination)
            free[j] = a.finish
            loc[j] = o.destination
    for j, agent in enumerate(ids):
        home = manhattan(loc[j], team.bases[j])
        finished = arrival(max(free[j], closed_at + 1), home, periods[j])
        travel[j] += home
        idle = finished - walked[j] - travel[j] - carry[j]
        records.append(AgentRecord(agent, finished, idle, carry[j], walked[j], travel[j]))
    by_obj = {a.object: a for a in comm.schedule}
    objects = [ObjectRecord(o.id, by_obj[o.id].agents, by_obj[o.id].start, by_obj[o.id].finish)
               for o in objs]
    makespan = max(r.finished for r in records)
    if ncp is None:
        messages = int(finders.sum()) + len(ids) + len(ids) * comm.coordinations
    else:
        messages = int(finders.sum()) + len(ids) + moves
    agreement = all(c.schedule == comm.schedule for c in comms)
    return RunResult(
        makespan=makespan, last_delivery=max((a.finish for a in comm.schedule), default=0),
        completed=True, steps=makespan + 1, agents=records, objects=objects, rejections=[],
        protocol="ccp" if ncp is None else "ncp", trigger=policy.name,
        predicted_makespan=comm.predicted_makespan,
        coordinations=comm.coordinations, messages=messages, agreement=agreement,
        warnings=[f"agent {c.me}: {w}" for c in comms for w in c.warnings],
        found={o.id: int(found[i]) for i, o in enumerate(objs)}, schedule=list(comm.schedule))


# ----------------------------------------------------------------------------- HCP


def _walk(cur: Cell, target: Cell, k: int) -> Cell:
    """Where k x-first unit moves from ``cur`` toward ``target`` end."""
    dx = target[0] - cur[0]
    mx = min(k, abs(dx))
    x = cur[0] + (mx if dx > 0 else -mx)
    k -= mx
    dy = target[1] - cur[1]
    my = min(k, abs(dy))
    return (x, cur[1] + (my if dy > 0 else -my))


@dataclass
class _Sweeps:
    """Where each agent's search would next sense an own object not yet found (HCP owners)."""

    hits: list[list[tuple[int, int]]]   # per agent: sorted (path index, object id)

    @classmethod
    def of(cls, scenario: Scenario, paths: list[np.ndarray]) -> "_Sweeps":
        hits = []
        for area, path in zip(scenario.subareas, paths):
            own = [o for o in scenario.objects if area.contains(o.location)]
            cells = np.array([o.location for o in own], dtype=np.int64).reshape(-1, 2)
            idx = first_sensing(path, cells)
            hits.append(sorted((int(i), o.id) for i, o in zip(idx, own) if i >= 0))
        return cls(hits)

    def next_hit(self, j: int, index: int, known: dict) -> int | None:
        for i, oid in self.hits[j]:
            if i >= index and oid not in known:
                return i
        return None


_GROUP = frozenset((HcpState.HELPING, HcpState.WAITING, HcpState.MOVING))


def _plan(agents: list, sweeps: _Sweeps, world: World, cache: list) -> list:
    """Per agent: (Quiet, steps) if its act would be silent and state-preserving from now for
    ``steps`` steps (None: until a message), or None if it decides something now. ``cache``
    holds still-valid plans (None: recompute) and is updated in place."""
    plans: list = []
    groups: dict[int, list[int]] = {}
    for j, ag in enumerate(agents):
        plan = cache[j]
        if plan is None:
            ag.skip(world.t, world.positions[ag.id])   # the agent last saw its pre-move cell
            q = ag.quiet()
            steps = None if q is None else q.steps
            if q is not None and q.kind == "sweep":
                hit = sweeps.next_hit(j, ag.search.index, ag.comm.objects)
                end = len(ag.search.path) - 1
                steps = (hit if hit is not None and hit < end else end) - ag.search.index
            plan = None if q is None or (steps is not None and steps <= 0) else (q, steps)
            cache[j] = plan
        if ag.state in _GROUP:
            groups.setdefault(ag.current.id, []).append(j)
        plans.append(plan)
    # The world settles an object's group together: if the group is complete (it moves now) or
    # any member decides (e.g. arrives), every member holding or carrying it acts for real.
    for oid, members in groups.items():
        at = world.objects[oid].at
        waiting = sum(1 for j in members if agents[j].state is HcpState.WAITING
                      and world.positions[agents[j].id] == at)
        if (waiting >= world.objects[oid].spec.required
                or any(plans[j] is None for j in members)):
            for j in members:
                if agents[j].state is not HcpState.HELPING:
                    plans[j] = None
    return plans


def _age(cache: list, plans: list, k: int) -> None:
    """Plans after k quiet steps: the same, k steps shorter (None once used up)."""
    for j, plan in enumerate(plans):
        if plan is None or (plan[1] is not None and plan[1] - k <= 0):
            cache[j] = None
        else:
            cache[j] = plan if plan[1] is None else (plan[0], plan[1] - k)


def _advance(agents: list, plans: list, world: World, k: int) -> None:
    """Apply k quiet steps of the given agents at once: the same moves and accounts the step
    engine would make (without advancing the clock)."""
    carried: dict[int, tuple[Cell, list]] = {}
    t = world.t + k
    for ag, plan in zip(agents, plans):
        q = plan[0]
        rec = world.records[ag.id]
        pos = world.positions[ag.id]
        if q.kind == "sweep":
            new = ag.search.path[ag.search.index + k]
            rec.search += k
            world.positions[ag.id] = new
            ag.skip(t, new, k)
        elif q.kind == "walk":
            new = _walk(pos, q.target, k)
            rec.travel += k
            world.positions[ag.id] = new
            ag.skip(t, new)
        elif q.kind == "carry":
            carried.setdefault(ag.current.id, (q.target, []))[1].append(ag)
        else:   # wait / hold
            if q.kind == "hold" or rec.finished is None:
                rec.idle += k
            ag.skip(t, pos)
    for oid, (dest, group) in carried.items():
        obj = world.objects[oid]
        new = _walk(obj.at, dest, k)
        world._at[obj.at].discard(oid)
        obj.at = new
        if new == obj.spec.destination:
            obj.delivered = t
        else:
            world._at[new].add(oid)
        for ag in group:
            world.records[ag.id].carry += k
            world.positions[ag.id] = new
            ag.skip(t, new)


def simulate_hcp(scenario: Scenario, max_steps: int | None = None) -> RunResult:
    from ost_ros.simulator import finish_result, make_agents, step_limit

    policy = CoordinationPolicy()
    agents = make_agents(scenario, "hcp", policy)
    world = World(scenario)
    sweeps = _Sweeps.of(scenario, sweep_paths(scenario))
    limit = max_steps if max_steps is not None else step_limit(scenario)
    messages = 0
    cache: list = [None] * len(agents)
    while not world.done and world.t < limit:
        plans = _plan(agents, sweeps, world, cache)
        if all(p is not None for p in plans):
            # Everyone quiet: jump to the first step at which someone decides something.
            spans = [p[1] for p in plans if p[1] is not None]
            k = min(spans + [limit - world.t])
            _advance(agents, plans, world, k)
            _age(cache, plans, k)
            world.t += k
            continue
        # A deciding step: deciders (with their whole carrying group) act for real; the other
        # quiet agents make their one quiet step in bulk.
        acting = [p is None for p in plans]
        actions = [ag.act(world.observe(ag.id)) for ag, a in zip(agents, acting) if a]
        inbox = [m for ag, a in zip(agents, acting) if a for m in ag.outbox()]
        if inbox:   # an empty step changes no one's knowledge
            messages += len(inbox)
            for ag in agents:
                ag.communicate(world.t, inbox)
        _advance([ag for ag, a in zip(agents, acting) if not a],
                 [p for p, a in zip(plans, acting) if not a], world, 1)
        if inbox:
            cache[:] = [None] * len(agents)   # messages may change anyone's plan
        else:
            _age(cache, plans, 1)             # deciders (None) are planned afresh
        world.apply(actions)
    return finish_result(world, agents, "hcp", policy, messages)


def simulate_events(scenario: Scenario, protocol: str = "ccp",
                    policy: CoordinationPolicy | None = None,
                    max_steps: int | None = None,
                    ncp: NegotiationSettings | None = None) -> RunResult:
    """Event-driven run; the same result as the step simulator."""
    if protocol not in ("ccp", "hcp", "ncp"):
        raise ValueError(f"unknown protocol {protocol!r} (choose from ccp, hcp, ncp)")
    if protocol == "hcp":
        return simulate_hcp(scenario, max_steps)
    settings = (ncp or NegotiationSettings()) if protocol == "ncp" else None
    result = simulate_ccp(scenario, policy or CoordinationPolicy(), settings)
    if max_steps is not None and result.steps > max_steps:
        from ost_ros.simulator import simulate   # the reference reports where it stopped
        return simulate(scenario, protocol, policy, max_steps=max_steps, ncp=ncp)
    return result
