"""Frames of a run: what the world looked like at chosen steps, recorded by a step hook.

:class:`FrameRecorder` is a step hook (``on_step(world, actions)``) of the step engine and of the
world's lockstep runtime (so it records an in-process run, a DDS run followed live, and a run
replayed from a recording alike). It keeps a frame every ``every`` steps and at every decision
point of the task — an object lifted for the first time or delivered, a robot failed — plus the
first and the last step, so a 10⁵-step run renders in a few hundred frames, not 10⁵.

Without a fixed ``every`` the recorder adapts: it starts with a frame every step and, whenever
the regular frames exceed ``target``, keeps every other one and doubles the spacing — so
memory stays bounded whatever the run's length, and the choice of frames is deterministic.

:class:`RealtimeRecorder` keeps the same frames of a run without a barrier (``ost sim --latency
… --animate``), which has no steps: it watches the in-process run (an
:class:`~ost_ros.realtime.run.Observer`), takes the world at the same regular steps and at the
step after each decision point, and adds who was in the team then — robots silent, declared out,
dead, not joined yet, the partition in force — and the latest change of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ost_ros.messages import SEARCHING_STATE, Action, ActionKind
from ost_ros.model import Scenario
from ost_ros.realtime.membership import ABSENT, DEAD, IN, OUT, SILENT
from ost_ros.world import World

if TYPE_CHECKING:
    from ost_ros.realtime.run import _Run
    from ost_ros.realtime.world import Snapshot

FAILED_STATE = "FAILED"  # drawn for a robot the world declared failed


@dataclass(frozen=True)
class Frame:
    """The world at the start of step ``t`` (after ``t`` steps)."""

    t: int
    positions: np.ndarray  # (N, 2) int: robot cells, in the scenario's agent order
    states: tuple[str, ...]  # each robot's global state (its last action's)
    holding: np.ndarray  # (N,) int: the object a robot holds or carries, -1 for none
    objects: np.ndarray  # (M, 2) int: object cells, in the scenario's object order
    delivered: np.ndarray  # (M,) bool
    event: bool = False  # taken at a decision point (a lift, a delivery, a failure)
    # Who is in the team (a run without a barrier; empty otherwise): per robot IN, SILENT, OUT,
    # DEAD or ABSENT (ost_ros.realtime.membership), its side of the partition in force (-1:
    # none), that partition ("0,1,2 | 3,4"), the latest change ("agent 3 declared out at 210")
    team: tuple[str, ...] = ()
    sides: tuple[int, ...] = ()
    split: str = ""
    note: str = ""


@dataclass
class _Frames:
    """Frames every ``spacing`` steps plus decision points, thinned to about ``target``."""

    scenario: Scenario
    every: int | None = None  # fixed spacing in steps; None: adaptive around ``target`` frames
    target: int = 400
    frames: list[Frame] = field(default_factory=list)
    spacing: int = field(init=False)

    def __post_init__(self) -> None:
        if self.every is not None and self.every < 1:
            raise ValueError(f"every: {self.every} must be at least 1")
        self.spacing = self.every or 1

    def _keep(self, frame: Frame) -> None:
        if self.frames and self.frames[-1].t == frame.t:
            self.frames[-1] = frame
        else:
            self.frames.append(frame)
        if self.every is None and sum(not f.event for f in self.frames) > self.target:
            self.spacing *= 2  # thin the regular frames; decision points stay
            self.frames = [f for f in self.frames if f.event or f.t % self.spacing == 0]


@dataclass
class FrameRecorder(_Frames):
    """A step hook that keeps the frames of a run (see the module's docstring)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self._agents = [a.id for a in self.scenario.agents]
        self._objects = [o.id for o in self.scenario.objects]
        self._states = {a: SEARCHING_STATE for a in self._agents}
        self._milestones: tuple = (
            tuple(False for _ in self._objects),
            tuple(False for _ in self._objects),
        )
        self._failed = 0
        self._world: World | None = None  # the world of the last step seen
        n = len(self._agents)
        self.frames.append(
            Frame(
                0,
                np.array([a.base for a in self.scenario.agents], dtype=np.int64).reshape(n, 2),
                tuple(self._states.values()),
                np.full(n, -1, dtype=np.int64),
                np.array([o.location for o in self.scenario.objects], dtype=np.int64).reshape(-1, 2),
                np.zeros(len(self._objects), dtype=bool),
                event=True,
            )
        )

    def __call__(self, world: World, actions: list[Action]) -> None:
        for a in actions:
            self._states[a.agent] = a.state
        for agent in world.failed:
            self._states[agent] = FAILED_STATE
        event = False
        # Lifts and deliveries happen only in steps with a carry; failures change the count.
        if len(world.failed) != self._failed or any(a.kind is ActionKind.CARRY for a in actions):
            milestones = (
                tuple(world.objects[i].start is not None for i in self._objects),
                tuple(world.objects[i].delivered is not None for i in self._objects),
            )
            event = milestones != self._milestones or len(world.failed) != self._failed
            self._milestones, self._failed = milestones, len(world.failed)
        self._world = world
        if event or world.t % self.spacing == 0 or world.done:
            self._keep(self._frame(world, event))

    def _frame(self, world: World, event: bool) -> Frame:
        holding = [-1 if a in world.failed else world.carrying.get(a, -1) for a in self._agents]
        return Frame(
            world.t,
            np.array([world.positions[a] for a in self._agents], dtype=np.int64).reshape(-1, 2),
            tuple(self._states[a] for a in self._agents),
            np.array(holding, dtype=np.int64),
            np.array([world.objects[i].at for i in self._objects], dtype=np.int64).reshape(-1, 2),
            np.array([world.objects[i].delivered is not None for i in self._objects], dtype=bool),
            event=event,
        )

    def finish(self) -> list[Frame]:
        """The frames, the last step's included (call once the run is over)."""
        if self._world is not None and self.frames[-1].t != self._world.t:
            self.frames.append(self._frame(self._world, False))
        return self.frames


EPS = 1e-9


@dataclass
class RealtimeRecorder(_Frames):
    """The frames of a run without a barrier (see the module's docstring): the run calls
    :meth:`advance` each time its clock moves on and :meth:`end` once it is over. A frame at
    step s is the world at time s; a decision point at time T (a first lift, a delivery, a change
    in the team or a partition beginning or healing) gives a frame at the first step ≥ T. It
    reads the run and never changes it."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self._team = {a.id: IN for a in self.scenario.agents}
        self._joiners: set[int] = set()  # robots that were absent (their first way in: "admitted")
        self._split: object = None
        self._milestones: tuple = ()
        self._note = ""
        self._event = False  # a decision point not drawn yet
        self._next = 0  # the first step not drawn yet
        self._done = False

    def advance(self, run: _Run, now: float, until: float) -> None:
        """Nothing happens in the run from ``now`` (every event at it handled) until ``until``
        but a partition beginning or healing (no event of the run: only the network knows)."""
        cuts = sorted(
            {x for sp in run.net.splits for x in (sp.start, sp.start + sp.steps) if now < x < until}
        )
        for a, b in zip([now, *cuts], [*cuts, until]):
            self._between(run, a, b)

    def _between(self, run: _Run, now: float, until: float) -> None:
        self._look(run, now)
        s = max(math.ceil(now - EPS), self._next)
        if self._event and s < until - EPS:
            self._take(run, s, event=True)
            s += 1
        while True:
            k = self.spacing  # (thinning may double it as frames are kept)
            s = -(-s // k) * k
            if s >= until - EPS:
                return
            self._take(run, s, event=False)
            s += 1

    def end(self, run: _Run) -> None:
        """The run is over (at ``world.end``): its last frame, at the step count of its result."""
        w = run.world
        self.advance(run, w.end, w.t)  # (its last decision point's frame, if it is due before)
        self._look(run, w.end)
        self._take(run, max(w.t, self._next), event=True)
        self._done = True

    def finish(self) -> list[Frame]:
        """The frames (call once the run is over)."""
        if not self._done:
            raise RuntimeError("the run is not over")
        return self.frames

    def _look(self, run: _Run, now: float) -> None:
        """What changed at ``now``: the team, the partition, lifts and deliveries."""
        team, split = run.team_at(now)
        t = _time(now)
        notes = []
        for a, new in team.items():
            old = self._team.get(a, IN)
            if new != old:
                notes.append(f"agent {a} {self._says(a, old, new)} at {t}")
                self._team[a] = new
        if split is not self._split:
            if split is not None:
                notes.append(f"partition at {t}")
            else:
                notes.append(f"partition healed at {t}")
            self._split = split
        if notes:
            self._note = "; ".join(notes)
            self._event = True
        w = run.world
        milestones = (
            sum(o.start is not None for o in w.objects.values()),
            sum(o.delivered is not None for o in w.objects.values()),
        )
        if milestones != self._milestones:
            self._event = self._event or bool(self._milestones)
            self._milestones = milestones

    def _says(self, agent: int, old: str, new: str) -> str:
        if new == ABSENT:
            self._joiners.add(agent)
            return "not there yet"
        if new == DEAD:
            return "dead"
        if new == SILENT:
            return "silent"
        if new == OUT:
            return "joins" if old == ABSENT else "declared out"
        if old == SILENT:
            return "heard again"
        if agent in self._joiners:
            self._joiners.discard(agent)
            return "admitted"
        return "back"

    def _take(self, run: _Run, s: int, event: bool) -> None:
        snap: Snapshot = run.world.snapshot(float(s))
        team, split = run.team_at(float(s))
        ids = [a.id for a in self.scenario.agents]
        n = len(ids)
        sides: tuple[int, ...] = ()
        if split is not None:
            sides = tuple(next((k for k, g in enumerate(split.groups) if a in g), -1) for a in ids)
        self._keep(
            Frame(
                s,
                np.array(snap.positions, dtype=np.int64).reshape(n, 2),
                snap.states,
                np.array(snap.holding, dtype=np.int64).reshape(n),
                np.array(snap.objects, dtype=np.int64).reshape(-1, 2),
                np.array(snap.delivered, dtype=bool).reshape(-1),
                event=event,
                team=tuple(team[a] for a in ids),
                sides=sides,
                split=_sides(split.groups) if split is not None else "",
                note=self._note,
            )
        )
        self._next = s + 1
        self._event = False


def _time(t: float) -> str:
    return str(round(t)) if abs(t - round(t)) < 1e-6 else f"{t:.1f}"


def _sides(groups) -> str:
    return " | ".join(",".join(map(str, sorted(g))) for g in groups)
