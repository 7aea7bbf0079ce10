"""The event engine for any protocol: the step engine's run, without stepping every agent every
step. Results are identical to :func:`ost_ros.engines.step.run_steps` (property-tested).

Each agent's ``plan`` says what it does while nothing happens (:mod:`ost_ros.protocols.plans`).
Whenever every agent's first segment is settled and no message is in flight, the engine jumps to
the next step at which some agent decides something — an own plan's segment ends, an object the
agent reacts to comes into its sensor range (the engine knows where the objects lie), or its comm
module acts on its own (a coordination trigger) — moving agents, objects and the per-agent
accounts in bulk. In a step where some agent decides, only the deciders act (with every member
of a carrying group any of them belongs to, so the group pulls together); the others make their
quiet step in bulk. A message invalidates every agent's plan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ost_ros.engines.common import finish_result, step_limit
from ost_ros.messages import Action, AgentMessage, ObjectInfo
from ost_ros.model import Cell, Scenario, arrival
from ost_ros.protocols import plans as pl
from ost_ros.protocols.base import ProtocolAgent
from ost_ros.result import RunResult
from ost_ros.sensing import first_sensing
from ost_ros.world import World

Quiet = tuple[pl.Segment, int | None] | None  # an agent's settled first segment and its length


@dataclass
class _Hits:
    """Where along a sweep path each object first comes into sensor range (ground truth: the
    engine knows where objects lie; an object moves only once some agent knows of it)."""

    objects: list[ObjectInfo]
    cells: np.ndarray
    _cache: dict[int, tuple[object, list[tuple[int, ObjectInfo]]]]

    @classmethod
    def of(cls, scenario: Scenario) -> _Hits:
        cells = np.array([o.location for o in scenario.objects], dtype=np.int64).reshape(-1, 2)
        return cls(list(scenario.objects), cells, {})

    def along(self, path) -> list[tuple[int, ObjectInfo]]:
        key = id(path)
        hit = self._cache.get(key)
        if hit is None or hit[0] is not path:
            idx = first_sensing(np.asarray(path, dtype=np.int64).reshape(-1, 2), self.cells)
            hit = (
                path,
                sorted(
                    ((int(i), o) for i, o in zip(idx, self.objects) if i >= 0), key=lambda h: (h[0], h[1].id)
                ),
            )
            self._cache[key] = hit
        return hit[1]

    def next(self, seg: pl.Segment, agent: ProtocolAgent) -> int | None:
        """The first path index from ``seg.index`` at which the agent senses news."""
        for i, o in self.along(seg.path):
            if i >= seg.index and agent.news(o):
                return i
        return None


def _quiet(agent: ProtocolAgent, world: World, hits: _Hits) -> Quiet:
    """The agent's settled first segment and how many steps of it are safe (None: it decides now)."""
    plan = agent.plan(world.t, world.positions[agent.id])
    if not plan.settled:
        return None
    seg, steps = plan[0], plan[0].steps
    if seg.kind == "sweep":
        hit = hits.next(seg, agent)
        if hit is not None:
            until = arrival(world.t, hit - seg.index, seg.period) - world.t
            steps = until if steps is None else min(steps, until)
    return None if steps is not None and steps <= 0 else (seg, steps)


def _plans(
    agents: list[ProtocolAgent],
    world: World,
    hits: _Hits,
    cache: list[Quiet],
    fresh: list[bool],
    wakes: list[int | None],
) -> list[Quiet]:
    """Per agent its quiet segment, or None if it acts for real this step. ``cache`` holds
    still-valid ones (``fresh`` False) and is updated in place, with each agent's next comm event."""
    groups: dict[int, list[int]] = {}
    for j, ag in enumerate(agents):
        if fresh[j]:
            cache[j] = _quiet(ag, world, hits)
            wakes[j] = ag.next_event(world.t)
            fresh[j] = cache[j] is None
        g = ag.group()
        if g is not None:
            groups.setdefault(g, []).append(j)
    plans = list(cache)
    # The world settles an object's group together: if the group is complete (it moves now) or
    # any member decides (e.g. arrives), every member holding or carrying it acts for real.
    for oid, members in groups.items():
        holding = sum(1 for j in members if (q := plans[j]) is not None and q[0].kind == "hold")
        if holding >= world.objects[oid].spec.required or any(plans[j] is None for j in members):
            for j in members:
                q = plans[j]
                if q is None or q[0].kind in ("hold", "carry"):
                    plans[j] = None
    # A carry moves only with its whole group: if fewer than n_i carriers of an object are quiet
    # (another one joins by acting for real, e.g. after delivering its last object), all act.
    carriers: dict[int, list[int]] = {}
    for j, q in enumerate(plans):
        if q is not None and q[0].kind == "carry":
            carriers.setdefault(q[0].object, []).append(j)
    for oid, js in carriers.items():
        if len(js) < world.objects[oid].spec.required:
            for j in js:
                plans[j] = None
    return plans


def _age(cache: list[Quiet], fresh: list[bool], plans: list[Quiet], t: int, k: int) -> None:
    """Plans after k quiet steps from step t: what is left of them (renewed once used up)."""
    for j, q in enumerate(plans):
        if q is None or (q[1] is not None and q[1] - k <= 0):
            fresh[j] = True
        else:
            cache[j] = (pl.rest(q[0], t, k), None if q[1] is None else q[1] - k)


def _advance(agents: list[ProtocolAgent], plans: list[Quiet], world: World, k: int) -> None:
    """Apply k quiet steps of the given agents at once: the same moves and accounts the step
    engine would make (without advancing the clock)."""
    t = world.t
    carried: dict[int, tuple[pl.Segment, list[ProtocolAgent]]] = {}
    for ag, q in zip(agents, plans):
        assert q is not None
        seg = q[0]
        pos = world.positions[ag.id]
        if seg.kind in ("sweep", "walk"):
            new, moves = pl.advance(seg, t, pos, k)
            world.bulk_walk(ag.id, new, k, moves, seg.state)
            ag.skip(t + k, new, seg, k)
        elif seg.kind == "carry":
            carried.setdefault(seg.object, (seg, []))[1].append(ag)
        else:
            world.bulk_wait(ag.id, k, seg.state, seg.object if seg.kind == "hold" else None)
            ag.skip(t + k, pos, seg, k)
    for oid, (seg, group) in carried.items():
        at: Cell = world.objects[oid].at
        new, moves = pl.advance(seg, t, at, k)
        world.bulk_carry(oid, [ag.id for ag in group], new, k, moves, -(-t // seg.period) * seg.period)
        for ag in group:
            ag.skip(t + k, new, seg, k)


def run_events(scenario: Scenario, agents: list[ProtocolAgent], max_steps: int | None = None) -> RunResult:
    """Run ``agents`` decision to decision; the same result as the step engine."""
    world = World(scenario)
    hits = _Hits.of(scenario)
    limit = max_steps if max_steps is not None else step_limit(scenario)
    messages = 0
    n = len(agents)
    cache: list[Quiet] = [None] * n
    fresh = [True] * n
    wakes: list[int | None] = [None] * n
    while not world.done and world.t < limit:
        plans = _plans(agents, world, hits, cache, fresh, wakes)
        t = world.t
        if all(q is not None for q in plans):
            # Everyone quiet: jump to the first step at which someone decides something.
            spans = [q[1] for q in plans if q is not None and q[1] is not None]
            spans += [w - t + 1 for w in wakes if w is not None]
            k = min([*spans, limit - t])
            _advance(agents, plans, world, k)
            _age(cache, fresh, plans, t, k)
            world.pass_steps(k)
            for j, w in enumerate(wakes):  # a comm module acting on its own in the last step
                if w == t + k - 1:
                    agents[j].communicate(w, [])
                    fresh[j] = True
            continue
        # A deciding step: deciders (with their whole carrying group) act for real; the other
        # quiet agents make their one quiet step in bulk.
        acting = [q is None for q in plans]
        actions: list[Action] = [ag.act(world.observe(ag.id)) for ag, a in zip(agents, acting) if a]
        inbox: list[AgentMessage] = [m for ag, a in zip(agents, acting) if a for m in ag.outbox()]
        messages += len(inbox)
        for j, ag in enumerate(agents):  # an empty step changes no one's knowledge, unless due
            if inbox or wakes[j] == t:
                ag.communicate(t, inbox)
        _advance(
            [ag for ag, a in zip(agents, acting) if not a],
            [q for q, a in zip(plans, acting) if not a],
            world,
            1,
        )
        if inbox:
            fresh[:] = [True] * n  # messages may change anyone's plan
        else:
            _age(cache, fresh, plans, t, 1)  # deciders (None) are planned afresh
            for j in range(n):
                if wakes[j] == t:
                    fresh[j] = True
        world.apply(actions)
    return finish_result(world, agents, messages)
