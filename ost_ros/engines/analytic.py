"""The analytic engine of protocols in which every agent holds the same public state (capability
``team_knowledge``: CCP, NCP, the auction): one comm module — the spec's ``team_comm``, speaking
for every agent — computes the whole run. Results are identical to
the step engine's (property-tested).

Planned = executed, so the schedule determines execution and the run follows from its events
alone: found times come from the sweeps (agent j stands on ``path_j[i]`` after i moves and senses
its 3×3); the protocol's team comm module (speaking for every agent) is fed the messages of a
step only at the steps where something can happen — a find, a search end, a step in which the
module acts on its own (a trigger, a negotiation round), or messages it sent the step before;
then each agent's timeline (travel, hold, carry, return) follows from its assignments.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import AgentMessage, ObjectFound, SearchDone
from ost_ros.model import Cell, Scenario, arrival, arrival_np, manhattan
from ost_ros.protocols.base import ProtocolSpec
from ost_ros.result import AgentRecord, ObjectRecord, RunResult
from ost_ros.sensing import first_sensings, sweep_paths
from ost_ros.team import TeamInfo


@lru_cache(maxsize=4)
def _sensing(scenario: Scenario) -> tuple[TeamInfo, list[np.ndarray], np.ndarray, np.ndarray]:
    """Team, sweep paths, each object's found time and how many agents sense it then (one
    scenario is typically run under several triggers: computed once)."""
    team = TeamInfo.from_scenario(scenario)
    paths = sweep_paths(scenario)
    # first[j, i]: when agent j first senses object i during its search (-1: never): it stands
    # on path[idx] from arrival(0, idx, k_j) on (k_j = 1: time = index).
    first = first_sensings(scenario)
    k = team.period_array()[:, None]
    first = np.where(first >= 0, arrival_np(np.zeros_like(first), first, k), -1)
    masked = np.where(first >= 0, first, np.iinfo(np.int64).max)
    if not scenario.objects:
        return team, paths, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    found = masked.min(axis=0)
    return team, paths, found, (masked == found[None, :]).sum(axis=0)


def run_analytic(
    scenario: Scenario, spec: ProtocolSpec, policy: CoordinationPolicy, settings: Any = None
) -> RunResult:
    """The run of protocol ``spec`` (with a team comm module) computed from its events."""
    assert spec.team_comm is not None
    team, paths, found, finders = _sensing(scenario)
    ids = team.agent_ids
    lengths = [int(x) for x in team.sweep_lengths()]  # when each search ends
    objs = list(scenario.objects)

    events: dict[int, list[AgentMessage]] = {}
    for i, o in enumerate(objs):
        events.setdefault(int(found[i]), []).append(ObjectFound(-1, int(found[i]), o))
    for j, length in enumerate(lengths):
        events.setdefault(length, []).append(SearchDone(ids[j], length))
    comm = spec.team_comm(team, policy, spec.default_settings() if settings is None else settings)
    sent = 0
    pending = sorted(events)
    k, t = 0, -1
    inflight: list[AgentMessage] = []
    closed_at: int | None = None
    while True:
        # The next step with news: an event, the module's own next act, or messages in flight.
        due = comm.next_event(t + 1)
        nxt = [
            s
            for s in (pending[k] if k < len(pending) else None, due, t + 1 if inflight else None)
            if s is not None
        ]
        if not nxt:
            break
        t = min(nxt)
        while k < len(pending) and pending[k] <= t:
            k += 1
        comm.receive(t, inflight + events.get(t, []))
        inflight = comm.drain()
        sent += len(inflight)
        if comm.closed and closed_at is None:
            closed_at = t
        if comm.closed and not inflight:
            break
    assert closed_at is not None, "the team's comm module never closed"
    know = comm.knowledge
    records = _timelines(team, paths, lengths, closed_at, know.schedule, {o.id: o for o in objs})
    by_obj = {a.object: a for a in know.schedule}
    objects = [ObjectRecord(o.id, by_obj[o.id].agents, by_obj[o.id].start, by_obj[o.id].finish) for o in objs]
    return RunResult(
        makespan=max(r.finished or 0 for r in records),
        last_delivery=max((a.finish for a in know.schedule), default=0),
        completed=True,
        steps=max(r.finished or 0 for r in records) + 1,
        agents=records,
        objects=objects,
        rejections=[],
        protocol=spec.name,
        trigger=comm.trigger,
        predicted_makespan=know.predicted_makespan,
        coordinations=know.coordinations,
        messages=int(finders.sum()) + len(ids) + sent,
        agreement=True,
        warnings=[f"agent {comm.me}: {w}" for w in know.warnings],
        found={o.id: int(found[i]) for i, o in enumerate(objs)},
        schedule=list(know.schedule),
    )


def _timelines(
    team: TeamInfo, paths: list[np.ndarray], lengths: list[int], closed_at: int, schedule: list, objects: dict
) -> list[AgentRecord]:
    """Each agent's account from its assignments (planned = executed): search L_j; travel = the
    walks to its objects and the way home; carry = the carry lengths; finish = max(last delivery,
    the closing step + 1) + the way home; idle = the rest."""
    ids = team.agent_ids
    walked = [int(x) for x in team.sweep_moves()]  # the cells its search walks
    periods = [int(x) for x in team.period_array()]
    free = list(lengths)
    loc: list[Cell] = [(int(p[-1][0]), int(p[-1][1])) for p in paths]
    travel = [0] * len(ids)
    carry = [0] * len(ids)
    for a in schedule:
        for agent in a.agents:
            j = team.index(agent)
            o = objects[a.object]
            travel[j] += manhattan(loc[j], o.location)
            carry[j] += manhattan(o.location, o.destination)
            free[j] = a.finish
            loc[j] = o.destination
    records = []
    for j, agent in enumerate(ids):
        home = manhattan(loc[j], team.bases[j])
        finished = arrival(max(free[j], closed_at + 1), home, periods[j])
        travel[j] += home
        idle = finished - walked[j] - travel[j] - carry[j]
        records.append(AgentRecord(agent, finished, idle, carry[j], walked[j], travel[j]))
    return records
