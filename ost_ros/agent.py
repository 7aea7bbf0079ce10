"""A CCP agent: three module FSAs (search, motion, comm) sharing one global state (paper §4).

The agent touches the world only through :class:`Observation` in and :class:`Action` out, and
other agents only through messages, so the same object runs in the in-process simulator and
inside a ROS 2 node. Per step, in the paper's order:

1. ``act(obs)``: the search module (sense, follow the sweep) then the motion module (decide,
   go to the object, wait for the group, carry, return to base) produce this step's action;
2. ``outbox()``: the messages produced this step (object found, search done, selections);
3. ``communicate(t, messages)``: the comm module takes in every agent's messages of the step and
   coordinates when a coordination point is reached; the schedule applies from step t+1.

Global FSA: SEARCHING → DECISION → HELPING → WAITING → MOVING → DECISION … → RETURNING → FINISH.
After a team mate fails (the world's AgentLost): tasks not under way are dropped (HELPING,
WAITING, MOVING with the dead robot, RETURNING, FINISH → DECISION), the agent says where it
stands (Status), and DECISION may hand it a dead robot's unsearched cells (→ SEARCHING).
"""
from __future__ import annotations

from collections import deque
from enum import Enum

from ost_msgs_py.messages import Action, ActionKind, Observation, ObjectFound, SearchDone
from ost_ros.comm import CcpComm
from ost_ros.coordination import Assignment, CoordinationPolicy
from ost_ros.model import Cell, can_move
from ost_ros.motion import step_toward
from ost_ros.recovery import Sweep
from ost_ros.search import SearchModule, SearchState
from ost_ros.team import TeamInfo


class GlobalState(str, Enum):
    SEARCHING = "SEARCHING"   # sweeping its subarea (search module)
    DECISION = "DECISION"     # picking the next scheduled object, or waiting for one
    HELPING = "HELPING"       # going to the object
    WAITING = "WAITING"       # at the object, waiting for the whole group
    MOVING = "MOVING"         # carrying the object with the group
    RETURNING = "RETURNING"   # nothing left anywhere: going back to base
    FINISH = "FINISH"         # at base, done


class CcpAgent:
    """One robot running the cost-balanced cooperation protocol."""

    protocol = "ccp"

    def __init__(self, agent_id: int, team: TeamInfo, policy: CoordinationPolicy | None = None):
        self.id = agent_id
        self.team = team
        k = team.index(agent_id)
        self.base: Cell = team.bases[k]
        self.period: int = team.periods[k] if team.periods else 1   # moves every `period` steps
        self.position: Cell = self.base
        self.t = 0
        self.state = GlobalState.SEARCHING
        self.search = SearchModule(team.search_path(k))
        self.comm = CcpComm(agent_id, team, policy or CoordinationPolicy())
        self.tasks: deque[Assignment | Sweep] = deque()   # own schedule, in scheduling order
        self.current: Assignment | None = None
        self._seen_schedule = 0                   # how much of the global schedule was read
        self._outbox: list = []

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
            if self.comm.note_found(o, obs.t):
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
                nxt = self.search.next_cell(self.position)
                return self._walk(nxt)
            if s is GlobalState.DECISION:
                self._read_schedule()
                if self.tasks and isinstance(self.tasks[0], Sweep):
                    # a failed team mate's unsearched cells: sweep them (sensing from here on)
                    self.search = SearchModule(list(self.tasks.popleft().path))
                    self.state = GlobalState.SEARCHING
                    self._search(obs)
                elif self.tasks:
                    self.current = self.tasks.popleft()
                    self.state = GlobalState.HELPING
                elif self.comm.closed:
                    self.state = GlobalState.RETURNING
                else:
                    return ActionKind.WAIT, (0, 0), -1
            elif s is GlobalState.HELPING:
                target = self.comm.objects[self.current.object].location
                if self.position == target:
                    self.state = GlobalState.WAITING
                else:
                    return self._walk(target)
            elif s is GlobalState.WAITING or s is GlobalState.MOVING:
                # Hold the object and pull toward its destination every step: the world moves it
                # once the whole group pulls, so no agent needs to know who else has arrived.
                obj = self.comm.objects[self.current.object]
                if self.position == obj.destination:  # delivered on arrival
                    self.current = None
                    self.state = GlobalState.DECISION
                    continue
                if self.position != obj.location:     # it has moved: the group is carrying
                    self.state = GlobalState.MOVING
                return ActionKind.CARRY, step_toward(self.position, obj.destination), obj.id
            elif s is GlobalState.RETURNING:
                if self.position == self.base:
                    self.state = GlobalState.FINISH
                else:
                    return self._walk(self.base)
            else:  # FINISH
                return ActionKind.WAIT, (0, 0), -1
        raise RuntimeError(f"agent {self.id}: motion FSA did not settle in state {self.state}")

    def _walk(self, target: Cell) -> tuple[ActionKind, Cell, int]:
        """One cell toward ``target`` — in a step this agent can move in; else it waits."""
        if not can_move(self.t, self.period):
            return ActionKind.WAIT, (0, 0), -1
        return ActionKind.MOVE, step_toward(self.position, target), -1

    def _read_schedule(self) -> None:
        schedule = self.comm.schedule
        for a in schedule[self._seen_schedule:]:
            if self.id in a.agents:
                self.tasks.append(a)
        self._seen_schedule = len(schedule)

    # ------------------------------------------------------------------ step, part 2: talk

    def outbox(self) -> list:
        """Messages of this step: found objects, search done, and last step's selections."""
        out = self.comm.drain() + self._outbox
        self._outbox = []
        return out

    def communicate(self, t: int, messages: list) -> None:
        """Comm module for step ``t``: every agent's messages of the step (own included)."""
        self.comm.receive(t, messages)
        if self.comm.reset:
            self._drop_cancelled()

    def _drop_cancelled(self) -> None:
        """A team mate failed: keep only what is under way (a carry without it, a sweep)."""
        self.comm.reset = False
        self.tasks.clear()
        self._seen_schedule = len(self.comm.schedule)   # kept entries are done or under way
        if self.current is not None and self.current not in self.comm.schedule:
            self.current = None
        if self.current is None and self.state not in (GlobalState.SEARCHING, GlobalState.DECISION):
            self.state = GlobalState.DECISION

    # ------------------------------------------------------------------ introspection

    def reads_sensor(self) -> bool:
        """Whether the next ``act`` looks at the sensor: while searching, or when a sweep taken
        over from a failed team mate may start in it (event skipping predicts only those)."""
        if self.state is GlobalState.SEARCHING:
            return True
        return self.state is GlobalState.DECISION and (
            any(isinstance(x, Sweep) for x in self.tasks)
            or any(isinstance(a, Sweep) and a.agent == self.id
                   for a in self.comm.schedule[self._seen_schedule:]))

    @property
    def done(self) -> bool:
        return self.state is GlobalState.FINISH

    @property
    def warnings(self) -> list[str]:
        return self.comm.warnings
