"""The agent side of the lockstep protocol, ROS-free: one core agent driven by decoded messages.

Per step the agent node feeds it a :class:`Tick` and peers' protocol messages (each a
:class:`Sample` from the topic of its kind); it answers with what to publish. Order inside the
agent is exactly the in-process simulator's:

    Tick(t, last, peers, counts) → comm module for step ``last`` with the messages of ``peers``
                                   (+ own), each sender's in its outbox order (``seq``)
                                 → replay skipped steps last+1 .. t-1 from the own plan
                                 → act(observation t) → publish the step's Samples, then Acted(t)

A Tick is held until every listed peer's messages of step ``last`` are in, as many as the world
counted (the counting barrier). The core agent runs unchanged; this class only orders its calls.
A failure the world announces for step ``last`` (``Tick.failed``) joins that step's inbox as an
``AgentLost``, after the peers' messages — the simulator's order. Samples are published before
the action, and every agent keeps the messages of the last few steps, so a peer's message that a
failed sender got to only some agents is relayed by the others on a Resend.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ost_ros import protocols
from ost_ros.lockstep.messages import (
    PLAN_CODE,
    Acted,
    AgentReport,
    PlanColumns,
    ProtocolViolation,
    Resend,
    RunEnd,
    Sample,
    ScheduleEntry,
    Tick,
)
from ost_ros.messages import Action, AgentLost, AgentMessage, ObjectInfo, Observation
from ost_ros.model import Cell
from ost_ros.protocols.base import ProtocolAgent
from ost_ros.protocols.plans import Plan, Row, Segment, advance, rows
from ost_ros.protocols.shared.agent import PLAN_HORIZON
from ost_ros.sensing import BLOCK

# Quiet steps planned ahead by default: as far as the protocols' planners look.
LOOKAHEAD = PLAN_HORIZON

# Messages of one step: sender -> seq -> message.
StepInbox = dict[int, dict[int, AgentMessage]]


@dataclass
class AgentRuntime:
    agent: ProtocolAgent  # a core agent: act(obs), outbox(), communicate(t, msgs)
    team: tuple[int, ...]  # every agent id, ascending (the simulator's inbox order)
    lookahead: int = 0  # plan this many quiet steps ahead (0: no event skipping)
    last: int = -1  # the last step this agent acted on
    sent: int = 0  # protocol messages broadcast so far
    finished: bool = False
    _tick: Tick | None = None
    _end: RunEnd | None = None
    _inbox: dict[int, StepInbox] = field(default_factory=dict)  # step -> what peers sent
    _own: list[AgentMessage] = field(default_factory=list)
    _plan: PlanColumns | tuple[()] = ()
    _known: dict[int, ObjectInfo] = field(default_factory=dict)
    _horizon: int = 8  # current planning depth, adapted to what the world skips
    # Recovery from a lost sample: what was published for the last step, to publish again.
    _last_tick: Tick | None = None
    _last_out: list[Any] = field(default_factory=list)
    _sent: dict[int, list[Sample]] = field(default_factory=dict)  # step -> own samples
    _resend: list[Any] = field(default_factory=list)
    _relay: dict[int, StepInbox] = field(default_factory=dict)  # finished steps' inboxes
    _report: AgentReport | None = None
    run: str | None = None  # the world's run id, from the first tick
    _early: list[Sample] = field(default_factory=list)  # samples before the first tick
    dropped: list[tuple[Sample, str]] = field(default_factory=list)  # early samples refused, why

    def __post_init__(self) -> None:
        # the message kinds of the agent's protocol (the registry): a topic each
        self.kinds: tuple[type, ...] = protocols.get(self.agent.protocol).messages

    @property
    def me(self) -> int:
        return self.agent.id

    # ------------------------------------------------------------------ input

    def accept_sample(self, sample: Sample) -> None:
        """One protocol message of a peer (from the topic of its kind)."""
        if self.run is None:
            self._early.append(sample)  # checked once the first tick says which run this is
            return
        m = sample.message
        if sample.run != self.run:
            raise ProtocolViolation(f"{m.TYPE} of run {sample.run!r}, this is run {self.run!r}")
        if m.sender == self.me:
            return  # own message: kept locally when sent
        if m.sender not in self.team:
            raise ProtocolViolation(f"{m.TYPE} from agent {m.sender}, not in the team")
        if type(m) not in self.kinds:
            raise ProtocolViolation(f"{m.TYPE} is not a message of protocol {self.agent.protocol}")
        if sample.step < self.last:
            return  # a re-sent message of a step already done (see Resend)
        msgs = self._inbox.setdefault(sample.step, {}).setdefault(m.sender, {})
        known = msgs.get(sample.seq)
        if known is not None:
            if known == m:
                return  # the same message again (see Resend)
            raise ProtocolViolation(
                f"second, different message #{sample.seq} of agent {m.sender} in step {sample.step}"
            )
        msgs[sample.seq] = m

    def accept_resend(self, req: Resend) -> None:
        """A peer lacks messages of step ``req.t``: publish this agent's again, and relay what it
        holds of the other listed peers (a sender may be dead)."""
        if req.run != self.run:
            raise ProtocolViolation(f"resend request of run {req.run!r}, this is run {self.run!r}")
        if req.sender not in self.team:
            raise ProtocolViolation(f"resend request from agent {req.sender}, not in the team")
        if self.me in req.peers:
            self._resend.extend(s for s in self._sent.get(req.t, ()) if s not in self._resend)
        for peer in req.peers:
            if peer in (self.me, req.sender):
                continue
            msgs = self._relay.get(req.t, {}).get(peer) or self._inbox.get(req.t, {}).get(peer) or {}
            for seq, m in sorted(msgs.items()):
                sample = Sample(m, req.t, seq, self.run)
                if sample not in self._resend:
                    self._resend.append(sample)

    def accept_tick(self, tick: Tick) -> None:
        if tick.observation.agent != self.me or tick.observation.t != tick.t:
            raise ProtocolViolation(
                f"tick for agent {tick.observation.agent} step {tick.observation.t}, this is agent {self.me}"
            )
        if len(tick.peers) != len(tick.counts):
            raise ProtocolViolation(f"tick lists {len(tick.peers)} peers and {len(tick.counts)} counts")
        if self.run is not None and tick.run != self.run:
            raise ProtocolViolation(f"tick of run {tick.run!r}, this is run {self.run!r}")
        if self.run is None and tick.t == 0 and tick.last == -1:
            self.run = tick.run
            early, self._early = self._early, []
            for sample in early:
                try:
                    self.accept_sample(sample)
                except ProtocolViolation as exc:
                    self.dropped.append((sample, str(exc)))
        elif self.run is None:
            raise ProtocolViolation(f"tick for step {tick.t} before this agent's first tick")
        if tick == self._tick:
            return  # re-sent while still held: nothing new
        if tick == self._last_tick:
            # The world re-sent the tick this agent already answered: its answer was lost.
            self._resend.extend(m for m in self._last_out if m not in self._resend)
            return
        if tick.last != self.last or tick.t <= self.last or self._tick is not None:
            raise ProtocolViolation(
                f"tick for step {tick.t} after {tick.last}, this agent acted last in step {self.last}"
            )
        if tick.t - tick.last - 1 > len(self._plan):
            raise ProtocolViolation(
                f"tick skips {tick.t - tick.last - 1} steps, the plan has {len(self._plan)}"
            )
        self._tick = tick

    def accept_end(self, end: RunEnd) -> None:
        if end.run != self.run:
            raise ProtocolViolation(f"run_end of run {end.run!r}, this is run {self.run!r}")
        if self._report is not None:
            if self._report not in self._resend:  # the world re-sent run_end: report again
                self._resend.append(self._report)
            return
        if end == self._end:
            return
        if len(end.peers) != len(end.counts):
            raise ProtocolViolation(f"run_end lists {len(end.peers)} peers and {len(end.counts)} counts")
        if end.last != self.last or end.steps - end.last - 1 > len(self._plan):
            raise ProtocolViolation(
                f"run_end after step {end.last} (+{end.steps - end.last - 1} "
                f"skipped), this agent acted last in step {self.last}"
            )
        self._end = end

    # ------------------------------------------------------------------ progress

    def held(self) -> tuple[int, tuple[int, ...]] | None:
        """A tick held by the barrier: its step and the peers whose messages are missing."""
        if self._tick is None:
            return None
        tick = self._tick
        return tick.t, tuple(
            p for p, n in zip(tick.peers, tick.counts) if p != self.me and not self._has(p, n)
        )

    def _has(self, peer: int, count: int) -> bool:
        """All ``count`` messages of ``peer`` for step ``self.last`` are in."""
        msgs = self._inbox.get(self.last, {}).get(peer, {})
        return all(k in msgs for k in range(count))

    def _ready(self, peers: tuple[int, ...], counts: tuple[int, ...]) -> bool:
        # (peers and counts are the same length: accept_tick/accept_end refuse any other)
        return all(p == self.me or self._has(p, n) for p, n in zip(peers, counts))

    def _finish_step(
        self,
        peers: tuple[int, ...],
        counts: tuple[int, ...],
        until: int,
        failed: tuple[AgentLost, ...] = (),
    ) -> None:
        """Comm module for ``self.last``, then replay the skipped steps up to ``until`` - 1."""
        if self.last >= 0:
            have = self._inbox.pop(self.last, {})
            self._relay[self.last] = have
            while len(self._relay) > 3:
                del self._relay[min(self._relay)]
            count = dict(zip(peers, counts))
            inbox: list[AgentMessage] = []
            for sender in self.team:
                if sender == self.me:
                    inbox.extend(self._own)
                elif sender in count:  # the sender's outbox order
                    inbox.extend(have[sender][k] for k in range(count[sender]))
            inbox.extend(m for m in failed if m.t == self.last)
            self._learn(inbox)
            self.agent.communicate(self.last, inbox)
        # Plan about twice as far as the world last skipped: long quiet stretches get long plans,
        # busy phases (every plan cut short by someone's message) cost little planning.
        self._horizon = max(8, min(self.lookahead, 2 * (until - self.last - 1)))
        self._replay(PlanColumns.of(self._plan), self.last + 1, until)
        self._own = []
        self._plan = ()

    def _replay(self, plan: PlanColumns, start: int, until: int) -> None:
        """Steps ``start`` .. ``until`` - 1, which the world executed from the agent's plan: the
        agent acts in each step in which it decides (checked against the plan) and skips the
        others in bulk — to the end of its plan's settled first segment, or to its comm module's
        next event — the event engine's rule, which leaves it as acting in every step would
        (property-tested: the event engine's results are the step engine's)."""
        k, s = 0, start
        while s < until:
            quiet = self._quiet(s, plan.position(k), until - s)
            if quiet is None:
                sensed = tuple(self._known[i] for i in plan.sensed_at(k))
                action = self.agent.act(Observation(self.me, s, plan.position(k), sensed))
                if self.agent.outbox() or not plan.same_action(k, action):
                    raise ProtocolViolation(f"replaying step {s}: the agent deviated from its plan")
                self.agent.communicate(s, [])
                k, s = k + 1, s + 1
                continue
            seg, m, wake = quiet
            to, _ = advance(seg, s, plan.position(k), m)
            self.agent.skip(s + m, to, seg, m)
            if wake == s + m - 1:  # its comm module acts on its own in the last of them
                self.agent.communicate(wake, [])
            k, s = k + m, s + m

    def _quiet(self, s: int, position: Cell, left: int) -> tuple[Segment, int, int | None] | None:
        """The agent's quiet segment from step ``s``, how many of the next ``left`` steps it
        covers and the comm module's next event; None if the agent decides in step ``s``."""
        plan = self.agent.plan(s, position)
        if not plan.settled:
            return None
        seg = plan[0]
        wake = self.agent.next_event(s)
        m = min(left, left if seg.steps is None else seg.steps, left if wake is None else wake - s + 1)
        return (seg, m, wake) if m > 0 else None

    def progress(self) -> list:
        """Everything that can be done now; returns the messages to publish, in order."""
        out, self._resend = self._resend, []
        if self._tick is not None and self._ready(self._tick.peers, self._tick.counts):
            tick, self._tick = self._tick, None
            self._finish_step(tick.peers, tick.counts, tick.t, tick.failed)
            obs = tick.observation
            self._learn(obs.sensed)
            plan = self.agent.plan(obs.t, obs.position) if self.lookahead else ()
            action = self.agent.act(obs)
            messages = self.agent.outbox()
            self.last = tick.t
            self._own = list(messages)
            self.sent += len(messages)
            self._plan = self._plan_steps(plan, obs, action) if plan and not messages else ()
            # Messages first: once the world has the action, the messages are out (if this process
            # dies right after, the world counts them and peers can relay them).
            step_out: list = []
            if messages:
                samples = [Sample(m, tick.t, k, self.run or "") for k, m in enumerate(messages)]
                step_out.extend(samples)
                self._sent[tick.t] = samples
                # A peer is at most one lockstep step behind: keep the last few steps only.
                while len(self._sent) > 3:
                    del self._sent[min(self._sent)]
            step_out.append(Acted(action, len(messages), self._plan, self.run or ""))
            self._last_tick, self._last_out = tick, step_out
            out.extend(step_out)
        if self._end is not None and self._tick is None and self._ready(self._end.peers, self._end.counts):
            end, self._end = self._end, None
            self._finish_step(end.peers, end.counts, end.steps, end.failed)
            self.finished = True
            self._report = self.report()
            out.append(self._report)
        return out

    def _learn(self, items: Iterable[Any]) -> None:
        for m in items:
            info = m if isinstance(m, ObjectInfo) else getattr(m, "object", None)
            if isinstance(info, ObjectInfo):
                self._known.setdefault(info.id, info)

    # ------------------------------------------------------------------ event skipping

    def _plan_steps(self, plan: Plan, obs: Observation, action: Action) -> PlanColumns | tuple[()]:
        """The steps after ``obs.t`` of the agent's plan (made before it acted in ``obs.t``), each
        with the observation it expects (the world checks it); cut where the agent would sense
        an object it reacts to. Built as the columns it travels in (no object per step)."""
        steps = rows(plan, obs.t, obs.position, 1 + min(self.lookahead, self._horizon))
        first = next(steps, None)
        if first is None or not action.does(*first[3:]):
            return ()  # the plan does not start with what it did (never, if plans are right)
        where = self._known_by_cell(self.agent.departures())
        kept: list[Row] = []
        count: list[int] = []
        ids: list[int] = []
        for row in steps:
            sensed = _predict_sensed(where, row[1], row[0]) if row[2] else ()
            if sensed and any(self.agent.news(self._known[i]) for i in sensed):
                break
            kept.append(row)
            count.append(len(sensed))
            ids.extend(sensed)
        if not kept:
            return ()
        _, position, searching, kind, direction, obj, state = zip(*kept)
        return PlanColumns(
            x=[p[0] for p in position], y=[p[1] for p in position], searching=searching,
            sensed_count=count, sensed=ids, kind=[PLAN_CODE[k] for k in kind],
            dx=[d[0] for d in direction], dy=[d[1] for d in direction], object=obj, state=state,
        )  # fmt: skip

    def _known_by_cell(self, departures: Mapping[int, int]) -> dict[Cell, list[tuple[int, int | None]]]:
        """Known objects by the cell they were found in, each with the step its carry starts
        (None: not known to start), ids ascending: built once per plan, read at every step."""
        by_cell: dict[Cell, list[tuple[int, int | None]]] = {}
        for info in self._known.values():
            by_cell.setdefault(info.location, []).append((info.id, departures.get(info.id)))
        for entries in by_cell.values():
            entries.sort()
        return by_cell

    # ------------------------------------------------------------------ end of run

    def report(self) -> AgentReport:
        k = self.agent.summary()
        schedule = tuple(ScheduleEntry(a.object, tuple(a.agents), a.start, a.finish) for a in k.schedule)
        found = tuple((int(o), int(t)) for o, t in k.found.items())
        return AgentReport(
            self.me,
            self.agent.protocol,
            k.trigger,
            k.predicted_makespan,
            k.coordinations,
            schedule,
            found,
            k.warnings,
            self.sent,
            k.view,
            run=self.run or "",
        )


def _predict_sensed(
    by_cell: Mapping[Cell, list[tuple[int, int | None]]], pos: Cell, s: int
) -> tuple[int, ...]:
    """Known objects expected in the 3×3 block at step ``s``: where they were found, unless
    the agent knows their carry has started by then."""
    out: list[int] = []
    for dx, dy in BLOCK:
        entries = by_cell.get((pos[0] + dx, pos[1] + dy))
        if entries:
            out.extend(i for i, start in entries if start is None or start >= s)
    return tuple(out)
