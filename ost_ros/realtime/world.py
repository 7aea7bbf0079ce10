"""The robots' bases in continuous time, computed by events — the world of a run without a
barrier (ROS-free; the world node serves it as one action per robot).

Each robot executes one *goal* at a time; a new goal preempts the current one at the robot's next
cell boundary (a move under way is completed first):

- :class:`Follow` — a path of cells, each adjacent to the previous, starting at the robot's cell
  (or next to it); the robot makes one move per movable step of its period (the first at a step
  t with t % period == 0, then one every period·f steps, each move lasting f, f the goal's speed
  factor: 1, or a seeded draw in [1, 1 + speed_jitter]). Result REACHED at the last cell;
- :class:`Stand` — stand still (labelled: waiting, or finished at the base); no result;
- :class:`Carry` — hold object k for the declared group: refused unless the robot stands at the
  object and it lies there undelivered; the carry starts when the LAST member of the group has
  asked with the same group (never with another), at the group's first movable step (the lcm of
  the members' periods), and moves x first then y at that period (factor: the members' largest)
  to the destination; delivered on arrival, every member's result REACHED then.

Goals are refused with a code and a reason (:data:`REFUSALS`). The world's events, due in time
order (:meth:`RealtimeWorld.advance`): goal results, detections — an object lying at rest comes
into a robot's 3×3 sensor, computed per goal from its path (:func:`ost_ros.sensing.first_sensing`),
not cell by cell —, carries started. Stalls (a robot stands still for S steps from step s) delay
every move not yet begun; a killed robot stops, and a group it carried drops the object where the
current move ends (its other members: ABORTED).

Time is a float in steps; with no speed jitter every event falls on an integer step and the
record — makespan, per-agent cost/idle/carry/search/travel, objects' start and delivery — is the
lockstep world's (:class:`ost_ros.world.World`; tested: at latency 0 the run equals ``ost sim``).
"""

from __future__ import annotations

import heapq
import math
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from ost_ros.model import Cell, Scenario, group_period, manhattan
from ost_ros.realtime.messages import FINISH_STATE, SEARCHING_STATE, Lost, ObjectInfo
from ost_ros.result import AgentRecord, ObjectRecord, RunResult, world_result
from ost_ros.search import route
from ost_ros.sensing import BLOCK, first_sensing

EPS = 1e-9
E = TypeVar("E")  # an event kind (:meth:`RealtimeWorld._noted`)

REACHED, PREEMPTED, REFUSED, ABORTED = "reached", "preempted", "refused", "aborted"
REFUSALS = {
    "START": "the path does not start at or next to the robot's cell",
    "PATH": "the path leaves the grid or is not 4-connected",
    "NOT_AT_OBJECT": "the robot does not stand at the object",
    "DELIVERED": "the object is delivered",
    "IN_TRANSIT": "another group carries the object",
    "BAD_GROUP": "the group does not hold the robot or is not n_i robots",
    "MEMBER_FAILED": "a member of the group has failed",
    "CARRYING": "its group carries the object already (a let-go came after the lift)",
    "NOT_AT_BASE": "finished away from its base",
    "FAILED": "the robot has failed",
    "UNKNOWN": "no such object or robot",
}


# ----------------------------------------------------------------------------- goals and events


@dataclass(frozen=True)
class Follow:
    path: tuple[Cell, ...]
    state: str


@dataclass(frozen=True)
class Stand:
    state: str
    # (a robot letting go of a hold: refused if its group has lifted already — the robot's status
    # then says it carries; over DDS the let-go and the lift cross)
    unless_carrying: bool = False


@dataclass(frozen=True)
class Carry:
    object: int
    group: tuple[int, ...]
    state: str


Goal = Follow | Stand | Carry


@dataclass(frozen=True)
class GoalResult:
    """How a goal ended: REACHED (at ``cell``, ``time``), PREEMPTED, REFUSED or ABORTED (``code``,
    ``reason``)."""

    agent: int
    goal: int
    outcome: str
    time: float
    cell: Cell
    code: str = ""
    reason: str = ""


@dataclass(frozen=True)
class Detection:
    """Objects at rest coming into ``agent``'s sensor at ``cell`` at ``time``; ``sensed``: every
    object at rest in its 3×3 there (the lockstep observation's order)."""

    agent: int
    time: float
    cell: Cell
    objects: tuple[ObjectInfo, ...]
    sensed: tuple[ObjectInfo, ...]


@dataclass(frozen=True)
class CarryStarted:
    """The group has lifted ``object`` at ``time``; it moves x first then y to the destination,
    a move every (group period)·``factor`` steps, each lasting ``factor`` (the members' largest)."""

    object: int
    group: tuple[int, ...]
    time: float
    factor: float = 1.0


@dataclass(frozen=True)
class GoalStarted:
    """Goal ``goal`` has taken over ``agent``'s base (a tracking world says so: the robot's own
    picture of its base, :class:`~ost_ros.realtime.base.BaseMirror`, is kept from these): the
    robot stands at ``cell`` from ``time``; a FOLLOW's first move leaves at ``first`` (inf: it
    stands or holds), then one every period·``factor`` steps, each lasting ``factor``;
    ``offset`` 1: the goal's path starts next to ``cell`` (0: at it)."""

    agent: int
    goal: int
    time: float
    cell: Cell
    offset: int = 0
    first: float = math.inf
    factor: float = 1.0


@dataclass(frozen=True)
class Stalled:
    """``agent``'s base stands still for ``steps`` from ``time``: every move not begun by then
    leaves that much later (a tracking world says so; a carry's whole group is told)."""

    agent: int
    time: float
    steps: float


@dataclass(frozen=True)
class Feedback:
    """Where the robot is at its first cell boundary at or after the asked time (a move under way
    is completed): ``cell``, ``time``; its goal (id, and the index of ``cell`` in that goal's path
    as sent, -1 if it is not on it yet), the object whose carry it is in (-1) and what it
    senses there."""

    agent: int
    time: float
    cell: Cell
    goal: int
    index: int
    carrying: int
    sensed: tuple[ObjectInfo, ...]


Event = GoalResult | Detection | CarryStarted | GoalStarted | Stalled


def follow_departures(first: float, moves: int, period: int, factor: float) -> list[float]:
    """When each move of a FOLLOW leaves (the world's and the robot's mirror's one formula)."""
    step = period * factor
    return [first + i * step for i in range(moves)]


def carry_departures(lift: float, moves: int, period: int, factor: float) -> list[float]:
    """When each move of a carry leaves, lifted at ``lift`` by a group of this period."""
    return [lift + i * period * factor for i in range(moves)]


# ----------------------------------------------------------------------------- internals


@dataclass
class Route:
    """Moves along ``cells`` from ``cells[0]`` (reached at ``start``): move i leaves ``cells[i]``
    at ``depart[i]`` and takes ``factor``. ``made``: the moves it made when it was cut."""

    cells: list[Cell]
    start: float
    depart: list[float]
    factor: float
    made: int | None = None

    @property
    def moves(self) -> int:
        return len(self.cells) - 1 if self.made is None else self.made

    def arrive(self, i: int) -> float:
        return self.start if i == 0 else self.depart[i - 1] + self.factor

    def committed(self, t: float) -> int:
        """Moves begun strictly before ``t`` (a move leaving at exactly t is not begun)."""
        lo, hi = 0, self.moves
        while lo < hi:
            mid = (lo + hi) // 2
            if self.depart[mid] < t - EPS:
                lo = mid + 1
            else:
                hi = mid
        return lo

    def boundary(self, t: float) -> tuple[int, float]:
        """The index of the cell the robot stands on at its first boundary at or after t, and when."""
        m = self.committed(t)
        return m, max(self.arrive(m), t)

    def reached_by(self, t: float) -> int:
        """Index of the last cell reached at or before t."""
        m = self.committed(t + 2 * EPS)
        return m if m == 0 or self.arrive(m) <= t + EPS else m - 1

    def shift(self, t: float, by: float) -> None:
        """Every move not begun before ``t`` leaves ``by`` later."""
        for i in range(self.committed(t), len(self.depart)):
            self.depart[i] += by


@dataclass
class _Leg:
    """A part of a robot's life on a route: what it counts as (search, travel or carry)."""

    route: Route
    kind: str


@dataclass
class _Carry:
    object: int
    group: tuple[int, ...]
    route: Route
    period: int
    version: int = 0


@dataclass
class _Bot:
    id: int
    base: Cell
    period: int
    cell: Cell
    time: float = 0.0  # when it got to ``cell`` (the start of whatever it does there)
    route: Route | None = None  # its current motion (a Follow goal's, or its group's carry)
    goal: int = 0  # id of its current goal (0: none)
    kind: str = ""  # "follow", "stand", "hold", "carry"
    goal_path: tuple[Cell, ...] = ()
    offset: int = 0  # index in goal_path of route.cells[i] is i - offset
    label: str = SEARCHING_STATE
    holding: int = -1  # object it holds or carries
    group: tuple[int, ...] = ()
    factor: float = 1.0
    version: int = 0
    stall_until: float = 0.0
    alive: bool = True
    out: bool = False  # stopped because it was declared out (not dead: it may come back)
    life: int = 0  # its robot's life (incarnation) the base last took goals from
    died: float | None = None
    finished: float | None = None
    finished_total: float = 0.0
    legs: list[_Leg] = field(default_factory=list)
    delivered: list[int] = field(default_factory=list)
    # (time, object): its carry was broken by a partner's failure; it goes on carrying until its
    # move under way ends at ``time``, and says so only then (the ABORTED result)
    broken: tuple[float, int] | None = None


@dataclass
class _Obj:
    spec: ObjectInfo
    at: Cell
    start: float | None = None
    carriers: tuple[int, ...] = ()
    delivered: float | None = None
    moving: bool = False


def _num(x: float | None) -> Any:
    """A time or duration for the record: an integer when it is one, else 3 decimals."""
    if x is None:
        return None
    r = round(x)
    return int(r) if abs(x - r) < 1e-6 else round(x, 3)


def _first_movable(t: float, period: int) -> float:
    """The first step ≥ t in which a robot (or group) of this period may begin a move."""
    return math.ceil(t / period - EPS) * period


# ----------------------------------------------------------------------------- the world


OUT_STATE, FAILED_STATE = "OUT", "FAILED"  # a robot declared out (stopped), one dead (timeline)


@dataclass(frozen=True)
class Snapshot:
    """Where robots and objects are at a time (:meth:`RealtimeWorld.snapshot`)."""

    positions: tuple[Cell, ...]  # robot cells, in the scenario's agent order
    states: tuple[str, ...]  # what each robot's base does (its goal's state; FAILED: dead)
    holding: tuple[int, ...]  # the object a robot holds or carries, -1 for none
    objects: tuple[Cell, ...]  # object cells, in the scenario's object order
    delivered: tuple[bool, ...]


@dataclass
class RealtimeWorld:
    """Ground truth of a run without a barrier. Callers pass time in (``at``, ``now``); the world
    never advances on its own: :meth:`advance` returns what is due, :meth:`next_time` says when."""

    scenario: Scenario
    speed_jitter: float = 0.0
    seed: int = 0
    stalls: tuple[tuple[int, float, float], ...] = ()  # (agent, from step, steps)
    now: float = 0.0
    # Also say how each base moves (GoalStarted from goal(), Stalled from advance(), in order
    # with the rest): what a robot whose base is across a network keeps its picture from.
    tracking: bool = False
    refusals: list[str] = field(default_factory=list)
    # A robot declared out is stopped, not dead: the run waits for it to come back and finish
    # (in process, where a silence ends for sure); False over DDS, where nobody knows whether it
    # will (a robot back before the end is used; the end does not wait).
    wait_for_out: bool = True

    def __post_init__(self) -> None:
        if self.speed_jitter < 0:
            raise ValueError(f"speed jitter {self.speed_jitter} must be ≥ 0")
        self.bots: dict[int, _Bot] = {
            a.id: _Bot(a.id, a.base, a.period, a.base) for a in self.scenario.agents
        }
        self.objects: dict[int, _Obj] = {o.id: _Obj(o, o.location) for o in self.scenario.objects}
        self._rest: dict[Cell, set[int]] = defaultdict(set)  # objects lying still, by cell
        for o in self.objects.values():
            self._rest[o.at].add(o.spec.id)
        self._holds: dict[int, dict[int, tuple[int, ...]]] = defaultdict(dict)  # obj -> agent -> group
        self._carries: dict[int, _Carry] = {}
        self._depart: dict[int, tuple[float, int]] = {}  # obj -> (time, version) of a pending lift
        self._serial = 0  # versions of lifts and carries: never reused, so a stale event never fits
        self._last_event: dict[int, float] = {}  # agent -> the time of its base's last event
        self._heap: list[tuple[float, int, int, tuple]] = []
        self._count = 0
        self._rng = np.random.default_rng(self.seed)
        self.failed: dict[int, int] = {}  # agent -> step it failed in (the record's)
        self._loads: dict[int, tuple[int, Cell]] = {}  # a failed robot's load: object, where it lies
        self.outs: dict[int, int] = {}  # agent -> step it was declared out in (until it is back)
        # agent -> (time, state) each time what it does changes: a run's timeline (--plot)
        self.labels: dict[int, list[tuple[float, str]]] = {a.id: [] for a in self.scenario.agents}
        self.revived: list[tuple[int, float]] = []  # (agent, time) of every robot back
        self._done: bool | None = None  # cached ``done`` (None: to compute)
        self.end: float = 0.0
        for agent, at, steps in self.stalls:
            if agent not in self.bots:
                raise ValueError(f"stall of agent {agent}: no such agent")
            if at < 0 or steps <= 0:
                raise ValueError(f"stall of agent {agent}: from step {at} for {steps} steps")
            self._push(at, 0, ("stall", agent, steps))

    # ------------------------------------------------------------------ queries

    def next_time(self) -> float | None:
        """When the next event is due (None: nothing will happen unless a goal is sent)."""
        while self._heap and not self._valid(self._heap[0][3]):
            heapq.heappop(self._heap)
        return self._heap[0][0] if self._heap else None

    def feedback(self, agent: int, at: float) -> Feedback:
        b = self.bots[agent]
        cell, time, m = self._handover(b, at)
        index = -1
        if b.kind == "follow" and b.route is not None:
            index = m - b.offset
        carrying = b.holding if b.kind == "carry" else -1
        if b.broken is not None and at < b.broken[0] - EPS:
            # a partner failed mid-carry: the base still carries until the move under way ends
            # and its ABORTED result says otherwise (what the robot's own picture shows; telling
            # it sooner would be the simulator's knowledge, not its base's)
            carrying = b.broken[1]
        return Feedback(agent, time, cell, b.goal, index, carrying, self._sensed(cell))

    def position(self, agent: int, t: float) -> Cell:
        """The last cell the robot reached at or before ``t`` (a past time: its legs)."""
        b = self.bots[agent]
        for leg in reversed(b.legs):
            r = leg.route
            if r.start <= t + EPS:
                return r.cells[min(r.reached_by(t), r.moves)]
        return b.base

    def snapshot(self, t: float) -> Snapshot:
        """The world at ``t``, a time at or after the last event handled and before the next one
        (an observer's view — the animation's: it reads, never changes anything), robots and
        objects in the scenario's order."""
        bots = [self.bots[a.id] for a in self.scenario.agents]
        objects, delivered = [], []
        for spec in self.scenario.objects:
            o = self.objects[spec.id]
            cell = o.at
            run = self._carries.get(spec.id) if o.moving else None
            if run is not None:
                r = run.route
                cell = r.cells[min(r.reached_by(t), r.moves)]
            objects.append(cell)
            delivered.append(o.delivered is not None)
        return Snapshot(
            positions=tuple(self.position(b.id, t) for b in bots),
            states=tuple(b.label if b.alive or b.out else FAILED_STATE for b in bots),
            holding=tuple(b.holding if b.alive and b.kind in ("hold", "carry") else -1 for b in bots),
            objects=tuple(objects),
            delivered=tuple(delivered),
        )

    @property
    def survivors(self) -> int:
        """Robots not dead (one declared out is stopped, not dead: the run waits for it)."""
        return sum(b.alive or (b.out and self.wait_for_out) for b in self.bots.values())

    @property
    def done(self) -> bool:
        """Every object the survivors can carry is delivered and every survivor is finished at
        its base (computed again only after something changed)."""
        if self._done is None:
            n = self.survivors
            self._done = all(
                o.delivered is not None or o.spec.required > n for o in self.objects.values()
            ) and all(
                b.finished is not None for b in self.bots.values() if b.alive or (b.out and self.wait_for_out)
            )
        return self._done

    # ------------------------------------------------------------------ goals

    def goal(self, agent: int, gid: int, goal: Goal, at: float, life: int = 0) -> list[GoalResult]:
        """Goal ``gid`` (the client's id) for ``agent``'s base; it takes over at the robot's first
        boundary at or after ``at``. Returns the results it causes now: its refusal, or the
        preempted goal's PREEMPTED (team mates of a carry it leaves get ABORTED when the group
        stops). ``life``: the robot's incarnation — a base stopped when its robot was declared
        out takes goals again from a later life only (:meth:`revive`)."""
        b = self.bots.get(agent)
        if b is not None and b.out and life > b.life:
            self.revive(agent, at, life)
        if b is None or not b.alive:
            return self._noted([GoalResult(agent, gid, REFUSED, at, (0, 0), "FAILED", REFUSALS["FAILED"])])
        self._done = None
        self.now = max(self.now, at)
        cell, time, m = self._handover(b, at)
        why = self._refuse(b, goal, cell)
        if why is not None:
            code, reason = why
            if code not in ("MEMBER_FAILED",):
                self.refusals.append(
                    f"t={_num(at)} agent {agent}: {type(goal).__name__.lower()} refused: {reason}"
                )
            return self._noted([GoalResult(agent, gid, REFUSED, at, cell, code, reason)])
        out: list[Any] = self._leave(b, at, time, cell, m)
        b.broken = None
        self._finish_label(b, goal, time)
        b.goal, b.version = gid, b.version + 1
        b.label = goal.state
        self._labelled(agent, time, goal.state)
        if isinstance(goal, Follow):
            self._follow(b, goal, cell, time)
        elif isinstance(goal, Stand):
            b.kind, b.route = "stand", None
        else:
            self._hold(b, goal, time)
        if self.tracking:
            r = b.route
            first = r.depart[0] if b.kind == "follow" and r is not None and r.depart else math.inf
            out.append(
                GoalStarted(agent, gid, time, cell, b.offset if b.kind == "follow" else 0, first, b.factor)
            )
        return self._noted(out)

    def _noted(self, events: list[E]) -> list[E]:
        """``events``, each base's last event time kept (:meth:`takeover` never goes before it)."""
        last = self._last_event
        for ev in events:
            for a in ev.group if isinstance(ev, CarryStarted) else (ev.agent,):  # type: ignore[attr-defined]
                last[a] = max(last.get(a, -math.inf), ev.time)  # type: ignore[attr-defined]
        return events

    def takeover(self, agent: int, goal: Goal, at: float, now: float) -> float:
        """When a robot's goal for its base, decided for time ``at``, takes over if it reaches the
        base at ``now`` (an agent node's goal crosses a network). At ``at`` if that is less than
        a step ago, not before any event the base has had (its events stay in time order), and
        the goal moves (two cells at least) or stands a robot that neither holds nor carries: a
        move takes a step at least, so every event the goal causes — an arrival, a detection, its
        end — is still to come; the robot decided in step ⌈at⌉ and its base starts in that step,
        as a base on board would. Otherwise now: a hold's lift, a let-go or a carry broken concern
        the partners' bases too, and nothing of theirs is rewritten. (Taken at now, a decision a
        few milliseconds late cost a whole step: the first move begins at a step's start — 48
        steps of a 1 660-step run.)"""
        b = self.bots.get(agent)
        if b is None or not now - 1.0 + EPS < at < now or b.kind in ("hold", "carry"):
            return max(at, now)
        if isinstance(goal, Follow):
            moves = len(goal.path) > 1
        else:
            moves = isinstance(goal, Stand) and not goal.unless_carrying
        return at if moves and at >= self._last_event.get(agent, -math.inf) - EPS else now

    def _refuse(self, b: _Bot, goal: Goal, cell: Cell) -> tuple[str, str] | None:
        if isinstance(goal, Follow):
            path = goal.path
            if not path:
                return "PATH", "empty path"
            if path[0] != cell and manhattan(path[0], cell) != 1:
                return "START", f"path starts at {path[0]}, robot at {cell}"
            grid = self.scenario.grid
            if not all(grid.contains(c) for c in path) or any(
                manhattan(a, c) != 1 for a, c in zip(path, path[1:])
            ):
                return "PATH", REFUSALS["PATH"]
            return None
        if isinstance(goal, Stand):
            if goal.unless_carrying and b.kind == "carry":
                return "CARRYING", REFUSALS["CARRYING"]
            if goal.state == FINISH_STATE and cell != b.base:
                return "NOT_AT_BASE", f"finished at {cell}, base {b.base}"
            return None
        o = self.objects.get(goal.object)
        if o is None:
            return "UNKNOWN", f"no object {goal.object}"
        if o.delivered is not None:
            return "DELIVERED", f"object {goal.object} is delivered"
        if o.moving:
            return "IN_TRANSIT", f"object {goal.object} is being carried"
        if o.at != cell:
            return "NOT_AT_OBJECT", f"object {goal.object} lies at {o.at}, robot at {cell}"
        if (
            b.id not in goal.group
            or len(set(goal.group)) != o.spec.required
            or any(j not in self.bots for j in goal.group)
        ):
            return "BAD_GROUP", f"group {list(goal.group)} for object {goal.object} (n_i {o.spec.required})"
        # (a member declared out is stopped, not dead: readmitted, it comes to hold; if it dies,
        # its notice has the group let go)
        dead = [j for j in goal.group if not self.bots[j].alive and not self.bots[j].out]
        if dead:
            return "MEMBER_FAILED", f"agents {dead} of the group have failed"
        return None

    def _handover(self, b: _Bot, at: float) -> tuple[Cell, float, int]:
        """(cell, time, index in the route) of the robot's first boundary at or after ``at``."""
        r = b.route
        if r is None:
            return b.cell, max(at, b.time), 0
        m, time = r.boundary(at)
        return r.cells[m], time, m

    def _finish_label(self, b: _Bot, goal: Goal, time: float) -> None:
        if goal.state == FINISH_STATE:
            if b.finished is None:
                b.finished = time
        elif b.finished is not None:
            b.finished_total += time - b.finished  # called back to work
            b.finished = None

    def _leave(self, b: _Bot, at: float, time: float, cell: Cell, m: int) -> list[GoalResult]:
        """End the robot's current goal at its handover (``cell`` at ``time``, ``m`` moves made)."""
        out: list[GoalResult] = []
        if b.goal and b.kind != "done":
            out.append(GoalResult(b.id, b.goal, PREEMPTED, time, cell))
        if b.kind == "follow" and b.route is not None:
            b.route.made = m
        elif b.kind == "hold":
            self._unhold(b)
        elif b.kind == "carry":
            self._break(self._carries[b.holding], at, b.id, "CARRIER_LEFT")
        b.route, b.kind, b.cell, b.time = None, "", cell, time
        b.holding, b.group = -1, ()
        return out

    def _follow(self, b: _Bot, goal: Follow, cell: Cell, time: float) -> None:
        path = list(goal.path)
        b.offset = 0 if path[0] == cell else 1
        cells = path if path[0] == cell else [cell] + path
        b.goal_path = goal.path
        b.kind = "follow"
        if len(cells) == 1:
            b.kind, b.route = "done", None
            self._push(time, 3, ("reached", b.id, b.goal, b.version))
            return
        f = self._factor()
        first = _first_movable(max(time, b.stall_until), b.period)
        r = Route(cells, time, follow_departures(first, len(cells) - 1, b.period, f), f)
        b.route, b.factor = r, f
        b.legs.append(_Leg(r, "search" if goal.state == SEARCHING_STATE else "travel"))
        self._schedule_follow(b)

    def _schedule_follow(self, b: _Bot) -> None:
        """The goal's REACHED and detections, from its route (again after a stall)."""
        r = b.route
        assert r is not None
        self._push(r.arrive(len(r.cells) - 1), 3, ("reached", b.id, b.goal, b.version))
        ids = [i for cell in self._rest.values() for i in cell]
        if not ids:
            return
        cells = np.array([self.objects[i].at for i in ids], dtype=np.int64).reshape(-1, 2)
        first = first_sensing(np.asarray(r.cells, dtype=np.int64).reshape(-1, 2), cells)
        hits: dict[int, list[int]] = defaultdict(list)
        for i, k in zip(ids, first):
            if k >= 1 and r.arrive(int(k)) >= self.now - EPS:  # not sensed yet
                hits[int(k)].append(i)
        for k, objs in hits.items():
            self._push(r.arrive(k), 4, ("detect", b.id, b.goal, b.version, k, tuple(sorted(objs))))

    def _next(self) -> int:
        self._serial += 1
        return self._serial

    def _factor(self) -> float:
        if self.speed_jitter <= 0:
            return 1.0
        return 1.0 + self.speed_jitter * float(self._rng.uniform())

    # ------------------------------------------------------------------ carrying

    def _hold(self, b: _Bot, goal: Carry, time: float) -> None:
        b.kind, b.route, b.holding, b.group = "hold", None, goal.object, tuple(sorted(goal.group))
        b.factor = self._factor()
        self._holds[goal.object][b.id] = b.group
        self._check_group(goal.object)

    def _check_group(self, oid: int) -> None:
        """Schedule the lift once every member of some declared group holds with that group."""
        holds = self._holds.get(oid, {})
        for group in sorted(set(holds.values())):
            if all(holds.get(j) == group for j in group):
                bots = [self.bots[j] for j in group]
                k = group_period([x.period for x in bots])
                start = max(max(x.time for x in bots), max(x.stall_until for x in bots), self.now)
                t = _first_movable(start, k)
                version = self._next()
                self._depart[oid] = (t, version)
                self._push(t, 1, ("lift", oid, version, group))
                return

    def _unhold(self, b: _Bot) -> None:
        holds = self._holds.get(b.holding, {})
        holds.pop(b.id, None)
        if b.holding in self._depart:  # a lift scheduled with it: called off
            self._depart[b.holding] = (math.inf, self._next())

    def _lift(self, oid: int, group: tuple[int, ...], t: float) -> list[Event]:
        o = self.objects[oid]
        bots = [self.bots[j] for j in group]
        k = group_period([x.period for x in bots])
        f = max(x.factor for x in bots)
        cells = route([o.at, o.spec.destination])
        r = Route(cells, t, carry_departures(t, len(cells) - 1, k, f), f)
        run = _Carry(oid, group, r, k, self._next())
        self._carries[oid] = run
        self._holds.pop(oid, None)
        self._depart.pop(oid, None)
        self._rest[o.at].discard(oid)
        o.moving, o.carriers = True, group
        if o.start is None:  # picked up again after a drop: the first lift stays its start
            o.start = t
        for x in bots:
            x.kind, x.route = "carry", r
            x.legs.append(_Leg(r, "carry"))
        self._push(r.arrive(len(cells) - 1), 2, ("deliver", oid, run.version))
        return [CarryStarted(oid, group, t, f)]

    def _deliver(self, run: _Carry, t: float) -> list[Event]:
        o = self.objects[run.object]
        o.moving, o.at, o.delivered = False, o.spec.destination, t
        del self._carries[run.object]
        out: list[Event] = []
        for j in run.group:
            x = self.bots[j]
            if not x.alive or x.kind != "carry" or x.holding != run.object:
                continue  # failed, or let go on the last move
            x.delivered.append(run.object)
            x.cell, x.time, x.route, x.kind, x.holding, x.group = o.spec.destination, t, None, "done", -1, ()
            out.append(GoalResult(j, x.goal, REACHED, t, o.spec.destination))
        return out

    def _break(self, run: _Carry, at: float, culprit: int, code: str) -> None:
        """A carry ends early (a member left or failed): the group completes its current move and
        drops the object there; the other live members' goals end ABORTED."""
        r = run.route
        m, time = r.boundary(at)
        if m == len(r.cells) - 1:
            return  # the move under way is the last: the object is delivered all the same
        r.made = m
        o = self.objects[run.object]
        o.moving, o.at = False, r.cells[m]
        del self._carries[run.object]
        for j in run.group:
            x = self.bots[j]
            if j == culprit or not x.alive:
                continue
            x.cell, x.time, x.route, x.kind, x.holding, x.group = r.cells[m], time, None, "done", -1, ()
            x.broken = (time, run.object)
            reason = f"agent {culprit} {'failed' if code == 'MEMBER_FAILED' else 'let go'}"
            self._push(time, 3, ("abort", j, x.goal, x.version, code, reason, r.cells[m]))
        self._drop(run.object, time)

    def _drop(self, oid: int, t: float) -> None:
        """Object ``oid`` comes to rest at its cell at time t: robots on the way sense it."""
        o = self.objects[oid]
        self._rest[o.at].add(oid)
        for b in self.bots.values():
            if not b.alive:
                continue
            if b.kind == "follow" and b.route is not None:
                r = b.route
                done = r.committed(t + 2 * EPS)
                for k in range(done, len(r.cells)):
                    c = r.cells[k]
                    if max(abs(c[0] - o.at[0]), abs(c[1] - o.at[1])) <= 1:
                        self._push(max(r.arrive(k), t), 4, ("detect", b.id, b.goal, b.version, k, (oid,)))
                        break
            elif b.kind in ("stand", "hold", "done", ""):
                c = b.cell
                if max(abs(c[0] - o.at[0]), abs(c[1] - o.at[1])) <= 1:
                    self._push(t, 4, ("detect", b.id, b.goal, b.version, -1, (oid,)))

    # ------------------------------------------------------------------ failures and stalls

    def kill(self, agent: int, t: float, out: bool = False) -> None:
        """Robot ``agent`` fails at time t (``out``: is declared out — stopped as if failed, but
        not dead: it may come back, :meth:`revive`): it stops; a lift it was part of is called
        off (its partners' holds end ABORTED), a carry it was in drops the object where the move
        under way ends."""
        b = self.bots.get(agent)
        if b is None or not b.alive:
            if b is not None and b.out and not out:  # out, and now dead for good
                b.out = False
                self.outs.pop(agent, None)
                self.failed[agent] = math.ceil(t - EPS)
                self._done = None
            return
        self._done = None
        self.now = max(self.now, t)
        b.alive, b.died, b.out = False, t, out
        if out:
            self.outs[agent] = math.ceil(t - EPS)
        else:
            self.failed[agent] = math.ceil(t - EPS)
        if b.kind == "follow" and b.route is not None:
            b.route.made = b.route.reached_by(t)
        elif b.kind == "hold":
            oid = b.holding
            self._unhold(b)
            for j, g in list(self._holds.get(oid, {}).items()):
                if agent in g:
                    x = self.bots[j]
                    self._push(
                        t,
                        3,
                        ("abort", j, x.goal, x.version, "MEMBER_FAILED", f"agent {agent} failed", x.cell),
                    )
        elif b.kind == "carry":
            oid = b.holding
            run = self._carries[oid]
            if run.route.boundary(t)[0] == len(run.route.cells) - 1:
                b.delivered.append(oid)  # its last move under way: delivered all the same
            else:
                self._break(run, t, agent, "MEMBER_FAILED")
                self._loads[agent] = (oid, self.objects[oid].at)
        if b.kind == "hold":
            self._loads[agent] = (b.holding, self.objects[b.holding].at)
        b.version += 1
        b.kind, b.route, b.goal = "dead", None, 0
        b.cell = self.position(agent, t)
        self._labelled(agent, t, OUT_STATE if out else FAILED_STATE)

    def _labelled(self, agent: int, t: float, state: str) -> None:
        runs = self.labels[agent]
        if not runs or runs[-1][1] != state:
            runs.append((t, state))

    def revive(self, agent: int, t: float, life: int) -> None:
        """Robot ``agent``, stopped when it was declared out, is back (a member readmitted it): its
        base takes goals again from where it stopped, holding nothing."""
        b = self.bots.get(agent)
        if b is None or b.alive:
            return
        self._done = None
        self.now = max(self.now, t)
        b.alive, b.time = True, max(t, b.died if b.died is not None else t)
        b.died, b.out, b.life = None, False, life
        b.kind, b.route, b.goal, b.holding, b.group = "", None, 0, -1, ()
        b.version += 1
        self.outs.pop(agent, None)
        self._loads.pop(agent, None)
        self.revived.append((agent, t))

    def notice(self, agent: int, stamp: int, seq: int, sensed_until: float | None = None) -> Lost:
        """The world's stamped notice of ``agent``'s failure: where its counted sensing ends (the
        cell it occupied at step ``stamp``, or at ``sensed_until`` if that is earlier: over DDS the
        world learns of a death late and its base moved on meanwhile — what the robot reported is
        what it sensed up to the last watermark the world heard, since it commits a time only
        once its base's events up to it are in), the object it held or carried (where it lies
        now) and the objects it helped deliver."""
        b = self.bots[agent]
        died = b.died if b.died is not None else self.now
        until = min(float(stamp), died, math.inf if sensed_until is None else sensed_until)
        at = self.position(agent, until)
        dropped: tuple[ObjectInfo, ...] = ()
        load = self._loads.get(agent)
        if load is not None and self.objects[load[0]].delivered is None:
            o = self.objects[load[0]]
            dropped = (ObjectInfo(o.spec.id, o.at, o.spec.destination, o.spec.required),)
        return Lost(agent, stamp, dropped, seq=seq, at=at, delivered=tuple(b.delivered))

    def _stall(self, agent: int, t: float, steps: float) -> list[Event]:
        """The robot stands still for ``steps`` from ``t``; who moves differently for it (a
        carry: its whole group) is told when the world is tracking."""
        b = self.bots[agent]
        if not b.alive:
            return []
        b.stall_until = max(b.stall_until, t + steps)
        moved: list[int] = []
        if b.kind == "follow" and b.route is not None:
            b.route.shift(t, steps)
            b.version += 1
            self._schedule_follow(b)
            moved = [agent]
        elif b.kind == "carry":
            run = self._carries[b.holding]
            run.route.shift(t, steps)
            run.version = self._next()
            self._push(run.route.arrive(len(run.route.cells) - 1), 2, ("deliver", run.object, run.version))
            moved = [j for j in run.group if self.bots[j].alive and self.bots[j].kind == "carry"]
        elif b.kind == "hold" and b.holding in self._depart:
            self._check_group(b.holding)
        return [Stalled(j, t, steps) for j in moved] if self.tracking else []

    # ------------------------------------------------------------------ events

    def _push(self, t: float, order: int, event: tuple) -> None:
        self._count += 1
        heapq.heappush(self._heap, (t, order, self._count, event))

    def _valid(self, ev: tuple) -> bool:
        kind = ev[0]
        if kind in ("reached", "detect", "abort"):
            b = self.bots[ev[1]]
            return b.alive and b.goal == ev[2] and b.version == ev[3]
        if kind == "lift":
            return self._depart.get(ev[1], (0.0, -1))[1] == ev[2]
        if kind == "deliver":
            run = self._carries.get(ev[1])
            return run is not None and run.version == ev[2]
        return True

    def advance(self, now: float) -> list[Event]:
        """Everything due up to ``now``, in time order."""
        out: list[Event] = []
        while self._heap and self._heap[0][0] <= now + EPS:
            t, _, _, ev = heapq.heappop(self._heap)
            if not self._valid(ev):
                continue
            self._done = None
            self.now = max(self.now, t)
            kind = ev[0]
            if kind == "stall":
                out += self._stall(ev[1], t, ev[2])
            elif kind == "lift":
                out += self._lift(ev[1], ev[3], t)
            elif kind == "deliver":
                out += self._deliver(self._carries[ev[1]], t)
            elif kind == "reached":
                b = self.bots[ev[1]]
                cell = b.route.cells[-1] if b.route is not None else b.cell
                if b.route is not None:
                    b.cell, b.time, b.route = cell, t, None
                b.kind = "done"
                out.append(GoalResult(b.id, b.goal, REACHED, t, cell))
            elif kind == "abort":
                b = self.bots[ev[1]]
                if b.kind == "hold":
                    self._unhold(b)
                b.kind, b.holding, b.group = "done", -1, ()
                out.append(GoalResult(b.id, b.goal, ABORTED, t, ev[6], ev[4], ev[5]))
            elif kind == "detect":
                det = self._detect(ev, t)
                if det is not None:
                    out.append(det)
        self.now = max(self.now, now)
        return self._noted(out)

    def _detect(self, ev: tuple, t: float) -> Detection | None:
        b = self.bots[ev[1]]
        k = ev[4]
        cell = b.route.cells[k] if (k >= 0 and b.route is not None) else b.cell
        objs = []
        for oid in ev[5]:
            o = self.objects[oid]
            if (
                not o.moving
                and o.delivered is None
                and max(abs(cell[0] - o.at[0]), abs(cell[1] - o.at[1])) <= 1
            ):
                objs.append(o.spec)
        if not objs:
            return None
        return Detection(b.id, t, cell, tuple(objs), self._sensed(cell))

    def _sensed(self, cell: Cell) -> tuple[ObjectInfo, ...]:
        out: list[ObjectInfo] = []
        for dx, dy in BLOCK:  # the lockstep world's order
            ids = self._rest.get((cell[0] + dx, cell[1] + dy))
            if ids:
                out.extend(self.objects[i].spec for i in sorted(ids))
        return tuple(out)

    # ------------------------------------------------------------------ the record

    def record(self, agent: int) -> AgentRecord:
        """The agent's account, as the lockstep world keeps it: moves along sweeps (search),
        other moves (travel), moves with a group (carry), and the rest of its working time idle
        (time finished at its base is not idle)."""
        b = self.bots[agent]
        moved = {"search": 0.0, "travel": 0.0, "carry": 0.0}
        for leg in b.legs:
            moved[leg.kind] += leg.route.moves * leg.route.factor
        if b.finished is not None:  # (a failed robot that had finished keeps it, as in lockstep)
            horizon = b.finished
        elif b.died is not None:  # (a carry's last move under way when it died is made: counted)
            horizon = max([b.died] + [leg.route.arrive(leg.route.moves) for leg in b.legs[-1:]])
        else:
            horizon = self.end
        idle = horizon - sum(moved.values()) - b.finished_total
        return AgentRecord(
            agent,
            finished=_num(b.finished),
            idle=_num(idle),
            carry=_num(moved["carry"]),
            search=_num(moved["search"]),
            travel=_num(moved["travel"]),
        )

    def undeliverable(self) -> list[int]:
        n = self.survivors
        return sorted(i for i, o in self.objects.items() if o.delivered is None and o.spec.required > n)

    @property
    def t(self) -> int:
        """Steps run (as the lockstep world counts them: the step after the last one)."""
        return math.ceil(self.end - EPS) + 1 if self.done else math.ceil(self.end - EPS)

    def result(self, **extra: Any) -> RunResult:
        objects = [
            ObjectRecord(o.spec.id, o.carriers, _num(o.start), _num(o.delivered))
            for o in sorted(self.objects.values(), key=lambda o: o.spec.id)
        ]
        return world_result(
            [self.record(a.id) for a in self.scenario.agents],
            objects,
            done=self.done,
            left=self.undeliverable(),
            required={i: o.spec.required for i, o in self.objects.items()},
            failed=self.failed,
            steps=self.t,
            rejections=self.refusals,
            **extra,
        )
