"""The agent of a shared-schedule protocol (CCP, NCP): three module FSAs (search, motion, comm)
sharing one global state (paper §4). The comm module (CCP's Algorithm Coordination, NCP's
negotiation) extends the global schedule; this agent executes its own part of it.

Per step, in the paper's order:

1. ``act(obs)``: the search module (sense, follow the sweep) then the motion module (decide,
   go to the object, wait for the group, carry, return to base) produce this step's action;
2. ``outbox()``: the messages produced this step (object found, search done, the comm module's);
3. ``communicate(t, messages)``: the comm module takes in every agent's messages of the step and
   coordinates when a coordination point is reached; the schedule applies from step t+1.

Global FSA: SEARCHING → DECISION → HELPING → WAITING → MOVING → DECISION … → RETURNING → FINISH.
After a team mate fails (the world's AgentLost, CCP): tasks not under way are dropped (HELPING,
WAITING, MOVING with the dead robot, RETURNING, FINISH → DECISION), the agent says where it
stands (Status), and DECISION may hand it a dead robot's unsearched cells (→ SEARCHING).

Planned = executed: what the agent does while nobody speaks follows from the schedule alone, so
:meth:`ScheduleAgent.plan` computes it segment by segment (no look-ahead by simulation).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence
from enum import Enum
from typing import Protocol

from ost_ros.coordination import Assignment
from ost_ros.messages import (
    FINISH_STATE,
    SEARCHING_STATE,
    Action,
    ActionKind,
    AgentMessage,
    ObjectFound,
    ObjectInfo,
    Observation,
    SearchDone,
    Status,
)
from ost_ros.model import Cell, arrival, can_move, group_period, manhattan, moves_between
from ost_ros.motion import step_toward
from ost_ros.protocols.base import AgentSummary
from ost_ros.protocols.plans import NO_PLAN, Plan, Segment
from ost_ros.protocols.shared.knowledge import Knowledge
from ost_ros.protocols.shared.recovery import Sweep
from ost_ros.search import SearchModule, SearchState
from ost_ros.team import TeamInfo


class GlobalState(str, Enum):
    SEARCHING = SEARCHING_STATE  # sweeping its subarea (search module)
    DECISION = "DECISION"  # picking the next scheduled object, or waiting for one
    HELPING = "HELPING"  # going to the object
    WAITING = "WAITING"  # at the object, waiting for the whole group
    MOVING = "MOVING"  # carrying the object with the group
    RETURNING = "RETURNING"  # nothing left anywhere: going back to base
    FINISH = FINISH_STATE  # at base, done


STATES = tuple(s.value for s in GlobalState)


class ScheduleComm(Protocol):
    """What the agent needs of its comm module (CCP's or NCP's)."""

    knowledge: Knowledge
    recovering: int | None  # the step a failure was learnt in (Status due the next step)
    reset: bool  # a failure cancelled the tasks not under way
    replanned: bool  # tasks not taken up yet were planned anew (CCP's improved planner)

    def receive(self, t: int, messages: Sequence[AgentMessage]) -> None: ...
    def drain(self) -> list[AgentMessage]: ...
    def pending(self) -> bool: ...
    def next_event(self, t: int) -> int | None: ...
    def status(self, t: int, at: Cell, current: Assignment | None) -> Status: ...
    @property
    def closed(self) -> bool: ...
    @property
    def trigger(self) -> str: ...


class ScheduleAgent:
    """One robot executing its part of a global schedule that its comm module keeps."""

    def __init__(self, agent_id: int, team: TeamInfo, comm: ScheduleComm, protocol: str):
        self.id = agent_id
        self.protocol = protocol
        self.team = team
        k = team.index(agent_id)
        self.base: Cell = team.bases[k]
        self.period: int = team.periods[k] if team.periods else 1  # moves every `period` steps
        self.position: Cell = self.base
        self.t = 0
        self.state = GlobalState.SEARCHING
        self.search = SearchModule(team.search_path(k))
        self.comm = comm
        self.knowledge = comm.knowledge
        self.tasks: deque[Assignment | Sweep] = deque()  # own schedule, in scheduling order
        self.current: Assignment | None = None
        self._seen_schedule = 0  # how much of the global schedule was read
        self._taken = 0  # own entries of the global schedule taken up so far
        self._outbox: list[AgentMessage] = []

    # ------------------------------------------------------------------ step, part 1: act

    def act(self, obs: Observation) -> Action:
        """Search module, then motion module, for step ``obs.t``."""
        self.t, self.position = obs.t, obs.position
        self._search(obs)
        kind, direction, obj = self._motion(obs)
        if self.comm.recovering is not None and self.comm.recovering == obs.t - 1:
            # the step after a failure was learnt: every survivor says where it stands
            self._outbox.append(self.comm.status(obs.t, self.position, self.current))
        return Action(self.id, self.t, kind, direction, obj, self.state.value)

    def _search(self, obs: Observation) -> None:
        if self.state is not GlobalState.SEARCHING:
            return
        for o in obs.sensed:
            if self.knowledge.note_found(o, obs.t):
                self._outbox.append(ObjectFound(self.id, obs.t, o))
        if self.search.at_end(self.position):
            self.search.state = SearchState.DONE
            self.state = GlobalState.DECISION
            self._outbox.append(SearchDone(self.id, obs.t))

    def _motion(self, obs: Observation) -> tuple[ActionKind, Cell, int]:
        # Each state either acts or hands over to the next state within the same step, so an
        # agent never loses a step to a bookkeeping transition (planned = executed).
        for _ in range(len(GlobalState) + 1):
            s = self.state
            if s is GlobalState.SEARCHING:
                return self._walk(self.search.next_cell(self.position))
            if s is GlobalState.DECISION:
                if not self._decide(obs):
                    return ActionKind.WAIT, (0, 0), -1
            elif s is GlobalState.HELPING:
                assert self.current is not None
                target = self.knowledge.objects[self.current.object].location
                if self.position != target:
                    return self._walk(target)
                self.state = GlobalState.WAITING
            elif s is GlobalState.WAITING or s is GlobalState.MOVING:
                # Hold the object and pull toward its destination every step: the world moves it
                # once the whole group pulls, so no agent needs to know who else has arrived.
                assert self.current is not None
                obj = self.knowledge.objects[self.current.object]
                if self.position == obj.destination:  # delivered on arrival
                    self.current = None
                    self.state = GlobalState.DECISION
                    continue
                if self.position != obj.location:  # it has moved: the group is carrying
                    self.state = GlobalState.MOVING
                return ActionKind.CARRY, step_toward(self.position, obj.destination), obj.id
            elif s is GlobalState.RETURNING:
                if self.position != self.base:
                    return self._walk(self.base)
                self.state = GlobalState.FINISH
            else:  # FINISH
                return ActionKind.WAIT, (0, 0), -1
        raise RuntimeError(f"agent {self.id}: motion FSA did not settle in state {self.state}")

    def _decide(self, obs: Observation) -> bool:
        """DECISION: take the next own task, or return once nothing more will come. False: wait."""
        self._read_schedule()
        if self.tasks and isinstance(self.tasks[0], Sweep):
            # a failed team mate's unsearched cells: sweep them (sensing from here on)
            sweep = self.tasks.popleft()
            self._taken += 1
            assert isinstance(sweep, Sweep)
            self.search = SearchModule(list(sweep.path))
            self.state = GlobalState.SEARCHING
            self._search(obs)
        elif self.tasks:
            task = self.tasks.popleft()
            self._taken += 1
            assert isinstance(task, Assignment)
            self.current = task
            self.state = GlobalState.HELPING
        elif self.comm.closed:
            self.state = GlobalState.RETURNING
        else:
            return False
        return True

    def _walk(self, target: Cell) -> tuple[ActionKind, Cell, int]:
        """One cell toward ``target`` — in a step this agent can move in; else it waits."""
        if not can_move(self.t, self.period):
            return ActionKind.WAIT, (0, 0), -1
        return ActionKind.MOVE, step_toward(self.position, target), -1

    def _read_schedule(self) -> None:
        self.tasks.extend(self._unread())
        self._seen_schedule = len(self.knowledge.schedule)

    def _unread(self) -> list[Assignment | Sweep]:
        """Own entries of the global schedule not yet taken into the task list."""
        return [a for a in self.knowledge.schedule[self._seen_schedule :] if self.id in a.agents]

    # ------------------------------------------------------------------ step, part 2: talk

    def outbox(self) -> list[AgentMessage]:
        """Messages of this step: found objects, search done, and the comm module's."""
        out = self.comm.drain() + self._outbox
        self._outbox = []
        return out

    def communicate(self, t: int, messages: Sequence[AgentMessage]) -> None:
        """Comm module for step ``t``: every agent's messages of the step (own included)."""
        self.comm.receive(t, messages)
        if self.comm.reset:
            self._drop_cancelled()
        if self.comm.replanned:
            self._resync()

    def _own(self) -> list[Assignment | Sweep]:
        return [a for a in self.knowledge.schedule if self.id in a.agents]

    def _resync(self) -> None:
        """Tasks not taken up yet were planned anew: what it has taken up stays first in its
        part of the schedule (the planner keeps it), the rest is its new task list."""
        self.comm.replanned = False
        self.tasks = deque(self._own()[self._taken :])
        self._seen_schedule = len(self.knowledge.schedule)

    def _drop_cancelled(self) -> None:
        """A team mate failed: keep only what is under way (a carry without it, a sweep)."""
        self.comm.reset = False
        self.tasks.clear()
        self._seen_schedule = len(self.knowledge.schedule)  # kept entries are done or under way
        self._taken = len(self._own())
        if self.current is not None and self.current not in self.knowledge.schedule:
            self.current = None
        if self.current is None and self.state not in (GlobalState.SEARCHING, GlobalState.DECISION):
            self.state = GlobalState.DECISION

    # ------------------------------------------------------------------ quiet steps

    def plan(self, t: int, position: Cell) -> Plan:
        """The steps it takes from ``t`` without a word: its schedule decides them, up to the step
        in which its comm module acts on its own (a trigger, the end of a negotiation round)."""
        if self._outbox or self.comm.pending() or self.comm.recovering is not None:
            return NO_PLAN
        last = self.comm.next_event(t)
        return _Planner(self, t, position, None if last is None else last + 1).run()

    def next_event(self, t: int) -> int | None:
        return self.comm.next_event(t)

    def skip(self, t: int, position: Cell, segment: Segment, steps: int) -> None:
        self.t, self.position = t, position
        if segment.kind == "sweep":  # it stands on the path's cell it has moved to
            self.search.index = min(
                segment.index + moves_between(t - steps, t, segment.period), len(segment.path) - 1
            )

    def news(self, obj: ObjectInfo) -> bool:
        return obj.id not in self.knowledge.objects

    def group(self) -> int | None:
        if self.current is None or self.state not in _GROUP:
            return None
        return self.current.object

    def departures(self) -> Mapping[int, int]:
        return {a.object: a.start for a in self.knowledge.assignments}

    # ------------------------------------------------------------------ introspection

    def summary(self) -> AgentSummary:
        k = self.knowledge
        return AgentSummary(
            self.comm.trigger,
            k.predicted_makespan,
            k.coordinations,
            tuple(k.assignments),
            dict(k.found_at),
            tuple(k.warnings),
            repr(k.schedule),
        )

    @property
    def done(self) -> bool:
        return self.state is GlobalState.FINISH

    @property
    def warnings(self) -> list[str]:
        return self.knowledge.warnings


_GROUP = frozenset((GlobalState.HELPING, GlobalState.WAITING, GlobalState.MOVING))
PLAN_HORIZON = 1024  # steps a quiet plan covers at least (when the schedule goes that far)


class _Planner:
    """The motion FSA run forward on the schedule, a segment at a time (planned = executed)."""

    def __init__(self, agent: ScheduleAgent, t: int, position: Cell, end: int | None):
        self.a = agent
        self.s, self.pos, self.end = t, position, end
        self.state = agent.state
        self.tasks: list[Assignment | Sweep] = list(agent.tasks) + agent._unread()
        self.current = agent.current
        self.path: Sequence[Cell] = agent.search.path
        self.index = agent.search.index
        self.out: list[Segment] = []
        self.handed_over = False  # a state or task changed before the first segment began

    def add(self, kind: str, steps: int | None, **kw) -> bool:
        """Append a segment from step ``s`` (cut at the plan's end); False once the plan is over."""
        cut = False
        if self.end is not None and (steps is None or self.s + steps >= self.end):
            steps, cut = self.end - self.s, True
        if steps is not None and steps <= 0:
            return not cut
        if not self.out and (
            self.state is not self.a.state
            or self.current is not self.a.current
            or len(self.tasks) != len(self.a.tasks) + len(self.a._unread())
        ):
            self.handed_over = True
        self.out.append(Segment(kind, self.state.value, steps, **kw))
        if steps is None:
            return False
        self.s += steps
        return not cut

    def run(self) -> Plan:
        go = True
        start = self.s
        # Past PLAN_HORIZON steps nobody reads the plan (the event engine takes its first
        # segment, the DDS runtime at most its lookahead): stop there at a segment's end.
        while go and (self.end is None or self.s < self.end) and self.s - start < PLAN_HORIZON:
            go = self.step()
        return Plan(tuple(self.out), settled=bool(self.out) and not self.handed_over)

    def step(self) -> bool:
        a, G = self.a, GlobalState
        if self.state is G.SEARCHING:
            return self.sweep()
        if self.state is G.DECISION:
            if self.tasks and isinstance(self.tasks[0], Sweep):
                sweep = self.tasks.pop(0)
                assert isinstance(sweep, Sweep)
                self.path, self.index = sweep.path, 0
                self.state = G.SEARCHING
            elif self.tasks:
                task = self.tasks.pop(0)
                assert isinstance(task, Assignment)
                self.current, self.state = task, G.HELPING
            elif a.comm.closed:
                self.state = G.RETURNING
            else:
                return self.add("wait", None)
            return True
        if self.state is G.HELPING:
            assert self.current is not None
            target = a.knowledge.objects[self.current.object].location
            if self.pos != target:
                if not self.add(
                    "walk",
                    arrival(self.s, manhattan(self.pos, target), a.period) - self.s,
                    period=a.period,
                    target=target,
                ):
                    return False
                self.pos = target
            self.state = G.WAITING
            return True
        if self.state in (G.WAITING, G.MOVING):
            return self.carry()
        if self.state is G.RETURNING:
            if self.pos != a.base:
                if not self.add(
                    "walk",
                    arrival(self.s, manhattan(self.pos, a.base), a.period) - self.s,
                    period=a.period,
                    target=a.base,
                ):
                    return False
                self.pos = a.base
            self.state = G.FINISH
            return True
        return self.add("wait", None)  # FINISH

    def sweep(self) -> bool:
        """Follow the path to its last cell; standing there it says SearchDone: the plan ends."""
        path, i = self.path, self.index
        if i >= len(path) or path[i] != self.pos:  # it has already moved on from path[i - 1]
            i -= 1
        if not 0 <= i < len(path) or path[i] != self.pos:
            return False  # off its path (never in a consistent run): no plan is always safe
        last = len(path) - 1
        if i < last:
            self.add(
                "sweep",
                arrival(self.s, last - i, self.a.period) - self.s,
                period=self.a.period,
                path=path,
                index=i,
            )
        return False

    def carry(self) -> bool:
        """Hold the object until its group is complete (the assignment's start), carry it to its
        destination with the group, then decide again."""
        a, G = self.a, GlobalState
        assert self.current is not None
        obj = a.knowledge.objects[self.current.object]
        if self.pos == obj.destination:
            self.current, self.state = None, G.DECISION
            return True
        if self.pos != obj.location:
            self.state = G.MOVING
        k = (
            group_period([a.team.periods[a.team.index(j)] for j in self.current.agents])
            if a.team.periods
            else 1
        )
        kw = dict(period=k, target=obj.destination, object=obj.id)
        if self.s < self.current.start and not self.add("hold", self.current.start - self.s, **kw):
            return False
        finish = arrival(self.s, manhattan(self.pos, obj.destination), k)
        if self.state is G.WAITING:
            # labelled WAITING until the group has moved it once (its first movable step)
            first = -(-self.s // k) * k
            if not self.add("carry", first + 1 - self.s, **kw):
                return False
            self.state = G.MOVING
        if not self.add("carry", finish - self.s, **kw):
            return False
        self.pos = obj.destination
        return True
