"""Ground truth of a run: where agents and objects are, what each agent senses, which actions
are legal. The in-process simulator and the ROS world node both drive this class.

Actions of one step are applied simultaneously. Rules: one 4-connected cell per step on the grid,
and an agent of period k only in steps t with t mod k = 0; an object moves only when at least
``required`` agents standing on its cell carry it in the same direction in the same step, in a
step every one of them may move in (fewer carriers, or a step the slowest cannot move in: they
hold it); it is delivered the moment it reaches its destination. Illegal actions (off the grid, not a unit move,
carrying from another cell, carriers pulling different ways, ...) are rejected with a reason (the
agent stays where it is) and counted in the result.

A failed agent (``fail``) acts no more: it stays where it stopped, and an object it was carrying
stays where its group held it. The run is then done when every object that the survivors can
still carry (``required`` ≤ survivors) is delivered and every survivor is home.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field, replace
from typing import Any

from ost_ros.messages import FINISH_STATE, SEARCHING_STATE, Action, ActionKind, ObjectInfo, Observation
from ost_ros.model import Cell, Scenario, can_move, group_period
from ost_ros.motion import DIRECTIONS, apply
from ost_ros.result import AgentRecord, ObjectRecord, RunResult, world_result
from ost_ros.sensing import BLOCK


@dataclass
class _Obj:
    spec: ObjectInfo
    at: Cell
    start: int | None = None
    carriers: tuple[int, ...] = ()
    delivered: int | None = None


@dataclass
class World:
    scenario: Scenario
    t: int = 0
    rejections: list[str] = field(default_factory=list)
    failed: dict[int, int] = field(default_factory=dict)  # agent -> step it failed in

    def __post_init__(self) -> None:
        self.positions: dict[int, Cell] = {a.id: a.base for a in self.scenario.agents}
        self.periods: dict[int, int] = {a.id: a.period for a in self.scenario.agents}
        self.bases: dict[int, Cell] = dict(self.positions)
        self.objects: dict[int, _Obj] = {o.id: _Obj(o, o.location) for o in self.scenario.objects}
        self._at: dict[Cell, set[int]] = defaultdict(set)  # undelivered objects by cell
        for o in self.objects.values():
            self._at[o.at].add(o.spec.id)
        self.records: dict[int, AgentRecord] = {a.id: AgentRecord(a.id) for a in self.scenario.agents}
        self.carrying: dict[int, int] = {}  # agent -> object its last action carried (or held)

    # ------------------------------------------------------------------ sensing

    def observe(self, agent_id: int) -> Observation:
        sensed = tuple(self.objects[i].spec for i in self.sensed_ids(agent_id))
        return Observation(agent_id, self.t, self.positions[agent_id], sensed)

    def sensed_ids(self, agent_id: int) -> tuple[int, ...]:
        """Ids of the objects in the agent's 3×3 block, in the order ``observe`` lists them."""
        pos = self.positions[agent_id]
        out: list[int] = []
        for dx, dy in BLOCK:
            ids = self._at.get((pos[0] + dx, pos[1] + dy))
            if ids:
                out.extend(sorted(ids))
        return tuple(out)

    # ------------------------------------------------------------------ acting

    def _reject(self, action: Action, why: str) -> None:
        self.rejections.append(f"t={self.t} agent {action.agent}: {action.kind.value} rejected: {why}")

    def apply(self, actions: list[Action]) -> None:
        """Apply one step's actions (one per agent) and advance the clock."""
        moves: dict[int, Cell] = {}
        carries: dict[int, list[Action]] = defaultdict(list)
        acted: set[int] = set()
        for act in actions:
            if not self._admit(act, acted):
                continue
            self._finish(act)
            if act.kind is ActionKind.WAIT:
                if self.records[act.agent].finished is None:
                    self.records[act.agent].idle += 1
                continue
            target = self._target(act)
            if target is None:
                continue
            if act.kind is ActionKind.MOVE:
                self._move(act, target, moves)
            else:
                carries[act.object].append(act)
        for oid, group in carries.items():
            self._carry(oid, group, moves)
        for agent, target in moves.items():
            self.positions[agent] = target
        self.t += 1

    def _admit(self, act: Action, acted: set[int]) -> bool:
        """Whether the action is from a live team member, its first of this step, for this step
        (what its agent carries is noted even when it is not)."""
        if act.agent not in self.records:
            self.rejections.append(f"t={self.t}: action from unknown agent {act.agent}")
            return False
        if act.agent in acted:
            self._reject(act, "second action in one step")
            return False
        acted.add(act.agent)
        if act.kind is ActionKind.CARRY:
            self.carrying[act.agent] = act.object
        else:
            self.carrying.pop(act.agent, None)
        if act.t != self.t:
            self._reject(act, f"stamped for step {act.t}, world is at step {self.t}")
            return False
        if act.agent in self.failed:
            self._reject(act, f"agent {act.agent} failed in step {self.failed[act.agent]}")
            return False
        return True

    def _finish(self, act: Action) -> None:
        """An agent reporting FINISH at its base is done; any other state calls it back to work."""
        rec = self.records[act.agent]
        if act.state != FINISH_STATE and rec.finished is not None:
            rec.finished = None  # called back to work (a team mate failed)
        if act.state == FINISH_STATE and rec.finished is None:
            pos = self.positions[act.agent]
            if pos == self.bases[act.agent]:
                rec.finished = self.t
            else:
                self._reject(act, f"FINISH at {pos}, away from base {self.bases[act.agent]}")

    def _target(self, act: Action) -> Cell | None:
        """The cell a move or carry leads to, or None (rejected) if it is not one cell on the grid."""
        if tuple(act.direction) not in DIRECTIONS:
            self._reject(act, f"direction {act.direction} is not one 4-connected cell")
            return None
        target = apply(self.positions[act.agent], act.direction)
        if not self.scenario.grid.contains(target):
            self._reject(act, f"{target} is off the grid")
            return None
        return target

    def _move(self, act: Action, target: Cell, moves: dict[int, Cell]) -> None:
        if not can_move(self.t, self.periods[act.agent]):
            self._reject(act, f"moves every {self.periods[act.agent]} steps, not in step {self.t}")
            return
        moves[act.agent] = target
        if act.state == SEARCHING_STATE:
            self.records[act.agent].search += 1
        else:
            self.records[act.agent].travel += 1

    def _carry(self, oid: int, group: list[Action], moves: dict[int, Cell]) -> None:
        obj = self.objects.get(oid)
        if obj is None or obj.delivered is not None:
            for act in group:
                self._reject(act, f"object {oid} does not exist or is delivered")
            return
        here = [a for a in group if self.positions[a.agent] == obj.at]
        for act in group:
            if self.positions[act.agent] != obj.at:
                self._reject(act, f"not at object {oid} ({obj.at})")
        directions = {tuple(a.direction) for a in here}
        if len(directions) > 1:
            for act in here:
                self._reject(act, f"carriers of object {oid} pull in {len(directions)} directions")
            return
        if len(here) < obj.spec.required or not can_move(
            self.t, group_period([self.periods[a.agent] for a in here])
        ):
            # Not an error: the agents hold the object and wait for the rest of the group (or
            # for a step in which the slowest of them can move).
            for act in here:
                self.records[act.agent].idle += 1
            return
        target = apply(obj.at, here[0].direction)
        carriers = tuple(sorted(a.agent for a in here))
        if obj.start is None:
            obj.start = self.t
        if obj.carriers != carriers:  # first lift, or picked up again after a carrier failed
            obj.carriers = carriers
        self._at[obj.at].discard(oid)
        obj.at = target
        for act in here:
            moves[act.agent] = target
            self.records[act.agent].carry += 1
        if target == obj.spec.destination:
            obj.delivered = self.t + 1
        else:
            self._at[target].add(oid)

    # ------------------------------------------------------------------ many steps at once
    # For the event engine: what ``apply`` would record over ``steps`` steps of one kind of
    # action, without stepping (the engine has checked that nothing else happens meanwhile).

    def bulk_walk(self, agent: int, to: Cell, steps: int, moves: int, state: str) -> None:
        """``steps`` steps of walking (sweeping if ``state`` is SEARCHING): ``moves`` moves end at
        ``to``; in the other steps the agent waits (it may not move in them)."""
        rec = self.records[agent]
        self.carrying.pop(agent, None)
        rec.finished = None
        self.positions[agent] = to
        if state == SEARCHING_STATE:
            rec.search += moves
        else:
            rec.travel += moves
        rec.idle += steps - moves

    def bulk_wait(self, agent: int, steps: int, state: str, holding: int | None = None) -> None:
        """``steps`` steps standing still: waiting, or holding object ``holding`` (its group is
        not complete yet, which counts as idle even for a robot that has finished)."""
        rec = self.records[agent]
        if holding is not None:
            self.carrying[agent] = holding
        else:
            self.carrying.pop(agent, None)
        if state != FINISH_STATE:
            rec.finished = None
        elif rec.finished is None and self.positions[agent] == self.bases[agent]:
            rec.finished = self.t
        if holding is not None or rec.finished is None:
            rec.idle += steps

    def bulk_carry(self, oid: int, carriers: list[int], to: Cell, steps: int, moves: int, first: int) -> None:
        """``steps`` steps of a complete group carrying object ``oid``: ``moves`` moves, the first
        in step ``first``, end at ``to`` (delivered there if it is the destination); in the other
        steps the group holds it."""
        obj = self.objects[oid]
        if moves:
            if obj.start is None:
                obj.start = first
            group = tuple(sorted(carriers))
            if obj.carriers != group:
                obj.carriers = group
            self._at[obj.at].discard(oid)
            obj.at = to
            if to == obj.spec.destination:
                obj.delivered = self.t + steps
            else:
                self._at[to].add(oid)
        for agent in carriers:
            rec = self.records[agent]
            self.carrying[agent] = oid
            rec.finished = None
            self.positions[agent] = to
            rec.carry += moves
            rec.idle += steps - moves

    def pass_steps(self, steps: int) -> None:
        """The clock after steps executed in bulk."""
        self.t += steps

    # ------------------------------------------------------------------ failures

    def fail(self, agent_id: int) -> None:
        """Agent ``agent_id`` fails now (step ``t``): it does not act in this step or later."""
        if agent_id in self.records and agent_id not in self.failed:
            self.failed[agent_id] = self.t

    def dropped_by(self, agent_id: int) -> tuple[ObjectInfo, ...]:
        """What a failing agent reported holding: the object its last action carried, if it
        stands on it — with the cell where it now lies (the robot's own last position)."""
        oid = self.carrying.get(agent_id)
        o = self.objects.get(oid) if oid is not None else None
        if o is None or o.delivered is not None or o.at != self.positions[agent_id]:
            return ()
        return (replace(o.spec, location=o.at),)

    @property
    def survivors(self) -> int:
        return len(self.records) - len(self.failed)

    def undeliverable(self) -> list[int]:
        """Undelivered objects needing more robots than survive."""
        return sorted(
            i for i, o in self.objects.items() if o.delivered is None and o.spec.required > self.survivors
        )

    # ------------------------------------------------------------------ ending

    @property
    def done(self) -> bool:
        n = self.survivors
        return all(o.delivered is not None or o.spec.required > n for o in self.objects.values()) and all(
            r.finished is not None for i, r in self.records.items() if i not in self.failed
        )

    def result(self, **extra: Any) -> RunResult:
        objects = [
            ObjectRecord(o.spec.id, o.carriers, o.start, o.delivered)
            for o in sorted(self.objects.values(), key=lambda o: o.spec.id)
        ]
        return world_result(
            [self.records[a.id] for a in self.scenario.agents],
            objects,
            done=self.done,
            left=self.undeliverable(),
            required={i: o.spec.required for i, o in self.objects.items()},
            failed=self.failed,
            steps=self.t,
            rejections=self.rejections,
            **extra,
        )
