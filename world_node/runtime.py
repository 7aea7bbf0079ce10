"""The world side of the lockstep protocol, ROS-free: ground truth driven by decoded messages.

Step t: send every agent its :class:`Tick` → collect one :class:`Acted` per agent → apply all
actions at once (``World.apply``, which validates and rejects) → t+1. The world counts who
broadcast protocol messages in step t and passes that list on in the next ticks: the agents'
counting barrier.

Event skipping: if nobody broadcast in step t, every agent's plan covers step t+1 and the world's
observation of each agent is what its plan expects, the world applies the planned actions
itself and moves on without a round trip — repeated while that holds. The agents replay the same
steps locally when the next tick arrives, so the run is step-for-step the lockstep run.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ost_msgs_py.messages import Action, Observation
from ost_msgs_py.runtime import ProtocolViolation, Acted, AgentReport, PlanStep, RunEnd, Tick
from ost_ros.coordination import Assignment
from ost_ros.model import Scenario
from ost_ros.result import RunResult
from ost_ros.simulator import step_limit
from ost_ros.world import World


@dataclass
class WorldRuntime:
    scenario: Scenario
    max_steps: int | None = None
    skipping: bool = True
    run: str = ""                # the run id stamped on every message of the run
    world: World = field(init=False)
    messages: int = 0            # protocol messages the agents broadcast (as counted by ost sim)
    round_trips: int = 0         # steps run in lockstep (one Tick/Acted exchange each)
    skipped: int = 0             # steps executed from plans
    ended: RunEnd | None = None
    _acted: dict[int, Acted] = field(default_factory=dict)
    _answered: dict[int, Acted] = field(default_factory=dict)   # each agent's latest answer
    _reports: dict[int, AgentReport] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.world = World(self.scenario)
        self.ids = tuple(a.id for a in self.scenario.agents)   # ascending, as in the simulator
        self.limit = self.max_steps if self.max_steps is not None else step_limit(self.scenario)

    # ------------------------------------------------------------------ stepping

    def start(self) -> list[Tick] | RunEnd:
        return self._next(last=-1, peers=())

    def accept_acted(self, acted: Acted) -> None:
        a = acted.action
        if acted.run != self.run:
            raise ProtocolViolation(f"action of run {acted.run!r}, this is run {self.run!r}")
        if a.agent not in self.ids:
            raise ProtocolViolation(f"action from agent {a.agent}, not in the team")
        if a.t < self.world.t and self._answered.get(a.agent) == acted:
            return  # a re-sent answer that arrived after the step was done
        if self.ended is not None or a.t != self.world.t:
            raise ProtocolViolation(f"action of agent {a.agent} for step {a.t}, world is at step "
                                    f"{self.world.t}" + (" (run ended)" if self.ended else ""))
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
        return len(self._acted) == len(self.ids)

    def advance(self) -> list[Tick] | RunEnd:
        """All actions of the step are in: apply them, skip what can be skipped, say what next."""
        acted = [self._acted[i] for i in self.ids]
        self._acted = {}
        last = self.world.t
        peers = tuple(x.action.agent for x in acted if x.sent > 0)
        self.messages += sum(x.sent for x in acted)
        self.world.apply([x.action for x in acted])
        self.round_trips += 1
        if self.skipping and not peers:
            self._skip([x.plan for x in acted])
        return self._next(last, peers)

    def _skip(self, plans: list[tuple[PlanStep, ...]]) -> None:
        for k in range(min(len(p) for p in plans)):
            if self.world.done or self.world.t >= self.limit:
                return
            t = self.world.t
            actions = []
            for agent, plan in zip(self.ids, plans):
                step = plan[k]
                if not _expected(self.world.observe(agent), step):
                    return
                actions.append(Action(agent, t, step.kind, step.direction, step.object, step.state))
            self.world.apply(actions)
            self.skipped += 1

    def _next(self, last: int, peers: tuple[int, ...]) -> list[Tick] | RunEnd:
        w = self.world
        if w.done or w.t >= self.limit:
            self.ended = RunEnd(w.t, last, w.done, peers, self.run)
            return self.ended
        return [Tick(w.t, last, w.observe(i), peers, self.run) for i in self.ids]

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
    def missing_reports(self) -> tuple[int, ...]:
        return tuple(i for i in self.ids if i not in self._reports)

    def result(self) -> RunResult:
        """The same record as ``ost_ros.simulator.finish_result``, from the agents' reports."""
        reports = [self._reports[i] for i in self.ids]
        first = reports[0]
        agreement = all(r.view == first.view for r in reports)
        found: dict[int, int] = {}
        for r in reports:   # CCP: everyone knows every find; HCP: each owner knows its own
            for oid, t in r.found:
                found[oid] = min(t, found.get(oid, t))
        warnings = [f"agent {r.agent}: {w}" for r in reports for w in r.warnings]
        schedule = [Assignment(e.object, tuple(e.agents), e.start, e.finish) for e in first.schedule]
        result = self.world.result(protocol=first.protocol, trigger=first.trigger,
                                   predicted_makespan=first.predicted_makespan,
                                   coordinations=first.coordinations, messages=self.messages,
                                   agreement=agreement, warnings=warnings, found=dict(sorted(found.items())),
                                   schedule=schedule)
        if not result.completed:
            result.error = f"not finished after {self.world.t} steps (deadlock or step limit)"
        return result


def _expected(obs: Observation, step: PlanStep) -> bool:
    if tuple(obs.position) != tuple(step.position):
        return False
    return not step.searching or tuple(o.id for o in obs.sensed) == tuple(step.sensed)
