"""The world side of the lockstep protocol, ROS-free: ground truth driven by decoded messages.

Step t: send every agent its :class:`Tick` → collect one :class:`Acted` per agent → apply all
actions at once (``World.apply``, which validates and rejects) → t+1. The world counts who
broadcast how many protocol messages in step t and passes those counts on in the next ticks: the
agents' counting barrier.

Event skipping: if nobody broadcast in step t, every agent's plan covers step t+1 and the world's
observation of each agent is what its plan expects, the world applies the planned actions
itself and moves on without a round trip — repeated while that holds. The agents replay the same
steps locally when the next tick arrives, so the run is step-for-step the lockstep run.

Failures: ``fail(agent)`` (the node calls it when the agent's liveliness is lost) declares the
agent failed in the current step — an action it may already have sent for it is discarded — so
the step completes with the survivors, and every later tick tells everyone (``Tick.failed``).
That is the simulator's ``failures={agent: step}`` run. A step with a failure is never skipped
over: the notice is news to the agents, like a broadcast.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ost_ros import protocols
from ost_ros.coordination import Assignment, CoordinationPolicy
from ost_ros.engines import step_limit
from ost_ros.lockstep.messages import (
    Acted,
    AgentReport,
    PlanColumns,
    PlanStep,
    ProtocolViolation,
    RunEnd,
    Tick,
)
from ost_ros.messages import Action, AgentLost
from ost_ros.model import Scenario
from ost_ros.result import RunResult
from ost_ros.world import World


@dataclass
class WorldRuntime:
    scenario: Scenario
    max_steps: int | None = None
    skipping: bool = True
    run: str = ""  # the run id stamped on every message of the run
    world: World = field(init=False)
    messages: int = 0  # protocol messages the agents broadcast (as counted by ost sim)
    round_trips: int = 0  # steps run in lockstep (one Tick/Acted exchange each)
    skipped: int = 0  # steps executed from plans
    ended: RunEnd | None = None
    _acted: dict[int, Acted] = field(default_factory=dict)
    _answered: dict[int, Acted] = field(default_factory=dict)  # each agent's latest answer
    _reports: dict[int, AgentReport] = field(default_factory=dict)
    failed: dict[int, int] = field(default_factory=dict)  # agent -> step it failed in
    protocol: str = "ccp"  # the agents' protocol (whether it recovers from a failure)
    organisation: str = "distributed"  # who coordinates (the coordinator does not recover)
    aborted: str | None = None  # why the run was ended early (a failure the protocol cannot take)
    _gone: set[int] = field(default_factory=set)  # lost after the run ended (no report coming)
    _notices: dict[int, AgentLost] = field(default_factory=dict)  # what every later tick says
    # Called after every step the world executes, round trip or skipped: (world, actions) — the
    # step engine's hook (frames, timelines of a run followed live or replayed). Not pickled.
    on_step: Callable[[World, list[Action]], None] | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        self.world = World(self.scenario)
        self.ids = tuple(a.id for a in self.scenario.agents)  # ascending, as in the simulator
        self.limit = self.max_steps if self.max_steps is not None else step_limit(self.scenario)

    @property
    def live(self) -> tuple[int, ...]:
        """Agents not declared failed, ascending."""
        return tuple(i for i in self.ids if i not in self.failed)

    def fail(self, agent: int) -> RunEnd | list | None:
        """Declare ``agent`` failed in the current step. Returns what to publish now if that
        completes the step (the Tick list or RunEnd), else None. After the run's end only its
        report stops being waited for."""
        if agent not in self.ids or agent in self.failed or agent in self._gone:
            return None
        if self.ended is not None:
            self._gone.add(agent)  # the run is over: it just will not report
            return None
        self.failed[agent] = self.world.t
        self._notices[agent] = AgentLost(agent, self.world.t, self.world.dropped_by(agent))
        self._acted.pop(agent, None)
        self.world.fail(agent)
        try:
            protocols.check(
                self.protocol, policy=CoordinationPolicy(organisation=self.organisation), failures=True
            )
        except protocols.ProtocolError as exc:
            self.aborted = f"agent {agent} failed in step {self.world.t}; {exc}"
            self.ended = RunEnd(self.world.t, self.world.t - 1, False, (), (), self.run, self._failed())
            return self.ended
        if self.max_steps is None:  # survivors may need longer than the fault-free bound
            self.limit = max(self.limit, step_limit(self.scenario, len(self.failed)))
        return self.advance() if self.step_complete else None

    def _failed(self) -> tuple[AgentLost, ...]:
        return tuple(self._notices[a] for a in sorted(self._notices))

    # ------------------------------------------------------------------ stepping

    def start(self) -> list[Tick] | RunEnd:
        return self._next(last=-1, sent={})

    def accept_acted(self, acted: Acted) -> None:
        a = acted.action
        if acted.run != self.run:
            raise ProtocolViolation(f"action of run {acted.run!r}, this is run {self.run!r}")
        if a.agent not in self.ids:
            raise ProtocolViolation(f"action from agent {a.agent}, not in the team")
        if a.agent in self.failed:
            raise ProtocolViolation(
                f"action of agent {a.agent}, declared failed in step {self.failed[a.agent]}"
            )
        if a.t < self.world.t and self._answered.get(a.agent) == acted:
            return  # a re-sent answer that arrived after the step was done
        if self.ended is not None or a.t != self.world.t:
            raise ProtocolViolation(
                f"action of agent {a.agent} for step {a.t}, world is at step "
                f"{self.world.t}" + (" (run ended)" if self.ended else "")
            )
        if a.agent in self._acted:
            if self._acted[a.agent] == acted:
                return  # the same answer again (the agent re-sent it)
            raise ProtocolViolation(f"second, different action of agent {a.agent} for step {a.t}")
        self._answered[a.agent] = acted
        self._acted[a.agent] = acted

    def acted_agents(self) -> tuple[int, ...]:
        """Agents whose action for the current step is in."""
        return tuple(self._acted)

    @property
    def step_complete(self) -> bool:
        return self.ended is None and len(self._acted) == len(self.live)

    def advance(self) -> list[Tick] | RunEnd:
        """All actions of the step are in: apply them, skip what can be skipped, say what next."""
        live = self.live
        acted = [self._acted[i] for i in live]
        self._acted = {}
        last = self.world.t
        sent = {x.action.agent: x.sent for x in acted if x.sent > 0}  # the agents' barrier counts
        self.messages += sum(sent.values())
        self._apply([x.action for x in acted])
        self.round_trips += 1
        news = last in self.failed.values()  # a failure notice: the agents must hear it
        if self.skipping and not sent and not news and acted:
            self._skip(live, [x.plan for x in acted])
        return self._next(last, sent)

    def _skip(self, live: tuple[int, ...], plans: list[Sequence[PlanStep]]) -> None:
        team = list(zip(live, [PlanColumns.of(p) for p in plans]))  # as they came off the wire
        for k in range(min(len(plan) for _, plan in team)):
            if self.world.done or self.world.t >= self.limit:
                return
            if not all(self._as_planned(agent, plan, k) for agent, plan in team):
                return
            t = self.world.t
            self._apply([plan.action(agent, t, k) for agent, plan in team])
            self.skipped += 1

    def _as_planned(self, agent: int, plan: PlanColumns, k: int) -> bool:
        """Whether the world's observation of ``agent`` is what step k of its plan expects: the
        position always, the sensed objects when searching (read without building the
        observation: the world checks every agent's plan at every skipped step)."""
        pos = self.world.positions[agent]
        if pos[0] != plan.x[k] or pos[1] != plan.y[k]:
            return False
        return not plan.searching[k] or self.world.sensed_ids(agent) == plan.sensed_at(k)

    def _apply(self, actions: list[Action]) -> None:
        self.world.apply(actions)
        if self.on_step is not None:
            self.on_step(self.world, actions)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["on_step"] = None  # a checkpoint holds the truth, not who watches it
        return state

    def _next(self, last: int, sent: dict[int, int]) -> list[Tick] | RunEnd:
        w = self.world
        failed = self._failed()
        peers, counts = tuple(sent), tuple(sent.values())
        if w.done or w.t >= self.limit or not self.live:
            self.ended = RunEnd(w.t, last, w.done, peers, counts, self.run, failed)
            return self.ended
        return [Tick(w.t, last, w.observe(i), peers, counts, self.run, failed) for i in self.live]

    # ------------------------------------------------------------------ result

    def accept_report(self, report: AgentReport) -> None:
        if report.run != self.run:
            raise ProtocolViolation(f"report of run {report.run!r}, this is run {self.run!r}")
        if self.ended is None:
            raise ProtocolViolation(f"report of agent {report.agent} before the run ended")
        if report.agent not in self.ids:
            raise ProtocolViolation(f"report from agent {report.agent}, not in the team")
        if report.agent in self._reports:
            if self._reports[report.agent] == report:
                return  # re-sent (after a re-sent run_end)
            raise ProtocolViolation(f"second, different report of agent {report.agent}")
        self._reports[report.agent] = report

    @property
    def reports(self) -> dict[int, AgentReport]:
        """The agents' reports so far, by agent."""
        return dict(self._reports)

    @property
    def missing_reports(self) -> tuple[int, ...]:
        return tuple(i for i in self.live if i not in self._reports and i not in self._gone)

    def result(self) -> RunResult:
        """The same record as ``ost_ros.engines.finish_result``, from the agents' reports
        (the survivors': a failed agent reports nothing)."""
        reports = [self._reports[i] for i in self.live if i in self._reports]
        if self.aborted or not reports:  # ended early: the world's truth is all there is
            result = self.world.result(protocol=self.protocol, messages=self.messages)
            result.error = self.aborted or "every agent failed"
            return result
        return result_from_reports(self.world, reports, self.messages, self.protocol)


def result_from_reports(
    world: Any, reports: Sequence[AgentReport], messages: int, protocol: str
) -> RunResult:
    """The run's record — ``world.result`` (the lockstep :class:`World` or the realtime world) — with
    what the agents know from their reports: the prediction and schedule (the first's), agreement
    (every view alike), when each object was first found, their warnings. As
    ``ost_ros.engines.finish_result`` builds it in process."""
    if not reports:
        result = world.result(protocol=protocol, messages=messages)
        result.error = result.error or "every agent failed"
        return result
    first = reports[0]
    found: dict[int, int] = {}
    for r in reports:  # CCP: everyone knows every find; HCP: each owner knows its own
        for oid, t in r.found:
            found[oid] = min(t, found.get(oid, t))
    result = world.result(
        protocol=first.protocol,
        trigger=first.trigger,
        predicted_makespan=first.predicted_makespan,
        coordinations=first.coordinations,
        messages=messages,
        agreement=all(r.view == first.view for r in reports),
        warnings=[f"agent {r.agent}: {w}" for r in reports for w in r.warnings],
        found=dict(sorted(found.items())),
        schedule=[Assignment(e.object, tuple(e.agents), e.start, e.finish) for e in first.schedule],
    )
    if not result.completed and result.error is None:
        result.error = f"not finished after {world.t} steps (deadlock or step limit)"
    return result
