"""Quiet plans: what an agent will do, without a word, while nothing reaches it.

A protocol's agent describes its next steps as a few :class:`Segment` s — sweep, walk, wait, hold
or carry — each of which repeats one kind of action under the world's rules of motion (one cell
per movable step, x first; a carry moves the object and its group). One description serves both
places that skip steps:

- the event engine (:mod:`ost_ros.engines.event`) jumps over the first segment of every agent at
  once (:func:`advance`), then tells each agent (``skip``);
- the DDS runtime (:mod:`ost_ros.lockstep.agent`) sends the whole plan, step by step (:func:`rows`),
  to the world, which executes it as long as what it observes is what the plan expects.

A plan is valid from the step it was made for, as long as no message reaches the agent and its
sensor shows nothing it reacts to (the agent's ``news``); callers check the second condition.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

from ost_ros.messages import ActionKind
from ost_ros.model import Cell, can_move, moves_between, walk
from ost_ros.motion import apply, step_toward

KINDS = ("sweep", "walk", "wait", "hold", "carry")


@dataclass(frozen=True)
class Segment:
    """``steps`` steps (None: until something happens) of one repeated behaviour, each reported
    with global state ``state``.

    - ``sweep``: follow ``path`` from ``path[index]`` (where the agent stands), one cell per
      movable step (steps t with t % ``period`` == 0; it waits in the others), sensing all the way;
    - ``walk``: toward ``target``, one cell per movable step, waiting in the others;
    - ``wait``: stand still;
    - ``hold``: carry ``object`` toward ``target`` (its destination) without it moving: the
      group is not complete yet;
    - ``carry``: carry ``object`` toward ``target``; the group moves in every step movable for
      ``period`` (the group's: the lcm of its members').
    """

    kind: str
    state: str
    steps: int | None = None
    period: int = 1
    target: Cell | None = None
    path: Sequence[Cell] = ()
    index: int = 0
    object: int = -1

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"segment kind {self.kind!r} is not one of {', '.join(KINDS)}")
        if self.steps is not None and self.steps < 1:
            raise ValueError(f"a {self.kind} segment lasts at least one step, not {self.steps}")

    @property
    def reads_sensor(self) -> bool:
        """Whether the agent looks at its sensor in these steps (it only does while sweeping)."""
        return self.kind == "sweep"


@dataclass(frozen=True)
class Plan:
    """An agent's quiet steps, segment after segment. ``settled``: the first segment continues
    what the agent is already doing — it decides nothing in its first step (no hand-over to
    another state or task), so the event engine may jump over it without calling ``act``."""

    segments: tuple[Segment, ...] = ()
    settled: bool = False

    def __iter__(self) -> Iterator[Segment]:
        return iter(self.segments)

    def __len__(self) -> int:
        return len(self.segments)

    def __getitem__(self, k: int) -> Segment:
        return self.segments[k]


NO_PLAN = Plan()  # the agent decides (and may speak) in the first step


@dataclass(frozen=True)
class PlannedStep:
    """One step of a plan: where the agent stands, whether it reads its sensor, and its action."""

    t: int
    position: Cell
    reads_sensor: bool
    kind: ActionKind
    direction: Cell
    object: int
    state: str


def _act(seg: Segment, s: int, pos: Cell, m: int) -> tuple[ActionKind, Cell, int, bool]:
    """The action of segment ``seg`` in step s from ``pos`` (sweep: on path[m]); and whether the
    agent's cell changes after it."""
    if seg.kind == "sweep":
        if m < len(seg.path) - 1 and can_move(s, seg.period):
            return ActionKind.MOVE, step_toward(pos, seg.path[m + 1]), -1, True
        return ActionKind.WAIT, (0, 0), -1, False
    if seg.kind == "walk":
        assert seg.target is not None
        if pos != seg.target and can_move(s, seg.period):
            return ActionKind.MOVE, step_toward(pos, seg.target), -1, True
        return ActionKind.WAIT, (0, 0), -1, False
    if seg.kind == "wait":
        return ActionKind.WAIT, (0, 0), -1, False
    assert seg.target is not None
    moves = seg.kind == "carry" and pos != seg.target and can_move(s, seg.period)
    return ActionKind.CARRY, step_toward(pos, seg.target), seg.object, moves


def unroll(plan: Iterable[Segment], t: int, position: Cell, limit: int) -> list[PlannedStep]:
    """The plan step by step from step ``t`` at ``position``: at most ``limit`` steps (an
    open-ended segment is cut there)."""
    return [PlannedStep(*row) for row in rows(plan, t, position, limit)]


Row = tuple[int, Cell, bool, ActionKind, Cell, int, str]  # a PlannedStep's fields, in order


def rows(plan: Iterable[Segment], t: int, position: Cell, limit: int) -> Iterator[Row]:
    """:func:`unroll`'s steps as plain tuples, one at a time: the DDS runtime reads them until
    the agent would sense news, every time it acts (no object per step, none past the cut)."""
    done = 0
    pos, s = position, t
    for seg in plan:
        n = limit - done if seg.steps is None else min(seg.steps, limit - done)
        m = seg.index
        for _ in range(n):
            kind, direction, obj, moves = _act(seg, s, pos, m)
            yield s, pos, seg.reads_sensor, kind, direction, obj, seg.state
            if moves:
                pos = apply(pos, direction)
                m += 1
            s += 1
        done += n
        if done >= limit:
            break


def advance(seg: Segment, t: int, position: Cell, steps: int) -> tuple[Cell, int]:
    """Where ``steps`` steps of ``seg`` from step ``t`` at ``position`` end, and how many moves
    they make (for a hold: none; for a carry: the object's moves too)."""
    if seg.kind in ("wait", "hold"):
        return position, 0
    moves = moves_between(t, t + steps, seg.period)
    if seg.kind == "sweep":
        moves = min(moves, len(seg.path) - 1 - seg.index)
        return seg.path[seg.index + moves], moves
    assert seg.target is not None
    end = walk(position, seg.target, moves)
    return end, abs(end[0] - position[0]) + abs(end[1] - position[1])


def rest(seg: Segment, t: int, steps: int) -> Segment:
    """What is left of ``seg`` (started in step ``t``) after ``steps`` of its steps."""
    left = None if seg.steps is None else seg.steps - steps
    index = seg.index
    if seg.kind == "sweep":
        index += min(moves_between(t, t + steps, seg.period), len(seg.path) - 1 - seg.index)
    if left is None and index == seg.index:
        return seg  # an open-ended wait, hold or walk: nothing of it is used up
    # The constructor, not dataclasses.replace: the event engine ages every quiet agent's plan
    # after every deciding step, and replace's generic field walk was a quarter of an HCP run.
    return Segment(seg.kind, seg.state, left, seg.period, seg.target, seg.path, index, seg.object)
