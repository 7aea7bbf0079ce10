"""The realtime runtimes wired in one process, on a discrete-event network with seeded latencies
(``ost sim SCENARIO --latency L[:J]``): the world's bases, every robot's runtime, and a network
whose copies of each message take L + U{0..J} steps, drawn per receiver. Agents are stepped only
by events — goal results, detections, messages, their timers — never by a loop over steps.

A robot's own base is reached without delay (it is the robot's own hardware: goals, results,
detections and feedback are immediate); only robot-to-robot messages and the world's failure
notices cross the network. A run ends when the world is done; with no event left before that it
is a deadlock, reported as a failed run (never a hang).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines.common import finish_result, step_limit
from ost_ros.model import Scenario
from ost_ros.negotiation.slots import NegotiationSettings
from ost_ros.protocols import ProtocolError, check
from ost_ros.realtime.agent import (
    AskFeedback,
    Output,
    Publish,
    RealtimeAgent,
    RtScheduleAgent,
    SendGoal,
    WakeAt,
)
from ost_ros.realtime.base import BaseMirror, mirror_of
from ost_ros.realtime.comms import RtAuctionComm, RtCcpComm, RtNcpComm
from ost_ros.realtime.messages import Digest, Mark, Need, ObjectInfo
from ost_ros.realtime.net import DELIVER, KILL, WAKE, WORLD, EventQueue, Latency, Network
from ost_ros.realtime.world import CarryStarted, Detection, Feedback, GoalResult, RealtimeWorld
from ost_ros.result import RunResult
from ost_ros.team import TeamInfo
from ost_ros.world import World

REALTIME = ("ccp", "ncp", "auction")
# Why the others do not run without a barrier (docs/realtime.md, "What each protocol guarantees").
REFUSED = {
    "hcp": "hcp does not run without a barrier: its requesters withdraw and ask again by what they "
    "see when, so a request staffed in a batch its requester has not read yet leaves helpers "
    "holding forever (no stamp rule fixes a decision taken on a stale view)",
    "improved": "--planner improved does not run without a barrier: it re-plans work no robot has "
    "taken up by predicted times, and a late robot may have taken it up already (a carry "
    "started with the old group)",
}


def check_realtime(protocol: str, policy: CoordinationPolicy | None = None, settings: Any = None) -> None:
    """One-line :class:`ProtocolError` if the protocol (or its options) cannot run without a
    barrier."""
    check(protocol, policy=policy)
    if protocol in REFUSED:
        raise ProtocolError(REFUSED[protocol])
    if protocol == "ccp" and getattr(settings, "planner", "paper") != "paper":
        raise ProtocolError(REFUSED["improved"])
    if protocol not in REALTIME:
        raise ProtocolError(f"{protocol} has no realtime runtime (realtime: {', '.join(REALTIME)})")


def make_agents(
    scenario: Scenario, protocol: str, policy: CoordinationPolicy, settings: Any = None
) -> list[RealtimeAgent]:
    """Every robot's realtime runtime, in id order."""
    check_realtime(protocol, policy, settings)
    check(protocol, scenario=scenario, policy=policy)
    team = TeamInfo.from_scenario(scenario)
    return [make_agent(team, a.id, protocol, policy, settings) for a in scenario.agents]


def make_agent(
    team: TeamInfo, agent_id: int, protocol: str, policy: CoordinationPolicy, settings: Any = None
) -> RealtimeAgent:
    """One robot's realtime runtime (an agent node builds its own; the protocol already checked)."""
    comm: RtCcpComm | RtNcpComm | RtAuctionComm
    if protocol == "ccp":
        comm = RtCcpComm(agent_id, team, policy)
    elif protocol == "ncp":
        comm = RtNcpComm(agent_id, team, policy, settings=settings or NegotiationSettings())
    else:
        comm = RtAuctionComm(agent_id, team, policy)
    return RealtimeAgent(RtScheduleAgent(agent_id, team, comm, protocol), team.agent_ids)


@dataclass
class RealtimeReport:
    """What the realtime run adds to the result: its network, agreement and lags."""

    latency: Latency
    seed: int
    speed_jitter: float
    stalls: tuple[tuple[int, float, float], ...]
    disagreements: int = 0  # batches whose coordination digests differ between agents
    coordinations: int = 0  # batches with a coordination, compared across agents
    lag: dict[int, float] = field(default_factory=dict)  # agent -> most a batch waited after its stamp
    marks: int = 0
    needs: int = 0
    copies: int = 0  # copies the network delivered
    events: int = 0  # events the run processed
    mirror_errors: list[str] = field(default_factory=list)  # (run_realtime(mirrors=True))

    def to_dict(self) -> dict[str, Any]:
        return {
            "mode": "realtime",
            "latency": [_n(self.latency.steps), _n(self.latency.jitter)],
            "latency_seed": self.seed,
            "speed_jitter": self.speed_jitter,
            "stalls": [list(s) for s in self.stalls],
            "disagreements": self.disagreements,
            "coordinations_compared": self.coordinations,
            "lag": {str(a): _n(v) for a, v in sorted(self.lag.items())},
            "network": {
                "marks": self.marks,
                "needs": self.needs,
                "copies": self.copies,
                "events": self.events,
            },
        }


def _n(x: float) -> Any:
    return int(x) if float(x).is_integer() else round(x, 3)


@dataclass
class _Run:
    world: RealtimeWorld
    agents: dict[int, RealtimeAgent]
    net: Network
    queue: EventQueue
    report: RealtimeReport
    live: set[int]
    digests: list[Digest] = field(default_factory=list)
    notices: dict[int, int] = field(default_factory=dict)  # failed agent -> its notice's stamp
    # Each robot's own picture of its base (as an agent node keeps it, from its base's events),
    # checked against the world at every decision: differences are listed here.
    mirrors: dict[int, BaseMirror] = field(default_factory=dict)
    mirror_errors: list[str] = field(default_factory=list)
    # How far behind its clock a robot knows its base's events (an agent node's base clock comes
    # that late): it commits no later than now - base_lag (0: its base is its own hardware).
    base_lag: float = 0.0
    declare_after: float = 0.0  # steps from a robot's death to the world's notice of it
    _ticks: dict[int, float] = field(default_factory=dict)  # agent -> its next base clock (base_lag)
    _world_times: set[float] = field(default_factory=set)

    def base_event(self, ev: Any) -> None:
        """A base's event for the robots' pictures (a tracking world's GoalStarted and Stalled go
        only there)."""
        if not self.mirrors:
            return
        if isinstance(ev, CarryStarted):
            for j in ev.group:
                if j in self.mirrors:
                    self.mirrors[j].take(ev)
        elif ev.agent in self.mirrors:
            sensed: tuple[ObjectInfo, ...] = ()
            if isinstance(ev, GoalResult) and ev.outcome in ("reached", "aborted"):
                sensed = self.world.feedback(ev.agent, ev.time).sensed
            self.mirrors[ev.agent].take(ev, sensed)

    def check_mirror(self, agent: int, fb: Feedback) -> None:
        m = self.mirrors.get(agent)
        if m is None:
            return
        mine = m.feedback(fb.time) if m.fresh else None
        if mine is None or (mine.time, mine.cell, mine.goal, mine.index, mine.carrying) != (
            fb.time,
            fb.cell,
            fb.goal,
            fb.index,
            fb.carrying,
        ):
            self.mirror_errors.append(f"agent {agent}: world {fb}, mirror {mine}")

    def dispatch(self, agent: int, outputs: list[Output], now: float) -> None:
        ra = self.agents[agent]
        for o in outputs:
            if agent not in self.live:
                return
            if isinstance(o, Publish):
                p = o.payload
                if isinstance(p, Mark):
                    self.report.marks += 1
                elif isinstance(p, Need):
                    self.report.needs += 1
                self.net.send(now, p, [j for j in sorted(self.live) if j != agent])
            elif isinstance(o, SendGoal):
                if agent in self.mirrors:
                    self.mirrors[agent].sent(o.id, o.goal)
                for r in self.world.goal(agent, o.id, o.goal, o.at):
                    self.base_event(r)
                    if isinstance(r, GoalResult):
                        self.dispatch(r.agent, self.agents[r.agent].on_result(r, now), now)
            elif isinstance(o, AskFeedback):
                fb = self.world.feedback(agent, o.at)
                self.check_mirror(agent, fb)
                self.dispatch(agent, ra.on_feedback(fb, now), now)
            elif isinstance(o, WakeAt):
                self.queue.push(max(o.time, now), WAKE, ("wake", agent))
            elif isinstance(o, Digest):
                self.digests.append(o)
        if self.base_lag and agent in self.live and ra.held(now) and self._ticks.get(agent, -1.0) <= now:
            # its base's clock tells it more base_lag later (an agent node's base clock)
            self._ticks[agent] = now + self.base_lag
            self.queue.push(now + self.base_lag, WAKE, ("wake", agent))
        self.schedule_world()

    def schedule_world(self) -> None:
        t = self.world.next_time()
        if t is not None and t not in self._world_times:
            self._world_times.add(t)
            self.queue.push(t, WORLD, ("world",))

    def world_events(self, now: float) -> None:
        self._world_times.discard(now)
        for ev in self.world.advance(now):
            self.base_event(ev)
            if isinstance(ev, GoalResult):
                if ev.agent in self.live:
                    self.dispatch(ev.agent, self.agents[ev.agent].on_result(ev, now), now)
            elif isinstance(ev, Detection):
                if ev.agent in self.live:
                    self.dispatch(ev.agent, self.agents[ev.agent].on_detection(ev, now), now)
            elif isinstance(ev, CarryStarted):
                for j in ev.group:
                    if j in self.live:
                        self.dispatch(j, self.agents[j].on_carry(ev, now), now)
        self.schedule_world()

    def loop(self, limit: float) -> tuple[str | None, float, float | None]:
        """Events in time order until the world is done at the end of a moment (as the lockstep
        world is at the end of a step: a robot finishing and one called back to work in the same
        moment leave it not done), nothing is left (a deadlock) or the limit passes. Returns
        (error, last time, end)."""
        queue, now = self.queue, 0.0
        while True:
            nxt = queue.peek()
            if (nxt is None or nxt > now + 1e-9) and self.world.done:
                return None, now, now
            if nxt is None:
                return (
                    f"deadlock: nothing left to happen at step {math.ceil(now)} and the run is not done",
                    now,
                    None,
                )
            t, phase, ev = queue.pop()
            if t > limit:
                return f"not finished after {limit} steps (deadlock or step limit)", now, None
            now = t
            self.report.events += 1
            if phase == WORLD:
                self.world_events(t)
            elif phase == KILL:
                (self.kill if ev[0] == "kill" else self.declare)(ev[1], t)
            elif phase == WAKE:
                if ev[1] in self.live:
                    ra = self.agents[ev[1]]
                    if self.base_lag:
                        ra.base_known(t - self.base_lag)
                    self.dispatch(ev[1], ra.start(t) if ev[0] == "start" else ra.on_clock(t), t)
            elif phase == DELIVER:
                receiver, payload = ev
                if receiver in self.live:
                    if self.base_lag:
                        self.agents[receiver].base_known(t - self.base_lag)
                    self.report.copies += 1
                    self.dispatch(receiver, self.agents[receiver].on_message(payload, t), t)

    def counted(self) -> int:
        """Protocol messages the team took in: a failed robot's count up to its notice's stamp
        (what it sent after its last watermark is dropped by everyone, as if never sent)."""
        n = 0
        for j, ra in self.agents.items():
            cut = self.notices.get(j, math.inf)
            n += sum(1 for s in ra.sent if s < cut)
        return n

    def kill(self, agent: int, now: float) -> None:
        """The robot is gone; the world declares it, stamped above its last watermark — at once,
        or ``declare_after`` steps later (as over DDS, where a lapsed liveliness tells the world:
        meanwhile the robot's base moves on, sensing what its dead robot never reports)."""
        if agent not in self.live:
            return
        self.live.discard(agent)
        if self.declare_after:
            self.queue.push(now + self.declare_after, KILL, ("declare", agent))
        else:
            self.declare(agent, now)

    def declare(self, agent: int, now: float) -> None:
        self.world.kill(agent, now)
        sp = self.agents[agent].speaker
        stamp = max(sp.announced + 1, math.ceil(now - 1e-9))
        # declared late, its counted sensing ends where its last watermark says (it commits a
        # time only once its base's events up to it are handled): not where its base is now
        sensed = float(sp.announced) if self.declare_after else None
        notice = self.world.notice(agent, stamp, sp.seq, sensed_until=sensed)
        self.notices[agent] = stamp
        self.net.send(now, notice, sorted(self.live))
        self.schedule_world()


def run_realtime(
    scenario: Scenario,
    protocol: str = "ccp",
    policy: CoordinationPolicy | None = None,
    settings: Any = None,
    latency: Latency | None = None,
    seed: int = 0,
    speed_jitter: float = 0.0,
    stalls: Sequence[tuple[int, float, float]] = (),
    failures: Mapping[int, float] | None = None,
    max_steps: int | None = None,
    prepare: Callable[[list[RealtimeAgent]], None] | None = None,
    mirrors: bool = False,
    base_lag: float = 0.0,
    declare_after: float = 0.0,
) -> tuple[RunResult, RealtimeReport]:
    """One run without a barrier, in process; the result (as ``ost sim`` builds it) and what the
    realtime run adds (agreement, lags, network figures). ``failures``: agent -> the time it
    fails; ``prepare(agents)``: fault injection before the run (tests); ``mirrors``: every robot
    also keeps its own picture of its base from the base's events, checked against the world at
    every decision (``report.mirror_errors``); ``base_lag``: every robot knows its base's events
    only this many steps after they happen (as over DDS), so it commits no later than that;
    ``declare_after``: a failed robot is declared this many steps after it died (as over DDS)."""
    policy = policy or CoordinationPolicy()
    latency = latency or Latency()
    failures = dict(failures or {})
    agents = make_agents(scenario, protocol, policy, settings)
    if prepare is not None:
        prepare(agents)
    queue = EventQueue()
    run = _Run(
        RealtimeWorld(scenario, speed_jitter, seed, tuple(stalls), tracking=mirrors),
        {ra.id: ra for ra in agents},
        Network(queue, latency, seed),
        queue,
        RealtimeReport(latency, seed, speed_jitter, tuple(stalls)),
        {ra.id for ra in agents},
    )
    bound = step_limit(scenario, len(failures))
    slack = (latency.steps + latency.jitter + 2) * 4 * (len(scenario.objects) + scenario.n_agents + 4)
    limit = max_steps if max_steps is not None else 2 * bound + slack + sum(s[2] for s in stalls)
    run.base_lag, run.declare_after = base_lag, declare_after
    if mirrors:
        where = {o.id: o.destination for o in scenario.objects}
        team = TeamInfo.from_scenario(scenario)
        run.mirrors = {ra.id: mirror_of(team, ra.id, where.__getitem__) for ra in agents}
    for a, t in sorted(failures.items()):
        if a not in run.agents:
            raise ValueError(f"failure of agent {a}: no such agent")
        queue.push(t, KILL, ("kill", a))
    for ra in agents:  # after any failure at step 0
        queue.push(0.0, WAKE, ("start", ra.id))
    error, now, end = run.loop(limit)
    run.world.end = now if end is None else end
    result = finish_result(cast(World, run.world), [ra.agent for ra in agents], run.counted())
    if error is not None:
        result.completed = False
        result.error = error
    run.report.lag = {ra.id: ra.max_lag for ra in agents}
    run.report.mirror_errors = run.mirror_errors
    run.report.disagreements, run.report.coordinations = disagreements(agents)
    return result, run.report


def disagreements(agents: Sequence[RealtimeAgent]) -> tuple[int, int]:
    """(batches whose digests differ between agents that took them, batches with a coordination
    compared): a batch an agent took without changing its schedule counts as its digest None."""
    stamps = sorted({t for ra in agents for t in ra.digests})
    bad = 0
    for t in stamps:
        seen = {
            (d.input, d.output) if (d := ra.digests.get(t)) is not None else None
            for ra in agents
            if t in ra.processed
        }
        if len(seen) > 1:
            bad += 1
    return bad, len(stamps)


__all__ = [
    "REALTIME",
    "Latency",
    "RealtimeReport",
    "check_realtime",
    "make_agent",
    "make_agents",
    "run_realtime",
]
