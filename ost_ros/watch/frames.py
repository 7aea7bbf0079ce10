"""Frames of a run: what the world looked like at chosen steps, recorded by a step hook.

:class:`FrameRecorder` is a step hook (``on_step(world, actions)``) of the step engine and of the
world's lockstep runtime (so it records an in-process run, a DDS run followed live, and a run
replayed from a recording alike). It keeps a frame every ``every`` steps and at every decision
point of the task — an object lifted for the first time or delivered, a robot failed — plus the
first and the last step, so a 10⁵-step run renders in a few hundred frames, not 10⁵.

Without a fixed ``every`` the recorder adapts: it starts with a frame every step and, whenever
the regular frames exceed ``target``, keeps every other one and doubles the spacing — so
memory stays bounded whatever the run's length, and the choice of frames is deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ost_ros.messages import SEARCHING_STATE, Action, ActionKind
from ost_ros.model import Scenario
from ost_ros.world import World

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


@dataclass
class FrameRecorder:
    """A step hook that keeps the frames of a run (see the module's docstring)."""

    scenario: Scenario
    every: int | None = None  # fixed spacing in steps; None: adaptive around ``target`` frames
    target: int = 400
    frames: list[Frame] = field(default_factory=list)
    spacing: int = field(init=False)

    def __post_init__(self) -> None:
        if self.every is not None and self.every < 1:
            raise ValueError(f"every: {self.every} must be at least 1")
        self.spacing = self.every or 1
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

    def _keep(self, frame: Frame) -> None:
        if self.frames and self.frames[-1].t == frame.t:
            self.frames[-1] = frame
        else:
            self.frames.append(frame)
        if self.every is None and sum(not f.event for f in self.frames) > self.target:
            self.spacing *= 2  # thin the regular frames; decision points stay
            self.frames = [f for f in self.frames if f.event or f.t % self.spacing == 0]

    def finish(self) -> list[Frame]:
        """The frames, the last step's included (call once the run is over)."""
        if self._world is not None and self.frames[-1].t != self._world.t:
            self.frames.append(self._frame(self._world, False))
        return self.frames
