"""The agent side of the lockstep protocol, ROS-free: one core agent driven by decoded messages.

Per step the agent node feeds it a :class:`Tick` and peers' :class:`StepMessages`; it answers
with what to publish. Order inside the agent is exactly the in-process simulator's:

    Tick(t, last, peers) → comm module for step ``last`` with the batches of ``peers`` (+ own)
                         → replay skipped steps last+1 .. t-1 from the own plan (no messages)
                         → act(observation t) → publish Acted(t) and, if any, StepMessages(t)

A Tick is held until every listed peer's batch of step ``last`` is in (the counting barrier). The
core agent runs unchanged; this class only orders its calls. A failure the world announces for
step ``last`` (``Tick.failed``) joins that step's inbox as an ``AgentLost``, after the peers'
messages — the simulator's order. Batches are published before the action, and every agent
keeps the batches of the last few steps, so a peer's batch that a failed sender got to only
some agents is relayed by the others on a Resend.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

from ost_msgs_py.messages import Action, AgentLost, AgentMessage, ObjectInfo, Observation
from ost_msgs_py.runtime import (
    Acted,
    AgentReport,
    PlanStep,
    ProtocolViolation,
    Resend,
    RunEnd,
    ScheduleEntry,
    StepMessages,
    Tick,
)
from ost_ros import protocols
from ost_ros.model import Cell
from ost_ros.protocols.base import ProtocolAgent
from ost_ros.protocols.plans import Plan, PlannedStep, unroll

_SENSE = tuple((dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1))  # the world's sensing order


STEP = "step"  # the channel of every protocol message without a channel of its own


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
    _batches: dict[int, dict[int, dict[str, StepMessages]]] = field(default_factory=dict)
    _own: list[AgentMessage] = field(default_factory=list)
    _plan: tuple[PlanStep, ...] = ()
    _known: dict[int, ObjectInfo] = field(default_factory=dict)
    _horizon: int = 8  # current planning depth, adapted to what the world skips
    # Recovery from a lost sample: what was published for the last step, to publish again.
    _last_tick: Tick | None = None
    _last_out: list[Any] = field(default_factory=list)
    _batches_sent: dict[int, list[StepMessages]] = field(default_factory=dict)
    _resend: list[Any] = field(default_factory=list)
    _relay: dict[int, dict[int, dict[str, StepMessages]]] = field(default_factory=dict)
    _report: AgentReport | None = None
    run: str | None = None  # the world's run id, from the first tick
    _early: list[StepMessages] = field(default_factory=list)  # batches before the first tick
    dropped: list[tuple[int, str]] = field(default_factory=list)  # (sender, why): other runs'

    def __post_init__(self) -> None:
        # the transport channels of the agent's protocol: "step", then its own (registry)
        self.channels: dict[str, tuple[type, ...]] = dict(protocols.get(self.agent.protocol).channels)

    @property
    def me(self) -> int:
        return self.agent.id

    # ------------------------------------------------------------------ input

    def accept_batch(self, batch: StepMessages) -> None:
        if self.run is None:
            self._early.append(batch)  # checked once the first tick says which run this is
            return
        if batch.run != self.run:
            raise ProtocolViolation(f"step_messages of run {batch.run!r}, this is run {self.run!r}")
        if batch.sender == self.me:
            return  # own batch: kept locally when sent
        if batch.sender not in self.team:
            raise ProtocolViolation(f"step_messages from agent {batch.sender}, not in the team")
        if (batch.channel != STEP and batch.channel not in self.channels) or not 1 <= batch.parts <= 1 + len(
            self.channels
        ):
            raise ProtocolViolation(
                f"step_messages of agent {batch.sender}: channel {batch.channel!r}, {batch.parts} parts"
            )
        if batch.t < self.last:
            return  # a re-sent batch of a step already done (see Resend)
        parts = self._batches.setdefault(batch.t, {}).setdefault(batch.sender, {})
        known = parts.get(batch.channel)
        if known is not None:
            if known == batch:
                return  # the same batch again (see Resend)
            raise ProtocolViolation(
                f"second, different step_messages of agent {batch.sender} for step {batch.t}"
            )
        if any(p.parts != batch.parts for p in parts.values()):
            raise ProtocolViolation(
                f"step_messages of agent {batch.sender} for step {batch.t} disagree on their number of parts"
            )
        parts[batch.channel] = batch

    def accept_resend(self, req: Resend) -> None:
        """A peer lacks this agent's batch of step ``req.t``: publish it again (if there was one)."""
        if req.run != self.run:
            raise ProtocolViolation(f"resend request of run {req.run!r}, this is run {self.run!r}")
        if req.sender not in self.team:
            raise ProtocolViolation(f"resend request from agent {req.sender}, not in the team")
        if self.me in req.peers:
            self._resend.extend(b for b in self._batches_sent.get(req.t, ()) if b not in self._resend)
        for peer in req.peers:  # relay what this agent holds of others (a sender may be dead)
            if peer in (self.me, req.sender):
                continue
            parts = self._relay.get(req.t, {}).get(peer) or self._batches.get(req.t, {}).get(peer) or {}
            self._resend.extend(b for b in parts.values() if b not in self._resend)

    def accept_tick(self, tick: Tick) -> None:
        if tick.observation.agent != self.me or tick.observation.t != tick.t:
            raise ProtocolViolation(
                f"tick for agent {tick.observation.agent} step {tick.observation.t}, this is agent {self.me}"
            )
        if self.run is not None and tick.run != self.run:
            raise ProtocolViolation(f"tick of run {tick.run!r}, this is run {self.run!r}")
        if self.run is None and tick.t == 0 and tick.last == -1:
            self.run = tick.run
            early, self._early = self._early, []
            for b in early:
                try:
                    self.accept_batch(b)
                except ProtocolViolation as exc:
                    self.dropped.append((b.sender, str(exc)))
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
        if end.last != self.last or end.steps - end.last - 1 > len(self._plan):
            raise ProtocolViolation(
                f"run_end after step {end.last} (+{end.steps - end.last - 1} "
                f"skipped), this agent acted last in step {self.last}"
            )
        self._end = end

    # ------------------------------------------------------------------ progress

    def held(self) -> tuple[int, tuple[int, ...]] | None:
        """A tick held by the barrier: its step and the peers whose step messages are missing."""
        if self._tick is None:
            return None
        return self._tick.t, tuple(p for p in self._tick.peers if p != self.me and not self._has(p))

    def _has(self, peer: int) -> bool:
        """Every part of ``peer``'s batch of step ``self.last`` is in."""
        parts = self._batches.get(self.last, {}).get(peer)
        return parts is not None and len(parts) > 0 and len(parts) == next(iter(parts.values())).parts

    def _ready(self, peers: tuple[int, ...]) -> bool:
        return all(p == self.me or self._has(p) for p in peers)

    def _finish_step(self, peers: tuple[int, ...], until: int, failed: tuple[AgentLost, ...] = ()) -> None:
        """Comm module for ``self.last``, then replay the skipped steps up to ``until`` - 1."""
        if self.last >= 0:
            have = self._batches.pop(self.last, {})
            self._relay[self.last] = have
            while len(self._relay) > 3:
                del self._relay[min(self._relay)]
            inbox = []
            for sender in self.team:
                if sender == self.me:
                    inbox.extend(self._own)
                elif sender in peers:
                    # the sender's outbox order: its comm module's (own channels) first
                    parts = have[sender]
                    for channel in (*self.channels, STEP):
                        if channel in parts:
                            inbox.extend(cast(Sequence[AgentMessage], parts[channel].messages))
            inbox.extend(m for m in failed if m.t == self.last)
            self._learn(inbox)
            self.agent.communicate(self.last, inbox)
        # Plan about twice as far as the world last skipped: long quiet stretches get long plans,
        # busy phases (every plan cut short by someone's message) cost little planning.
        self._horizon = max(8, min(self.lookahead, 2 * (until - self.last - 1)))
        for k, s in enumerate(range(self.last + 1, until)):
            step = self._plan[k]
            obs = Observation(self.me, s, step.position, tuple(self._known[i] for i in step.sensed))
            action = self.agent.act(obs)
            if self.agent.outbox() or not _same_action(action, step):
                raise ProtocolViolation(f"replaying step {s}: the agent deviated from its plan")
            self.agent.communicate(s, [])
        self._own = []
        self._plan = ()

    def progress(self) -> list:
        """Everything that can be done now; returns the messages to publish, in order."""
        out, self._resend = self._resend, []
        if self._tick is not None and self._ready(self._tick.peers):
            tick, self._tick = self._tick, None
            self._finish_step(tick.peers, tick.t, tick.failed)
            obs = tick.observation
            self._learn(obs.sensed)
            plan = self.agent.plan(obs.t, obs.position) if self.lookahead else ()
            action = self.agent.act(obs)
            messages = self.agent.outbox()
            self.last = tick.t
            self._own = list(messages)
            self.sent += len(messages)
            self._plan = self._plan_steps(plan, obs, action) if plan and not messages else ()
            # Batches first: once the world has the action, the batches are out (if this process
            # dies right after, the world counts them and peers can relay them).
            step_out: list = []
            if messages:
                batches = split_batch(self.me, tick.t, messages, self.run or "", self.channels)
                step_out.extend(batches)
                self._batches_sent[tick.t] = batches
                # A peer is at most one lockstep step behind: keep the last few batches only.
                while len(self._batches_sent) > 3:
                    del self._batches_sent[min(self._batches_sent)]
            step_out.append(Acted(action, len(messages), self._plan, self.run or ""))
            self._last_tick, self._last_out = tick, step_out
            out.extend(step_out)
        if self._end is not None and self._tick is None and self._ready(self._end.peers):
            end, self._end = self._end, None
            self._finish_step(end.peers, end.steps, end.failed)
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

    def _plan_steps(self, plan: Plan, obs: Observation, action: Action) -> tuple[PlanStep, ...]:
        """The steps after ``obs.t`` of the agent's plan (made before it acted in ``obs.t``), each
        with the observation it expects (the world checks it); cut where the agent would sense
        an object it reacts to."""
        steps = unroll(plan, obs.t, obs.position, 1 + min(self.lookahead, self._horizon))
        if not steps or not _same_action(action, steps[0]):
            return ()  # the plan does not start with what it did (never, if plans are right)
        departures = self.agent.departures()
        out = []
        for st in steps[1:]:
            sensed = self._predict_sensed(st.position, st.t, departures) if st.reads_sensor else ()
            if any(self.agent.news(self._known[i]) for i in sensed):
                break
            out.append(
                PlanStep(st.position, st.reads_sensor, sensed, st.kind, st.direction, st.object, st.state)
            )
        return tuple(out)

    def _predict_sensed(self, pos: Cell, s: int, departures: Mapping[int, int]) -> tuple[int, ...]:
        """Known objects expected in the 3×3 block at step ``s``: where they were found, unless
        the agent knows their carry has started by then."""
        by_cell: dict[Cell, list[int]] = {}
        for info in self._known.values():
            start = departures.get(info.id)
            if start is None or start >= s:
                by_cell.setdefault(info.location, []).append(info.id)
        out: list[int] = []
        for dx, dy in _SENSE:
            ids = by_cell.get((pos[0] + dx, pos[1] + dy))
            if ids:
                out.extend(sorted(ids))
        return tuple(out)

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


def split_batch(
    sender: int,
    t: int,
    messages: Sequence[AgentMessage],
    run: str = "",
    channels: Mapping[str, tuple[type, ...]] | None = None,
) -> list[StepMessages]:
    """A step's messages as batches per channel: each protocol message kind its protocol gives a
    channel of its own goes there (NCP's moves), the rest on ``step``."""
    own = {cls: name for name, kinds in (channels or {}).items() for cls in kinds}
    split: dict[str, list[AgentMessage]] = {STEP: []}
    for m in messages:
        split.setdefault(own.get(type(m), STEP), []).append(m)
    parts = [(c, tuple(ms)) for c, ms in split.items() if ms]
    return [StepMessages(sender, t, cast(tuple[Any, ...], ms), c, len(parts), run) for c, ms in parts]


def _same_action(action: Action, step: PlanStep | PlannedStep) -> bool:
    return (
        action.kind is step.kind
        and tuple(action.direction) == tuple(step.direction)
        and action.object == step.object
        and action.state == step.state
    )
