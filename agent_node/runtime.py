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

import copy
from dataclasses import dataclass, field

from ost_msgs_py.messages import (Action, ActionKind, AgentLost, NegotiationOffer, Observation,
                                  ObjectInfo)
from ost_msgs_py.runtime import (CHANNELS, ProtocolViolation, Acted, AgentReport, PlanStep, Resend,
                                 RunEnd, ScheduleEntry, StepMessages, Tick)
from ost_ros.agent import CcpAgent
from ost_ros.recovery import Sweep
from ost_ros.model import can_move, group_period
from ost_ros.motion import apply as move

_SENSE = tuple((dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1))   # the world's sensing order


@dataclass
class AgentRuntime:
    agent: object                       # a core agent: act(obs), outbox(), communicate(t, msgs)
    team: tuple[int, ...]               # every agent id, ascending (the simulator's inbox order)
    trigger: str = ""
    lookahead: int = 0                  # plan this many quiet steps ahead (0: no event skipping)
    last: int = -1                      # the last step this agent acted on
    sent: int = 0                       # protocol messages broadcast so far
    finished: bool = False
    _tick: Tick | None = None
    _end: RunEnd | None = None
    _batches: dict[int, dict[int, dict[str, StepMessages]]] = field(default_factory=dict)
    _own: list = field(default_factory=list)
    _plan: tuple[PlanStep, ...] = ()
    _known: dict[int, ObjectInfo] = field(default_factory=dict)
    _horizon: int = 8                   # current planning depth, adapted to what the world skips
    # Recovery from a lost sample: what was published for the last step, to publish again.
    _last_tick: Tick | None = None
    _last_out: list = field(default_factory=list)
    _batches_sent: dict[int, list[StepMessages]] = field(default_factory=dict)
    _resend: list = field(default_factory=list)
    _relay: dict[int, dict[int, dict[str, StepMessages]]] = field(default_factory=dict)
    _report: AgentReport | None = None
    run: str | None = None              # the world's run id, from the first tick
    _early: list = field(default_factory=list)   # batches that came before the first tick
    dropped: list = field(default_factory=list)  # (sender, why) of messages of other runs

    @property
    def me(self) -> int:
        return self.agent.id

    # ------------------------------------------------------------------ input

    def accept_batch(self, batch: StepMessages) -> None:
        if self.run is None:
            self._early.append(batch)   # checked once the first tick says which run this is
            return
        if batch.run != self.run:
            raise ProtocolViolation(f"step_messages of run {batch.run!r}, this is run {self.run!r}")
        if batch.sender == self.me:
            return  # own batch: kept locally when sent
        if batch.sender not in self.team:
            raise ProtocolViolation(f"step_messages from agent {batch.sender}, not in the team")
        if batch.channel not in CHANNELS or not 1 <= batch.parts <= len(CHANNELS):
            raise ProtocolViolation(f"step_messages of agent {batch.sender}: channel "
                                    f"{batch.channel!r}, {batch.parts} parts")
        if batch.t < self.last:
            return  # a re-sent batch of a step already done (see Resend)
        parts = self._batches.setdefault(batch.t, {}).setdefault(batch.sender, {})
        known = parts.get(batch.channel)
        if known is not None:
            if known == batch:
                return  # the same batch again (see Resend)
            raise ProtocolViolation(f"second, different step_messages of agent {batch.sender} "
                                    f"for step {batch.t}")
        if any(p.parts != batch.parts for p in parts.values()):
            raise ProtocolViolation(f"step_messages of agent {batch.sender} for step {batch.t} "
                                    "disagree on their number of parts")
        parts[batch.channel] = batch

    def accept_resend(self, req: Resend) -> None:
        """A peer lacks this agent's batch of step ``req.t``: publish it again (if there was one)."""
        if req.run != self.run:
            raise ProtocolViolation(f"resend request of run {req.run!r}, this is run {self.run!r}")
        if req.sender not in self.team:
            raise ProtocolViolation(f"resend request from agent {req.sender}, not in the team")
        if self.me in req.peers:
            self._resend.extend(b for b in self._batches_sent.get(req.t, ()) if b not in self._resend)
        for peer in req.peers:   # relay what this agent holds of others (a sender may be dead)
            if peer in (self.me, req.sender):
                continue
            parts = self._relay.get(req.t, {}).get(peer) or self._batches.get(req.t, {}).get(peer) or {}
            self._resend.extend(b for b in parts.values() if b not in self._resend)

    def accept_tick(self, tick: Tick) -> None:
        if tick.observation.agent != self.me or tick.observation.t != tick.t:
            raise ProtocolViolation(f"tick for agent {tick.observation.agent} step "
                                    f"{tick.observation.t}, this is agent {self.me}")
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
            raise ProtocolViolation(f"tick for step {tick.t} after {tick.last}, this agent acted "
                                    f"last in step {self.last}")
        if tick.t - tick.last - 1 > len(self._plan):
            raise ProtocolViolation(f"tick skips {tick.t - tick.last - 1} steps, the plan has "
                                    f"{len(self._plan)}")
        self._tick = tick

    def accept_end(self, end: RunEnd) -> None:
        if end.run != self.run:
            raise ProtocolViolation(f"run_end of run {end.run!r}, this is run {self.run!r}")
        if self._report is not None:
            if self._report not in self._resend:   # the world re-sent run_end: report again
                self._resend.append(self._report)
            return
        if end == self._end:
            return
        if end.last != self.last or end.steps - end.last - 1 > len(self._plan):
            raise ProtocolViolation(f"run_end after step {end.last} (+{end.steps - end.last - 1} "
                                    f"skipped), this agent acted last in step {self.last}")
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
        return bool(parts) and len(parts) == next(iter(parts.values())).parts

    def _ready(self, peers: tuple[int, ...]) -> bool:
        return all(p == self.me or self._has(p) for p in peers)

    def _finish_step(self, peers: tuple[int, ...], until: int,
                     failed: tuple[AgentLost, ...] = ()) -> None:
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
                    # the sender's outbox order: negotiation moves (its comm module) first
                    parts = have[sender]
                    for channel in ("negotiation", "step"):
                        if channel in parts:
                            inbox.extend(parts[channel].messages)
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
            action = self.agent.act(obs)
            messages = self.agent.outbox()
            self.last = tick.t
            self._own = list(messages)
            self.sent += len(messages)
            self._plan = self._make_plan(obs, action) if self.lookahead and not messages else ()
            # Batches first: once the world has the action, the batches are out (if this process
            # dies right after, the world counts them and peers can relay them).
            step_out: list = []
            if messages:
                batches = split_batch(self.me, tick.t, messages, self.run)
                step_out.extend(batches)
                self._batches_sent[tick.t] = batches
                # A peer is at most one lockstep step behind: keep the last few batches only.
                while len(self._batches_sent) > 3:
                    del self._batches_sent[min(self._batches_sent)]
            step_out.append(Acted(action, len(messages), self._plan, self.run))
            self._last_tick, self._last_out = tick, step_out
            out.extend(step_out)
        if self._end is not None and self._tick is None and self._ready(self._end.peers):
            end, self._end = self._end, None
            self._finish_step(end.peers, end.steps, end.failed)
            self.finished = True
            self._report = self.report()
            out.append(self._report)
        return out

    def _learn(self, items) -> None:
        for m in items:
            info = m if isinstance(m, ObjectInfo) else getattr(m, "object", None)
            if isinstance(info, ObjectInfo):
                self._known.setdefault(info.id, info)

    # ------------------------------------------------------------------ event skipping

    def _make_plan(self, obs: Observation, action: Action) -> tuple[PlanStep, ...]:
        """Run a copy of the agent ahead while nothing would be said: its actions for the quiet
        steps t+1, t+2, ..., each with the observation it expects (the world checks it)."""
        team = getattr(self.agent, "team", None)
        clone = copy.deepcopy(self.agent, {id(team): team} if team is not None else None)
        clone.communicate(obs.t, [])
        if clone.outbox():
            return ()
        pos = self._next_position(obs.position, action, obs.t)
        plan = []
        for s in range(obs.t + 1, obs.t + 1 + min(self.lookahead, self._horizon)):
            reads = self._reads_sensor(clone)
            sensed = self._predict_sensed(pos, s) if reads else ()
            o = Observation(self.me, s, pos, tuple(self._known[i] for i in sensed))
            act = clone.act(o)
            if clone.outbox():
                break
            plan.append(_plan_step(o, act, reads))
            clone.communicate(s, [])
            pos = self._next_position(pos, act, s)
        return tuple(plan)

    def _reads_sensor(self, agent) -> bool:
        # CcpAgent looks at its sensor only while searching; for any other agent class assume it
        # always does (the world then also compares what is sensed: slower, never wrong).
        if type(agent).act is CcpAgent.act:
            return agent.reads_sensor()
        return True

    def _scheduled(self) -> dict[int, ScheduleEntry | object]:
        comm = getattr(self.agent, "comm", None)
        return {a.object: a for a in getattr(comm, "schedule", ()) if not isinstance(a, Sweep)}

    def _next_position(self, pos, action: Action, t: int):
        if action.kind is ActionKind.MOVE:
            return move(pos, action.direction)
        if action.kind is ActionKind.CARRY:
            # Planned = executed: the group is complete from the assignment's start on, and
            # moves in the steps its slowest member can move in.
            a = self._scheduled().get(action.object)
            if a is not None and t >= a.start and can_move(t, self._group_period(a.agents)):
                return move(pos, action.direction)
        return pos

    def _group_period(self, agents) -> int:
        team = getattr(self.agent, "team", None)
        if team is None or not team.periods:
            return 1
        return group_period([team.periods[team.index(j)] for j in agents])

    def _predict_sensed(self, pos, s: int) -> tuple[int, ...]:
        """Known objects expected at their original cell in the 3×3 block at step ``s``."""
        sched = self._scheduled()
        by_cell: dict[tuple[int, int], list[int]] = {}
        for info in self._known.values():
            a = sched.get(info.id)
            if a is None or a.start >= s:
                by_cell.setdefault(info.location, []).append(info.id)
        out: list[int] = []
        for dx, dy in _SENSE:
            ids = by_cell.get((pos[0] + dx, pos[1] + dy))
            if ids:
                out.extend(sorted(ids))
        return tuple(out)

    # ------------------------------------------------------------------ end of run

    def report(self) -> AgentReport:
        comm = getattr(self.agent, "comm", None)
        schedule = tuple(ScheduleEntry(a.object, tuple(a.agents), a.start, a.finish)
                         for a in getattr(comm, "schedule", ()) if not isinstance(a, Sweep))
        found = tuple((int(k), int(v)) for k, v in getattr(comm, "found_at", {}).items())
        protocol = self.agent.protocol
        # As ost_ros.simulator.finish_result: CCP/NCP agents agree on the schedule, HCP on the groups.
        view = getattr(comm, "groups", None) if protocol == "hcp" else getattr(comm, "schedule", None)
        return AgentReport(self.me, protocol, self.trigger if protocol != "hcp" else "help",
                           getattr(comm, "predicted_makespan", None),
                           int(getattr(comm, "coordinations", 0)), schedule, found,
                           tuple(getattr(self.agent, "warnings", ())), self.sent, repr(view),
                           run=self.run or "")


def split_batch(sender: int, t: int, messages: list, run: str = "") -> list[StepMessages]:
    """A step's messages as batches per channel: NCP moves on ``negotiation``, the rest on ``step``."""
    moves = tuple(m for m in messages if isinstance(m, NegotiationOffer))
    rest = tuple(m for m in messages if not isinstance(m, NegotiationOffer))
    parts = [(c, ms) for c, ms in (("step", rest), ("negotiation", moves)) if ms]
    return [StepMessages(sender, t, ms, c, len(parts), run) for c, ms in parts]


def _plan_step(obs: Observation, action: Action, reads: bool) -> PlanStep:
    return PlanStep(obs.position, reads, tuple(o.id for o in obs.sensed) if reads else (),
                    action.kind, tuple(action.direction), action.object, action.state)


def _same_action(action: Action, step: PlanStep) -> bool:
    return (action.kind is step.kind and tuple(action.direction) == tuple(step.direction)
            and action.object == step.object and action.state == step.state)
