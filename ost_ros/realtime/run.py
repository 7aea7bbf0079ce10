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
from dataclasses import dataclass, field, replace
from typing import Any, Protocol, cast

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines.common import finish_result, step_limit
from ost_ros.model import Scenario
from ost_ros.negotiation.slots import NegotiationSettings
from ost_ros.protocols import ProtocolError, check
from ost_ros.realtime.agent import RealtimeAgent, Record
from ost_ros.realtime.base import BaseMirror, mirror_of
from ost_ros.realtime.body import RtScheduleAgent
from ost_ros.realtime.comms import RtAuctionComm, RtCcpComm, RtGreedyComm, RtNcpComm
from ost_ros.realtime.hcp import RtHcpAgent, RtHcpRuntime
from ost_ros.realtime.membership import ABSENT, DEAD, IN, MONITOR, OUT, SILENT, Monitor
from ost_ros.realtime.messages import Back, Envelope, Mark, Need, ObjectInfo
from ost_ros.realtime.net import DELIVER, KILL, WAKE, WORLD, EventQueue, Latency, Network, Split
from ost_ros.realtime.outputs import AskFeedback, Output, Publish, SendGoal, WakeAt
from ost_ros.realtime.remote import BaseLink
from ost_ros.realtime.world import CarryStarted, Detection, Feedback, GoalResult, RealtimeWorld
from ost_ros.result import RunResult
from ost_ros.team import TeamInfo
from ost_ros.world import World

REALTIME = ("ccp", "ncp", "auction", "greedy", "hcp")
# What a protocol cannot honour without a barrier (docs/realtime.md, "What each protocol
# guarantees"): option -> why, in one line.
REFUSED: dict[str, dict[str, str]] = {
    "hcp": {
        "join": "hcp takes no robot into the team after the start (--join): its owners and "
        "heirs are fixed by the subareas of the robots there at the start",
    },
}


def refused(protocol: str, option: str) -> str | None:
    """Why ``protocol`` cannot honour ``option`` without a barrier (None: it can)."""
    return REFUSED.get(protocol, {}).get(option)


def _check_options(protocol: str, **given: bool) -> None:
    """One-line :class:`ProtocolError` for an option given that the protocol cannot honour."""
    for option, on in given.items():
        why = refused(protocol, option)
        if on and why:
            raise ProtocolError(why)


def check_realtime(protocol: str, policy: CoordinationPolicy | None = None) -> None:
    """One-line :class:`ProtocolError` if the protocol (or its options) cannot run without a
    barrier."""
    check(protocol, policy=policy)
    if protocol not in REALTIME:
        raise ProtocolError(f"{protocol} has no realtime runtime (realtime: {', '.join(REALTIME)})")


def make_agents(
    scenario: Scenario, protocol: str, policy: CoordinationPolicy, settings: Any = None, monitor: bool = False
) -> list[RealtimeAgent]:
    """Every robot's realtime runtime, in id order (``monitor``: a membership monitor takes part)."""
    check_realtime(protocol, policy)
    check(protocol, scenario=scenario, policy=policy)
    team = TeamInfo.from_scenario(scenario)
    return [make_agent(team, a.id, protocol, policy, settings, monitor) for a in scenario.agents]


def make_agent(
    team: TeamInfo,
    agent_id: int,
    protocol: str,
    policy: CoordinationPolicy,
    settings: Any = None,
    monitor: bool = False,
    whole_record: bool = True,
) -> RealtimeAgent:
    """One robot's realtime runtime (an agent node builds its own; the protocol already
    checked). ``whole_record``: it keeps what the in-process run's report is computed from (every
    batch's digest and time, every message's stamp); an agent node keeps counts only."""
    record = Record(whole=whole_record)
    if protocol == "hcp":
        return RtHcpRuntime(RtHcpAgent(agent_id, team), team.agent_ids, monitor=monitor, record=record)
    comm: RtCcpComm | RtNcpComm | RtAuctionComm | RtGreedyComm
    if protocol == "greedy":
        comm = RtGreedyComm(agent_id, team, policy)
    elif protocol == "ccp":
        comm = RtCcpComm(agent_id, team, policy, planner=getattr(settings, "planner", "paper"))
    elif protocol == "ncp":
        comm = RtNcpComm(agent_id, team, policy, settings=settings or NegotiationSettings())
    else:
        comm = RtAuctionComm(agent_id, team, policy)
    agent = RtScheduleAgent(agent_id, team, comm, protocol)
    return RealtimeAgent(agent, team.agent_ids, monitor=monitor, record=record)


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
    base_delay: Latency | None = None  # bases across a network this far (None: their own hardware)
    marks: int = 0
    needs: int = 0
    copies: int = 0  # copies the network delivered
    events: int = 0  # events the run processed
    mirror_errors: list[str] = field(default_factory=list)  # (run_realtime(mirrors=True))
    silences: tuple[tuple[int, float, float], ...] = ()  # (agent, from step, steps)
    joins: tuple[tuple[int, float], ...] = ()  # (agent, step)
    failure_timeout: float = 0.0
    declared: int = 0  # notices of robots that were not dead (silent too long, or not there yet)
    rejoins: int = 0  # robots back (a Back counted)
    out_at_end: list[int] = field(default_factory=list)  # robots out (not dead) when the run ended
    splits: tuple[Split, ...] = ()
    held: int = 0  # copies a partition held until it healed
    lost: int = 0  # copies a partition lost (said again after it healed)
    # per partition: steps from its heal until every robot had taken the last batch stamped
    # before it (all compute alike again); None: the run ended before
    healed: list[float | None] = field(default_factory=list)
    # agent -> (time, state) each time what its base does changes (OUT: declared out; --plot)
    labels: dict[int, list[tuple[float, str]]] = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {
            "mode": "realtime",
            "latency": [_n(self.latency.steps), _n(self.latency.jitter)],
            "latency_seed": self.seed,
            "speed_jitter": self.speed_jitter,
            "stalls": [list(s) for s in self.stalls],
            **(
                {"base_delay": [_n(self.base_delay.steps), _n(self.base_delay.jitter)]}
                if self.base_delay is not None
                else {}
            ),
            "disagreements": self.disagreements,
            "coordinations_compared": self.coordinations,
            "lag": {str(a): _n(v) for a, v in sorted(self.lag.items())},
            "network": {
                "marks": self.marks,
                "needs": self.needs,
                "copies": self.copies,
                "events": self.events,
            },
            "membership": {
                "silences": [list(s) for s in self.silences],
                "joins": [list(j) for j in self.joins],
                "failure_timeout": _n(self.failure_timeout),
                "declared": self.declared,
                "rejoins": self.rejoins,
                "out_at_end": self.out_at_end,
                "splits": [
                    ["/".join(",".join(map(str, sorted(g))) for g in sp.groups), _n(sp.start), _n(sp.steps)]
                    + (["lost"] if sp.lost else [])
                    for sp in self.splits
                ],
                "held": self.held,
                **({"lost": self.lost} if any(sp.lost for sp in self.splits) else {}),
                "healed_after": [None if h is None else _n(round(h, 3)) for h in self.healed],
            },
        }


def _n(x: float) -> Any:
    return int(x) if float(x).is_integer() else round(x, 3)


class Observer(Protocol):
    """Watches a run (the animation's frames, ``ost sim --latency … --animate``) and never
    changes it: :meth:`advance` each time the run's clock moves on — nothing happens from ``now``
    (every event at it handled) until ``until`` —, :meth:`end` once the run is over."""

    def advance(self, run: _Run, now: float, until: float) -> None: ...

    def end(self, run: _Run) -> None: ...


# ----------------------------------------------------------------------------- events
# What a robot's runtime is called with (held, in order, while its process is stopped):


@dataclass(frozen=True)
class Start:
    """The run begins."""


@dataclass(frozen=True)
class Clock:
    """A timer it asked for (``WakeAt``), or its base's clock: ``on_clock``."""


@dataclass(frozen=True)
class Message:
    """A peer's message, a watermark, a need, a Hello or a notice arrives."""

    payload: Any


@dataclass(frozen=True)
class Again:
    """Peers cut off by a partition that lost what crossed it are back."""


@dataclass(frozen=True)
class Base:
    """One of its base's events, heard at once (its base is its own hardware)."""

    event: GoalResult | Detection | CarryStarted


@dataclass(frozen=True)
class BaseIn:
    """One of its base's events, across a network (:class:`~ost_ros.realtime.remote.BaseLink`)."""

    event: Any
    sensed: tuple[ObjectInfo, ...]


Input = Start | Clock | Message | Again | Base | BaseIn


@dataclass(frozen=True)
class Call:
    """Robot ``agent`` (or the monitor) is called with ``input``."""

    agent: int
    input: Input


# The run's own events (the KILL phase: before the world's and the robots' at the same time):


@dataclass(frozen=True)
class Kill:
    agent: int


@dataclass(frozen=True)
class Declare:
    """A dead robot's notice, ``declare_after`` steps after it died."""

    agent: int


@dataclass(frozen=True)
class Freeze:
    agent: int
    steps: float


@dataclass(frozen=True)
class Thaw:
    agent: int


@dataclass(frozen=True)
class DeclareOut:
    """A robot silent past the failure timeout."""

    agent: int


@dataclass(frozen=True)
class Heal:
    """Partition ``split`` (which lost what crossed it) heals."""

    split: int


@dataclass(frozen=True)
class GoalArrives:
    agent: int
    goal: SendGoal
    life: int


@dataclass(frozen=True)
class BaseArrives:
    agent: int
    event: Any
    sensed: tuple[ObjectInfo, ...]


@dataclass(frozen=True)
class WorldDue:
    """The world's bases have something to do now."""


# ----------------------------------------------------------------------------- the run's state


@dataclass
class _Members:
    """Who is in the team: who lives, the monitor (runs with silences or joins), who is silent
    (its process stopped, and what came for it meanwhile), and every notice and Back sent."""

    live: set[int]
    monitor: Monitor | None = None
    monitor_wakes: set[float] = field(default_factory=set)
    failure_timeout: float = 10.0  # steps of silence after which a live robot is declared out
    declare_after: float = 0.0  # steps from a robot's death to the notice of it (as over DDS)
    # A silent robot: until when, and what came for it meanwhile (its messages, timers and base
    # events wait, as in a stopped process's sockets)
    frozen: dict[int, float] = field(default_factory=dict)
    held: dict[int, list[Input]] = field(default_factory=dict)
    notice_log: dict[tuple[int, int], tuple[int, int]] = field(
        default_factory=dict
    )  # (agent, life) -> (stamp, seq)
    backs: dict[tuple[int, int], tuple[int, int, int]] = field(
        default_factory=dict
    )  # -> (stamp, sender, seq)
    sent: dict[int, list[Envelope]] = field(default_factory=dict)  # agent -> its messages, as sent


@dataclass
class _Bases:
    """The robots' bases as each robot knows them: its own picture (checked against the world at
    every decision: ``errors``), how late it knows its base's events (``lag``: as an agent node's
    base clock), and — bases across a network (``remote``) — each robot's link to its base, the
    arrivals due on each way, the events on their way and the next base clock."""

    mirrors: dict[int, BaseMirror] = field(default_factory=dict)
    errors: list[str] = field(default_factory=list)
    lag: float = 0.0
    remote: Network | None = None
    links: dict[int, BaseLink] = field(default_factory=dict)
    due: dict[tuple[str, int], float] = field(default_factory=dict)  # (way, agent) -> last arrival
    in_flight: dict[int, list[float]] = field(default_factory=dict)  # agent -> its events' times
    ticks: dict[int, float] = field(default_factory=dict)  # agent -> its next base clock


@dataclass
class _Run:
    world: RealtimeWorld
    agents: dict[int, RealtimeAgent]
    net: Network
    queue: EventQueue
    report: RealtimeReport
    members: _Members
    bases: _Bases = field(default_factory=_Bases)
    observer: Observer | None = None  # watches the run (reads only)
    _world_times: set[float] = field(default_factory=set)

    @property
    def live(self) -> set[int]:
        return self.members.live

    def team_at(self, now: float) -> tuple[dict[int, str], Split | None]:
        """Who is in the team at ``now`` as an observer sees it — per robot IN, SILENT (its
        process stopped, not declared yet), OUT (declared, not back), DEAD or ABSENT (not joined
        yet) — and the partition in force, if any (reads only)."""
        joins = dict(self.report.joins)
        team = {}
        for a in self.agents:
            if a not in self.live or a in self.world.failed:
                team[a] = DEAD
            elif a in joins and now < joins[a]:
                team[a] = ABSENT
            elif a in self.world.outs:
                team[a] = OUT
            elif a in self.members.frozen:
                team[a] = SILENT
            else:
                team[a] = IN
        split = next((sp for sp in self.net.splits if sp.start <= now < sp.start + sp.steps), None)
        return team, split

    # ------------------------------------------------------------------ the loop

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
            if self.observer is not None and t > now:
                self.observer.advance(self, now, t)
            now = t
            self.report.events += 1
            if phase == DELIVER:  # (the network's own events: receiver, payload)
                receiver, payload = ev
                if receiver in self.live or receiver == MONITOR:
                    self.report.copies += 1
                self.call(receiver, Message(payload), t)
            else:
                self.handle(ev, t)

    def handle(self, ev: Any, now: float) -> None:
        """One event of the run's own."""
        match ev:
            case Call(agent, what):
                self.call(agent, what, now)
            case WorldDue():
                self.world_events(now)
            case Kill(agent):
                self.kill(agent, now)
            case Declare(agent):
                self.declare(agent, now)
            case Freeze(agent, steps):
                self.freeze(agent, steps, now)
            case Thaw(agent):
                self.thaw(agent, now)
            case DeclareOut(agent):
                self.declare_out(agent, now)
            case Heal(k):
                self.heal(k, now)
            case GoalArrives(agent, goal, life):
                self.goal_arrives(agent, goal, life, now)
            case BaseArrives(agent, event, sensed):
                self.bases.in_flight[agent].pop(0)
                self.call(agent, BaseIn(event, sensed), now)
            case _:
                raise TypeError(f"no such event: {ev!r}")

    def call(self, agent: int, what: Input, now: float) -> None:
        """Robot ``agent``'s runtime called with ``what``, now — or when it runs again, if it is
        silent (the monitor: it hears a broadcast, or its timer fires)."""
        m = self.members
        if agent == MONITOR and m.monitor is not None:
            m.monitor_wakes.discard(now)
            self.monitor_hears(what.payload if isinstance(what, Message) else None, now)
            return
        if agent not in self.live:
            return
        if agent in m.frozen:
            m.held.setdefault(agent, []).append(what)
            return
        ra = self.agents[agent]
        remote = self.bases.remote is not None
        if isinstance(what, Start) and remote:
            # what its base senses where it stands (the world node's first event), on its way
            fb = self.world.feedback(agent, now)
            if fb.sensed:
                self.base_event(Detection(agent, now, fb.cell, fb.sensed, fb.sensed), now)
        if remote:
            ra.base_known(self._known(agent, now))
        elif self.bases.lag:
            ra.base_known(now - self.bases.lag)
        if isinstance(what, BaseIn):
            self.base_in(agent, what.event, what.sensed, now)
            return
        if isinstance(what, Again):
            self.resend(agent, now)
        self.dispatch(agent, self._answer(ra, what, now), now)
        if remote and not isinstance(what, Clock) and ra.decision_due(now):
            self.dispatch(agent, ra.on_clock(now), now)  # (its base's clock came: a node fires)

    @staticmethod
    def _answer(ra: RealtimeAgent, what: Input, now: float) -> list[Output]:
        """The runtime's callback for ``what``."""
        match what:
            case Again():
                return ra.again(now)
            case Start():
                return ra.start(now)
            case Clock():
                return ra.on_clock(now)
            case Message(payload):
                return ra.on_message(payload, now)
            case Base(GoalResult() as res):
                return ra.on_result(res, now)
            case Base(Detection() as det):
                return ra.on_detection(det, now)
            case Base(CarryStarted() as carry):
                return ra.on_carry(carry, now)
        raise TypeError(f"no such input: {what!r}")

    def dispatch(self, agent: int, outputs: list[Output], now: float) -> None:
        """What a robot's runtime asked for, in order."""
        ra = self.agents[agent]
        bases = self.bases
        for o in outputs:
            if agent not in self.live:
                return
            if isinstance(o, Publish):
                self.publish(agent, o.payload, now)
            elif isinstance(o, SendGoal):
                self.send_goal(agent, o, now)
            elif isinstance(o, AskFeedback) and bases.remote is not None:
                self.dispatch(agent, bases.links[agent].decide(o.at, now), now)
            elif isinstance(o, AskFeedback):
                fb = self.world.feedback(agent, o.at)
                if not ra.out:
                    self.check_mirror(agent, fb)
                self.dispatch(agent, ra.on_feedback(fb, now), now)
            elif isinstance(o, WakeAt):
                self.queue.push(max(o.time, now), WAKE, Call(agent, Clock()))
        # (with bases across a network, their clock comes at least once a step)
        lag = bases.lag or (max(bases.remote.latency.steps, 1.0) if bases.remote is not None else 0.0)
        if lag and agent in self.live and ra.held(now) and bases.ticks.get(agent, -1.0) <= now:
            # its base's clock tells it more base_lag later (an agent node's base clock)
            bases.ticks[agent] = now + lag
            self.queue.push(now + lag, WAKE, Call(agent, Clock()))
        self.schedule_world()

    def publish(self, agent: int, p: Any, now: float) -> None:
        if isinstance(p, Envelope):
            self.members.sent.setdefault(agent, []).append(p)  # (kept as sent: said again after a cut)
        if isinstance(p, Mark):
            self.report.marks += 1
        elif isinstance(p, Need):
            self.report.needs += 1
        elif isinstance(p, Envelope) and isinstance(p.message, Back):
            self.back_sent(p)
        self.net.send(now, p, [j for j in sorted(self.live) if j != agent] + self._monitor_ids)

    def send_goal(self, agent: int, o: SendGoal, now: float) -> None:
        if agent in self.bases.mirrors:
            self.bases.mirrors[agent].sent(o.id, o.goal)
        life = self.agents[agent].incarnation
        if self.bases.remote is not None:
            self.queue.push(self._arrival("goal", agent, now), KILL, GoalArrives(agent, o, life))
            return
        for r in self.world.goal(agent, o.id, o.goal, o.at, life):
            self.base_event(r, now)
            if isinstance(r, GoalResult):
                self.dispatch(r.agent, self.agents[r.agent].on_result(r, now), now)

    # ------------------------------------------------------------------ the world's bases

    def schedule_world(self) -> None:
        t = self.world.next_time()
        if t is not None and t not in self._world_times:
            self._world_times.add(t)
            self.queue.push(t, WORLD, WorldDue())

    def world_events(self, now: float) -> None:
        self._world_times.discard(now)
        for ev in self.world.advance(now):
            self.base_event(ev, now)
            if self.bases.remote is not None:
                continue
            if isinstance(ev, (GoalResult, Detection)):
                self.call(ev.agent, Base(ev), now)
            elif isinstance(ev, CarryStarted):
                for j in ev.group:
                    self.call(j, Base(ev), now)
        self.schedule_world()

    def base_event(self, ev: Any, now: float) -> None:
        """A base's event for the robots' pictures (a tracking world's GoalStarted and Stalled go
        only there); with bases across a network, on its way to its robots (:meth:`base_in`)."""
        bases = self.bases
        if bases.remote is not None:
            there: tuple[ObjectInfo, ...] = ()  # (with a result: what it senses where it stands)
            if isinstance(ev, GoalResult) and ev.outcome in ("reached", "aborted"):
                there = self.world.feedback(ev.agent, ev.time).sensed
            for j in ev.group if isinstance(ev, CarryStarted) else (ev.agent,):
                bases.in_flight.setdefault(j, []).append(now)
                self.queue.push(self._arrival("base", j, now), KILL, BaseArrives(j, ev, there))
            return
        if not bases.mirrors:
            return
        if isinstance(ev, CarryStarted):
            for j in ev.group:
                if j in bases.mirrors:
                    bases.mirrors[j].take(ev)
        elif ev.agent in bases.mirrors:
            sensed: tuple[ObjectInfo, ...] = ()
            if isinstance(ev, GoalResult) and ev.outcome in ("reached", "aborted"):
                sensed = self.world.feedback(ev.agent, ev.time).sensed
            bases.mirrors[ev.agent].take(ev, sensed)

    def check_mirror(self, agent: int, fb: Feedback) -> None:
        m = self.bases.mirrors.get(agent)
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
            self.bases.errors.append(f"agent {agent}: world {fb}, mirror {mine}")

    # ------------------------------------------------------------------ bases across a network

    def across_a_network(self, delay: Latency | None, seed: int) -> None:
        """Every robot's base across a network, ``delay`` away (its own draws: the messages'
        stay as they were), each robot deciding on its own picture (:class:`BaseLink`); None:
        each its own hardware."""
        if delay is None:
            return
        self.bases.remote = Network(self.queue, delay, seed + 7919)
        self.report.base_delay = delay
        for ra in self.agents.values():
            ra.across_a_network()
            self.bases.links[ra.id] = BaseLink(ra, self.bases.mirrors[ra.id])

    def _arrival(self, way: str, agent: int, now: float) -> float:
        """When something sent now on ``way`` (goals to the world, events to a robot) arrives:
        its own delay, after everything sent before it on the same way (one reliable topic)."""
        bases = self.bases
        assert bases.remote is not None
        at = max(bases.due.get((way, agent), 0.0), now + bases.remote.delay())
        bases.due[(way, agent)] = at
        return at

    def goal_arrives(self, agent: int, o: SendGoal, life: int, now: float) -> None:
        """A robot's goal reaches the world: it takes over when the world node takes it over
        (:meth:`RealtimeWorld.takeover`: at its decision's time if less than a step ago)."""
        for r in self.world.goal(agent, o.id, o.goal, self.world.takeover(agent, o.goal, o.at, now), life):
            self.base_event(r, now)
        self.schedule_world()

    def base_in(self, agent: int, ev: Any, sensed: tuple[ObjectInfo, ...], now: float) -> None:
        """One of its base's events reaches a robot, as an agent node takes it (its
        :class:`BaseLink`): its picture and its runtime, then what it may commit, then the
        decision that waited for its picture."""
        ra, link = self.agents[agent], self.bases.links[agent]
        self.dispatch(agent, link.event(ev, sensed, now), now)
        ra.base_known(self._known(agent, now))
        self.dispatch(agent, link.retry(now), now)
        if ra.held(now) or ra.decision_due(now):
            self.dispatch(agent, ra.on_clock(now), now)

    def _known(self, agent: int, now: float) -> float:
        """How far a robot has its base's events: up to the first still on its way (its base's
        clock says as much over DDS), and no further than that clock has come."""
        bases = self.bases
        assert bases.remote is not None
        known = now - bases.remote.latency.steps
        due = self.world.next_time()
        if due is not None and due <= now:  # the world has not moved its bases on to now yet
            known = min(known, due - 1e-6)
        flying = bases.in_flight.get(agent)
        return min(known, flying[0] - 1e-6) if flying else known

    # ------------------------------------------------------------------ who is in the team

    @property
    def _monitor_ids(self) -> list[int]:
        return [MONITOR] if self.members.monitor is not None else []

    def membership(
        self,
        silences: Sequence[tuple[int, float, float]],
        joins: Mapping[int, float],
        timeout: float,
        failures: Mapping[int, float],
    ) -> None:
        """A monitor for the team, the silences and the joins (a robot that joins is out from
        the start and heard from its step on)."""
        m = self.members
        m.monitor = Monitor(tuple(sorted(self.agents)))
        m.failure_timeout = timeout
        self.report.silences, self.report.failure_timeout = tuple(silences), timeout
        self.report.joins = tuple(sorted(joins.items()))
        for a, at, steps in silences:
            if a not in self.agents:
                raise ValueError(f"silence of agent {a}: no such agent")
            if at < 0 or steps <= 0:
                raise ValueError(f"silence of agent {a}: from step {at} for {steps} steps")
            self.queue.push(at, KILL, Freeze(a, steps))
        for a, at in sorted(joins.items()):
            if a not in self.agents:
                raise ValueError(f"join of agent {a}: no such agent")
            if at <= 0:
                raise ValueError(f"join of agent {a} at step {at}: must be > 0")
            if a in failures:
                raise ValueError(f"agent {a} both joins and fails")
            m.frozen[a] = at
            self.queue.push(at, KILL, Thaw(a))
            self.declare_out(a, 0.0)

    def monitor_hears(self, payload: Any, now: float) -> None:
        """The monitor hears a broadcast (or its timer fires: None): it commits what it can and
        announces what is wanted; a Back for a dead robot has it declared again, for that life."""
        m = self.members.monitor
        assert m is not None
        marks = m.tick(now) if payload is None else m.hear(payload, now)
        for mark in marks:
            self.report.marks += 1
            self.net.send(now, mark, sorted(self.live))
        nxt = m.next_wanted()
        if nxt is not None and nxt > now and nxt not in self.members.monitor_wakes:
            self.members.monitor_wakes.add(nxt)
            self.queue.push(float(nxt), WAKE, Call(MONITOR, Clock()))
        back = payload.message if isinstance(payload, Envelope) else None
        if isinstance(back, Back) and back.agent not in self.live:
            self.declare(back.agent, now)

    def counted(self) -> int:
        """Protocol messages the team took in: those of each robot's lives — from the start to its
        first notice (a failed robot's up to its notice's stamp: what it sent after its last
        watermark is dropped by everyone, as if never sent), from each Back that counted (the
        first in batch order) to the next notice."""
        m = self.members
        n = 0
        for j, ra in self.agents.items():
            lives = [(-1, 0)]
            lives += [(b[0] + 1, b[2]) for _, b in sorted((k, v) for k, v in m.backs.items() if k[0] == j)]
            spans = []
            for k, (first, after) in enumerate(lives):
                end, upto = m.notice_log.get((j, k), (math.inf, math.inf))
                spans.append((first, max(end, first), after, upto))
            n += sum(1 for s, q in ra.record.sent if any(f <= s < e and a < q <= u for f, e, a, u in spans))
        return n

    def freeze(self, agent: int, steps: float, now: float) -> None:
        """Robot ``agent`` falls silent for ``steps`` (its process stopped: it hears, decides and
        sends nothing; its base goes on); past the failure timeout it is declared out."""
        m = self.members
        if agent not in self.live or agent in m.frozen:
            return
        m.frozen[agent] = now + steps
        self.queue.push(now + steps, KILL, Thaw(agent))
        if steps > m.failure_timeout:
            self.queue.push(now + m.failure_timeout, KILL, DeclareOut(agent))

    def thaw(self, agent: int, now: float) -> None:
        """It runs again: what came for it meanwhile, in order, then on as before."""
        m = self.members
        if m.frozen.pop(agent, None) is None:
            return
        for what in m.held.pop(agent, []):
            self.call(agent, what, now)
        self.call(agent, Clock(), now)

    def declare_out(self, agent: int, now: float) -> None:
        """A live robot silent too long is declared out: its base stops (as a failed robot's)
        and every robot, itself included, gets the stamped notice — above its last watermark and
        above the batch it was last readmitted in. It comes back when it is heard again."""
        if agent not in self.live:
            return
        ra = self.agents[agent]
        m = self.members.monitor
        if (
            ra.out
            or m is None
            or agent in m.out
            or any(d.agent == agent and d.life == m.lives.get(agent, 0) for d in m.declared)
        ):
            return  # out already (its next life, if it asks, is declared when it falls silent)
        self.world.kill(agent, now, out=True)
        self.report.declared += 1
        self.announce(agent, now, dead=False)

    def kill(self, agent: int, now: float) -> None:
        """The robot is gone; it is declared, stamped above its last watermark — at once, or
        ``declare_after`` steps later (as over DDS, where a lapsed liveliness tells the monitor:
        meanwhile the robot's base moves on, sensing what its dead robot never reports)."""
        if agent not in self.live:
            return
        self.live.discard(agent)
        if self.members.declare_after:
            self.queue.push(now + self.members.declare_after, KILL, Declare(agent))
        else:
            self.declare(agent, now)

    def declare(self, agent: int, now: float) -> None:
        """A dead robot's notice: the monitor's, if one runs; else the run's on the world's behalf,
        stamped above the last watermark the robot gave (it is declared once: it is dead)."""
        self.world.kill(agent, now)
        if self.members.monitor is not None:
            self.announce(agent, now, dead=True)
            return
        ra = self.agents[agent]
        life = ra.incarnation
        sp = ra.speaker
        stamp = max(sp.announced + 1, math.ceil(now - 1e-9))
        # declared late, its counted sensing ends where its last watermark says (it commits a
        # time only once its base's events up to it are handled): not where its base is now
        sensed = float(sp.announced) if self.members.declare_after else None
        notice = replace(self.world.notice(agent, stamp, sp.seq, sensed_until=sensed), incarnation=life)
        self.members.notice_log[(agent, life)] = (stamp, sp.seq)
        self.net.send(now, notice, sorted(self.live))
        self.schedule_world()

    def announce(self, agent: int, now: float, dead: bool) -> None:
        """The monitor declares ``agent`` (silent too long; ``dead``: gone for good): its notice,
        stamped above its last watermark heard, to every robot (itself included, if it runs)."""
        m = self.members.monitor
        assert m is not None
        d = m.declare(agent, dead=dead)
        if d is None:
            return
        notice = self.world.notice(agent, d.stamp, d.seq, sensed_until=float(d.watermark))
        notice = replace(notice, incarnation=d.life, serial=d.serial)
        self.members.notice_log[(agent, d.life)] = (d.stamp, d.seq)
        self.net.send(now, notice, sorted(self.live))
        self.monitor_hears(None, now)
        self.schedule_world()

    def back_sent(self, env: Envelope) -> None:
        """A member readmits a robot: the first Back in batch order will count."""
        b = env.message
        key = (b.agent, b.incarnation)
        mine = (env.stamp, env.sender, b.after)
        backs = self.members.backs
        if key not in backs or mine < backs[key]:
            backs[key] = mine

    def heal(self, k: int, now: float) -> None:
        """Partition ``k``, which lost what crossed it, heals: each robot of its groups sees its
        peers back and says it again (as an agent node does when its writers' readers come
        back: ``RealtimeAgentNode.readers_back``); a dead robot's messages the monitor holds
        and relays."""
        for agent in sorted(frozenset().union(*self.net.splits[k].groups)):
            if agent in self.live:
                self.call(agent, Again(), now)
            else:
                self.resend(agent, now)

    def resend(self, agent: int, now: float) -> None:
        """Every message ``agent`` sent, again, to every robot (a copy it has is dropped)."""
        for env in self.members.sent.get(agent, []):
            self.net.send(now, env, [j for j in sorted(self.live) if j != agent])


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
    silences: Sequence[tuple[int, float, float]] = (),
    joins: Mapping[int, float] | None = None,
    failure_timeout: float = 10.0,
    splits: Sequence[Split] = (),
    observe: Observer | None = None,
    base_delay: Latency | None = None,
) -> tuple[RunResult, RealtimeReport]:
    """One run without a barrier, in process; the result (as ``ost sim`` builds it) and what the
    realtime run adds (agreement, lags, network figures). ``failures``: agent -> the time it
    fails; ``prepare(agents)``: fault injection before the run (tests); ``mirrors``: every robot
    also keeps its own picture of its base from the base's events, checked against the world at
    every decision (``report.mirror_errors``); ``base_lag``: every robot knows its base's events
    only this many steps after they happen (as over DDS), so it commits no later than that;
    ``declare_after``: a failed robot is declared this many steps after it died (as over DDS);
    ``silences``: (agent, from, steps) — the robot's process stops that long (declared out past
    ``failure_timeout`` steps; it comes back when it runs again); ``joins``: agent -> the step it
    joins at (out from the start, until then); ``splits``: partitions, whose copies between
    groups are held until they heal; ``observe``: watches the run as it goes (the animation's
    frames; it changes nothing); ``base_delay``: every robot's base is across a network, as an
    agent node's — its goals reach the world and its base's events reach it this late (each way
    in order), and it decides on its own picture of its base (``mirrors``), committing only as
    far as its base's events are in."""
    policy = policy or CoordinationPolicy()
    mirrors = mirrors or base_delay is not None
    latency = latency or Latency()
    failures = dict(failures or {})
    _check_options(protocol, join=bool(joins))
    monitor = bool(silences or joins)  # (without them, as before: the world declares the dead)
    agents = make_agents(scenario, protocol, policy, settings, monitor=monitor)
    if prepare is not None:
        prepare(agents)
    queue = EventQueue()
    run = _Run(
        # (a robot declared out is waited for unless the protocol never takes it back: HCP)
        RealtimeWorld(
            scenario, speed_jitter, seed, tuple(stalls), tracking=mirrors, wait_for_out=protocol != "hcp"
        ),
        {ra.id: ra for ra in agents},
        Network(queue, latency, seed, splits=tuple(splits)),
        queue,
        RealtimeReport(latency, seed, speed_jitter, tuple(stalls)),
        _Members({ra.id for ra in agents}, declare_after=declare_after),
        _Bases(lag=base_lag),
        observe,
    )
    bound = step_limit(scenario, len(failures))
    slack = (latency.steps + latency.jitter + 2) * 4 * (len(scenario.objects) + scenario.n_agents + 4)
    joins = dict(joins or {})
    # a robot out and back re-plans like a failure, after its silence (or its join) has passed
    away = sum(s[2] for s in silences) + max(joins.values(), default=0) + (len(silences) + len(joins)) * slack
    away += sum(sp.steps for sp in splits) + len(splits) * slack
    for sp in splits:
        for g in sp.groups:
            if not g <= set(run.agents):
                raise ValueError(f"split: no agents {sorted(g - set(run.agents))}")
    limit = max_steps if max_steps is not None else 2 * bound + slack + sum(s[2] for s in stalls) + away
    if mirrors:
        where = {o.id: o.destination for o in scenario.objects}
        team = TeamInfo.from_scenario(scenario)
        run.bases.mirrors = {ra.id: mirror_of(team, ra.id, where.__getitem__) for ra in agents}
    run.across_a_network(base_delay, seed)
    if failure_timeout <= 0:
        raise ValueError(f"failure timeout {failure_timeout}: must be > 0")
    if monitor:
        run.membership(silences, joins, failure_timeout, failures)
    for k, sp in enumerate(splits):
        if sp.lost:  # (after the copies of its last moment: the robots say it again then)
            queue.push(sp.start + sp.steps, KILL, Heal(k))
    for a, t in sorted(failures.items()):
        if a not in run.agents:
            raise ValueError(f"failure of agent {a}: no such agent")
        queue.push(t, KILL, Kill(a))
    for ra in agents:  # after any failure at step 0
        queue.push(0.0, WAKE, Call(ra.id, Start()))
    error, now, end = run.loop(limit)
    run.world.end = now if end is None else end
    result = finish_result(cast(World, run.world), [ra.agent for ra in agents], run.counted())
    if error is not None:
        result.completed = False
        result.error = error
    run.report.lag = {ra.id: ra.record.max_lag for ra in agents}
    run.report.rejoins = sum(ra.life.rejoins for ra in agents)
    run.report.splits = tuple(splits)
    run.report.healed = [healed(agents, sp.start + sp.steps, run.live) for sp in splits]
    run.report.labels = run.world.labels
    run.report.held, run.report.lost = run.net.held, run.net.lost
    run.report.out_at_end = sorted(run.world.outs)
    run.report.mirror_errors = run.bases.errors
    run.report.disagreements, run.report.coordinations = disagreements(agents)
    if observe is not None:
        observe.end(run)
    return result, run.report


def healed(agents: Sequence[RealtimeAgent], heal: float, live: set[int]) -> float | None:
    """Steps from ``heal`` until every live robot in the team had taken the last batch stamped
    before it (what the partition held up: from then on all compute alike again); 0 if none was
    held past it, None if a robot never took it."""
    stamps = [t for ra in agents for t in ra.record.taken_at if t < heal]
    if not stamps:
        return 0.0
    last = max(stamps)
    times = [ra.record.taken_at.get(last) for ra in agents if ra.id in live and not ra.out]
    if any(t is None for t in times):
        return None
    return max(0.0, max(t for t in times if t is not None) - heal)


def disagreements(agents: Sequence[RealtimeAgent]) -> tuple[int, int]:
    """(batches whose digests differ between agents that took them, batches with a coordination
    compared): a batch an agent took without changing its schedule counts as its digest None."""
    stamps = sorted({t for ra in agents for t in ra.record.digests})
    bad = 0
    for t in stamps:
        seen = {
            (d.input, d.output) if (d := ra.record.digests.get(t)) is not None else None
            for ra in agents
            if t in ra.record.processed
        }
        if len(seen) > 1:
            bad += 1
    return bad, len(stamps)


__all__ = [
    "REALTIME",
    "Latency",
    "Observer",
    "RealtimeReport",
    "check_realtime",
    "make_agent",
    "make_agents",
    "refused",
    "run_realtime",
]
