"""A run rebuilt from its messages, ROS-free: the world's own runtime fed what the nodes said.

:class:`RunFollower` takes the run's messages in any order in which they can arrive — the
world's :class:`RunInfo`, the agents' :class:`Ready`, every :class:`Tick`, :class:`Acted` and
:class:`RunEnd`, the agents' :class:`AgentReport` — and drives a :class:`WorldRuntime` through
exactly the steps the world node took: step s is executed once the world's next tick (or its
run end) says that s is over and every surviving agent's action for s is in; failures are
applied where the world's notices put them; the skipped steps follow from the agents' plans,
as in the world. Every step executed calls ``on_step(world, actions)`` — the frames of a live
view, the timeline of a replay. At the end the agents' reports give the same result as the
world's ``<ns>/result``, rebuilt without a single node: ``ost replay`` checks that it is
(:mod:`ost_msgs_py.replay` feeds it a recording).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ost_ros.bounds import lower_bound
from ost_ros.errors import OstError
from ost_ros.lockstep.messages import Acted, AgentReport, ProtocolViolation, Ready, RunEnd, RunInfo, Tick
from ost_ros.lockstep.world import WorldRuntime
from ost_ros.messages import Action
from ost_ros.model import Scenario
from ost_ros.result import RunResult
from ost_ros.scenario import ScenarioError, parse_scenario
from ost_ros.world import World

StepHook = Callable[[World, list[Action]], None]


class FollowError(OstError):
    """The messages do not make a run (no run info, out of step with the world); says why."""


@dataclass
class RunFollower:
    on_step: StepHook | None = None
    info: RunInfo | None = None
    scenario: Scenario | None = None
    rt: WorldRuntime | None = None
    lost: str | None = None  # why following stopped (the rebuilt run left the world's steps)
    ignored: int = 0  # messages of other runs, duplicates
    _ready: dict[int, Ready] = field(default_factory=dict)
    _acted: dict[int, dict[int, Acted]] = field(default_factory=dict)  # step -> agent -> action
    _marks: dict[int, Tick | RunEnd] = field(default_factory=dict)  # `last` -> the world's word on it
    _ticks: dict[int, dict[int, Tick]] = field(default_factory=dict)  # `last` -> agent -> tick
    _computed: dict[int, dict[int, Tick]] = field(default_factory=dict)  # recent steps, rebuilt
    _end: RunEnd | None = None
    _reports: list[AgentReport] = field(default_factory=list)

    def feed(self, msg: Any) -> None:
        """One message of the run (others — protocol samples, resends — are ignored)."""
        if isinstance(msg, RunInfo):
            self._info(msg)
        elif self.info is not None and getattr(msg, "run", self.info.run) not in ("", self.info.run):
            self.ignored += 1  # another run's (a stray)
            return
        elif isinstance(msg, Ready):
            self._ready[msg.agent] = msg
        elif isinstance(msg, Tick):
            self._marks.setdefault(msg.last, msg)
            done = self._computed.get(msg.last)
            if done is not None:  # a tick of a step already rebuilt: it must be the rebuilt one
                self._compare(msg.last, done, {msg.observation.agent: msg})
            else:
                self._ticks.setdefault(msg.last, {})[msg.observation.agent] = msg
        elif isinstance(msg, RunEnd):
            self._end = self._end or msg
        elif isinstance(msg, Acted):
            self._acted.setdefault(msg.action.t, {}).setdefault(msg.action.agent, msg)
        elif isinstance(msg, AgentReport):
            self._reports.append(msg)
        self._pump()

    def _info(self, info: RunInfo) -> None:
        if self.info is not None:
            if info.run != self.info.run:
                self.ignored += 1
            return
        try:
            self.scenario = parse_scenario(info.scenario, "run_info.scenario")
        except ScenarioError as exc:
            raise FollowError(f"run_info: {exc}") from None
        self.info = info

    def _start(self) -> bool:
        assert self.info is not None and self.scenario is not None
        ids = [a.id for a in self.scenario.agents]
        if self.rt is not None:
            return True
        if any(i not in self._ready for i in ids) or -1 not in self._marks:
            return False  # the world started once every agent was ready; its first tick says so
        self.rt = WorldRuntime(
            self.scenario,
            self.info.max_steps or None,
            self.info.event_skipping,
            run=self.info.run,
            protocol=min(r.protocol for r in self._ready.values()),
            organisation=min(r.organisation for r in self._ready.values()),
            on_step=self.on_step,
        )
        self.rt.start()
        return True

    def _pump(self) -> None:
        if self.info is None or self.lost is not None or not self._start():
            return
        rt = self.rt
        assert rt is not None
        while rt.ended is None and self.lost is None:
            s = rt.world.t
            mark = self._marks.get(s)
            if mark is None and self._end is not None and self._end.last <= s:
                mark = self._end  # the run ended here (or was ended by a failure it cannot take)
            if mark is None:
                return
            for notice in mark.failed:
                if notice.agent not in rt.failed and notice.t == s:
                    rt.fail(notice.agent)
            if rt.ended is not None:
                break
            acted = self._acted.get(s, {})
            if any(i not in acted for i in rt.live):
                return  # an action still on its way
            try:
                for i in rt.live:
                    rt.accept_acted(acted[i])
            except ProtocolViolation as exc:
                self.lost = f"step {s}: {exc}"
                return
            nxt = rt.advance()
            self._acted.pop(s, None)
            self._check(s, nxt, mark)
        self._collect()

    def _check(self, s: int, nxt: Any, mark: Tick | RunEnd) -> None:
        """After step s the rebuilt world must be where the world said it went."""
        if isinstance(mark, Tick):
            if not isinstance(nxt, list):
                self.lost = f"after step {s} the rebuilt run ended; the world went on to step {mark.t}"
                return
            computed = {k.observation.agent: k for k in nxt}
            self._compare(s, computed, self._ticks.pop(s, {}))
            self._computed[s] = computed
            for old in [k for k in self._computed if k < s - 16]:  # late ticks come soon or never
                del self._computed[old]
        elif not isinstance(nxt, RunEnd) or nxt.steps != mark.steps:
            self.lost = (
                f"after step {s} the rebuilt run does not end where the world's did (step {mark.steps})"
            )

    def _compare(self, s: int, computed: dict[int, Tick], heard: dict[int, Tick]) -> None:
        for agent, tick in heard.items():
            mine = computed.get(agent)
            if mine is None or mine.t != tick.t or mine.observation != tick.observation:
                self.lost = (
                    f"after step {s} the rebuilt world is not where the world's tick to agent "
                    f"{agent} for step {tick.t} says it is"
                )

    def _collect(self) -> None:
        rt = self.rt
        if rt is None or rt.ended is None:
            return
        for r in self._reports:
            try:
                rt.accept_report(r)
            except ProtocolViolation:
                self.ignored += 1
        self._reports.clear()

    def result(self) -> RunResult:
        """The rebuilt result, as the world node publishes it (lower bound included)."""
        if self.info is None:
            raise FollowError("no run_info: not a recording of a run (or recorded after its start)")
        if self.lost is not None:
            raise FollowError(f"the rebuilt run left the world's steps: {self.lost}")
        if self.rt is None:
            missing = sorted({a.id for a in self.scenario.agents} - set(self._ready)) if self.scenario else []
            raise FollowError(
                "the run never started" + (f" (no Ready from agents {missing[:8]})" if missing else "")
            )
        if self.rt.ended is None:
            raise FollowError(f"the run stops at step {self.rt.world.t} (no tick or action after it)")
        if self.rt.missing_reports:
            raise FollowError(f"no report from agents {list(self.rt.missing_reports)[:8]}")
        result = self.rt.result()
        assert self.scenario is not None
        result.lower_bound = lower_bound(self.scenario).value
        return result
