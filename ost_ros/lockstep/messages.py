"""Message schemas of the lockstep (world node ↔ agent nodes), on top of the protocol messages.
ROS-free: the runtimes (:mod:`.agent`, :mod:`.world`) exchange these; the nodes carry them.

- :class:`Ready`: an agent is up and has matched every endpoint it needs (discovery done);
- :class:`Tick` (world → one agent): the observation of step t, and which peers broadcast in the
  previous lockstep step (the count the agent's barrier waits for);
- :class:`Acted` (agent → world): the action of step t, how many protocol messages the agent
  broadcast in step t, and (event skipping) its plan for the following quiet steps;
- :class:`Sample` (agent → all agents, on the topic of the message's kind): one protocol message of
  step t with its place ``seq`` among the sender's messages of the step. An agent runs its comm
  module for step t once it holds every sample of every sender the world listed, as many as the
  world counted — a counting barrier whose counts the world supplies, so quiet steps cost no
  agent-to-agent traffic;
- :class:`Resend`: recovery — an agent whose tick waited too long for some peers' batches asks
  them to publish those again (the world likewise re-sends a tick whose action does not come);
- :class:`RunInfo`: the world's description of its run (latched), for whoever follows it;
- :class:`RunEnd`: the world's clock stopped (every object delivered and every agent home, or
  the step limit); agents answer with an :class:`AgentReport` (what only agents know: the
  schedule they hold, predicted makespan, coordinations, warnings), from which the world builds
  the same result as the in-process simulator.

Like :mod:`ost_ros.messages`: frozen dataclasses with a ``TYPE`` tag; on the wire each is the
``ost_msgs`` interface of the same name (:mod:`ost_msgs_py.wire`).
Every message of a run carries the world's ``run`` id (random per run, kept across a world
restart): agents learn it from their first tick, and anything stamped with another run's id — a
stray publisher, a leftover node of an earlier run — is dropped with a warning.
"""

from __future__ import annotations

import array
import builtins
import itertools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, overload

from ost_ros.errors import OstError
from ost_ros.messages import (
    SCHEMA_VERSION,
    Action,
    ActionKind,
    AgentLost,
    AgentMessage,
    Cell,
    Observation,
    ScheduledObject,
)

RUNTIME_VERSION = 1


class ProtocolViolation(OstError):
    """A well-formed message that does not fit the run (unknown sender, wrong step, duplicate)."""


@dataclass(frozen=True)
class Ready:
    """Agent ``agent`` is ready: its node runs and all its endpoints are matched."""

    TYPE: ClassVar[str] = "ready"
    agent: int
    protocol: str
    scenario: str  # fingerprint of the scenario the agent loaded (must match the world's)
    organisation: str = "distributed"  # who coordinates (CCP): decides whether failures recover
    version: int = RUNTIME_VERSION


@dataclass(frozen=True)
class Tick:
    """World → agent: observe and act for step ``t``.

    ``failed``: the world's notice (:class:`~ost_ros.messages.AgentLost`) of every agent it
    has declared failed (it sent no action for the notice's step). The agent adds the notices of
    step ``last`` to that step's inbox, after the peers' messages (as the simulator).

    ``peers``: the agents that broadcast protocol messages in step ``last`` (the previous step the
    agent acted on itself); the agent first runs its comm module for ``last`` with exactly those
    batches. Steps ``last+1 .. t-1`` were skipped: the world executed the agent's own plan for them
    (event skipping) and the agent replays that plan locally.
    """

    TYPE: ClassVar[str] = "tick"
    t: int
    last: int
    observation: Observation
    peers: tuple[int, ...] = ()
    counts: tuple[int, ...] = ()  # how many messages each of ``peers`` broadcast in step ``last``
    run: str = ""  # the world's run id (strays of other runs are dropped)
    failed: tuple[AgentLost, ...] = ()  # every failure so far (the world's notices)
    version: int = RUNTIME_VERSION


@dataclass(frozen=True)
class PlanStep:
    """One step of an agent's plan: what it expects to observe and what it will then do.

    ``sensed`` is compared with the world's observation only when ``searching`` (other states
    never look at the sensor); ``position`` is always compared.
    """

    position: Cell
    searching: bool
    sensed: tuple[int, ...]
    kind: ActionKind
    direction: Cell
    object: int
    state: str


# ost_msgs/Plan's kind codes: WAIT=0, MOVE=1, CARRY=2
PLAN_KINDS = (ActionKind.WAIT, ActionKind.MOVE, ActionKind.CARRY)
PLAN_CODE = {k: n for n, k in enumerate(PLAN_KINDS)}


class PlanColumns(Sequence[PlanStep]):
    """A plan as parallel columns, as it travels (``ost_msgs/Plan``); a step is built only when
    it is read. The world reads each agent's plan only as far as it skips — at most the shortest
    plan of the team, often a small part of a 1 024-step one — so it never builds the rest.
    Equal to any sequence of the same :class:`PlanStep` s."""

    COLUMNS = ("x", "y", "searching", "sensed_count", "sensed", "kind", "dx", "dy", "object", "state")
    # array codes of the columns (searching and state are tuples)
    _CODES: ClassVar[dict[str, str]] = {
        "x": "i",
        "y": "i",
        "sensed_count": "H",
        "sensed": "i",
        "kind": "B",
        "dx": "b",
        "dy": "b",
        "object": "i",
    }
    __slots__ = (*COLUMNS, "_starts")

    x: array.array
    y: array.array
    searching: tuple[bool, ...]
    sensed_count: array.array
    sensed: array.array
    kind: array.array
    dx: array.array
    dy: array.array
    object: array.array
    state: tuple[str, ...]
    _starts: tuple[int, ...] | None

    def __init__(self, **columns: Iterable[Any]) -> None:
        for name in self.COLUMNS:
            value = columns[name]
            code = self._CODES.get(name)
            if code is None:
                value = tuple(map(bool, value)) if name == "searching" else tuple(value)
            elif not (isinstance(value, array.array) and value.typecode == code):
                value = array.array(code, value)
            object.__setattr__(self, name, value)
        # Each error names its column (the wire puts the message's field path before it).
        n = len(self.x)
        for name in self.COLUMNS:
            if name != "sensed" and len(getattr(self, name)) != n:
                raise ValueError(f"{name}: {len(getattr(self, name))} entries, x has {n}")
        if sum(self.sensed_count) != len(self.sensed):
            raise ValueError(f"sensed: {len(self.sensed)} ids, sensed_count says {sum(self.sensed_count)}")
        if max(self.kind, default=0) >= len(PLAN_KINDS):
            bad = next(i for i, code in enumerate(self.kind) if code >= len(PLAN_KINDS))
            raise ValueError(f"kind[{bad}]: {self.kind[bad]} is not one of 0 (wait), 1 (move), 2 (carry)")
        object.__setattr__(self, "_starts", None)

    @classmethod
    def of(cls, steps: Iterable[PlanStep]) -> PlanColumns:
        if isinstance(steps, PlanColumns):
            return steps
        steps = tuple(steps)
        return cls(
            x=[p.position[0] for p in steps],
            y=[p.position[1] for p in steps],
            searching=[p.searching for p in steps],
            sensed_count=[len(p.sensed) for p in steps],
            sensed=[i for p in steps for i in p.sensed],
            kind=[PLAN_CODE[p.kind] for p in steps],
            dx=[p.direction[0] for p in steps],
            dy=[p.direction[1] for p in steps],
            object=[p.object for p in steps],
            state=[p.state for p in steps],
        )

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("a plan is immutable")

    def __len__(self) -> int:
        return len(self.x)

    @overload
    def __getitem__(self, k: int) -> PlanStep: ...
    @overload
    def __getitem__(self, k: slice) -> tuple[PlanStep, ...]: ...
    def __getitem__(self, k: int | slice) -> PlanStep | tuple[PlanStep, ...]:
        if isinstance(k, slice):
            return tuple(self[i] for i in range(*k.indices(len(self))))
        if k < 0:
            k += len(self)
        return PlanStep(
            (self.x[k], self.y[k]),
            self.searching[k],
            self.sensed_at(k),
            PLAN_KINDS[self.kind[k]],
            (self.dx[k], self.dy[k]),
            self.object[k],
            self.state[k],
        )

    # Step k read column by column, without building its PlanStep (the world checks every
    # agent's plan at every step it skips; the agent replays its own).

    def position(self, k: int) -> Cell:
        return (self.x[k], self.y[k])

    def sensed_at(self, k: int) -> tuple[int, ...]:
        starts = self._starts
        if starts is None:  # where each step's sensed ids begin: once, when first read
            starts = (0, *itertools.accumulate(self.sensed_count))
            object.__setattr__(self, "_starts", starts)
        return tuple(self.sensed[starts[k] : starts[k + 1]])

    def action(self, agent: int, t: int, k: int) -> Action:
        """Step k's action, as ``agent`` takes it in step ``t``."""
        return _action(
            agent, t, PLAN_KINDS[self.kind[k]], (self.dx[k], self.dy[k]), self.object[k], self.state[k]
        )

    def same_action(self, k: int, action: Action) -> bool:
        """Whether ``action`` is step k's (whoever took it, whenever)."""
        return action.does(PLAN_KINDS[self.kind[k]], (self.dx[k], self.dy[k]), self.object[k], self.state[k])

    def _columns(self) -> tuple[Any, ...]:
        return tuple(getattr(self, name) for name in self.COLUMNS)

    def __eq__(self, other: builtins.object) -> bool:
        if isinstance(other, PlanColumns):
            return self._columns() == other._columns()
        if isinstance(other, Sequence) and not isinstance(other, str):
            return len(self) == len(other) and all(a == b for a, b in zip(self, other))
        return NotImplemented

    def __hash__(self) -> int:
        return hash(tuple(self))  # as the tuple of its steps (equal objects, equal hashes)

    def __repr__(self) -> str:
        return f"PlanColumns({len(self)} steps)"

    def __reduce__(self) -> tuple[Any, ...]:
        return _plan_columns, self._columns()


def _action(agent: int, t: int, kind: ActionKind, direction: Cell, obj: int, state: str) -> Action:
    """``Action(agent, t, kind, direction, obj, state)``, built in half the time: the world builds
    one per agent per step it skips (111 000 in the demo), and a frozen dataclass's ``__init__``
    sets each of its seven fields through ``object.__setattr__``. Filling the new instance's
    ``__dict__`` gives an equal object (same fields, same hash); Action has no ``__post_init__``
    to skip (tests/ost_msgs_py/test_plan_columns.py checks both)."""
    a = object.__new__(Action)
    a.__dict__.update(
        agent=agent, t=t, kind=kind, direction=direction, object=obj, state=state, version=SCHEMA_VERSION
    )
    return a


def _plan_columns(*columns: Any) -> PlanColumns:
    return PlanColumns(**dict(zip(PlanColumns.COLUMNS, columns)))


@dataclass(frozen=True)
class Acted:
    """Agent → world: the action of step ``action.t``.

    ``sent``: how many protocol messages the agent broadcast in that step (0: no batch is sent).
    ``plan``: the agent's actions for steps t+1, t+2, ... provided nobody broadcasts anything and
    its observations are as expected (empty when event skipping is off).
    """

    TYPE: ClassVar[str] = "acted"
    action: Action
    sent: int
    plan: Sequence[PlanStep] = ()  # a tuple, or PlanColumns as it comes off the wire
    run: str = ""  # the world's run id (strays of other runs are dropped)
    version: int = RUNTIME_VERSION


@dataclass(frozen=True)
class Sample:
    """One protocol message as it travels on its kind's topic (``/ost/<message TYPE>``).

    ``step``: the step the sender broadcast it in (a message's own ``t`` can be earlier: a
    coordination's selections); ``seq``: its place among everything the sender broadcast in that
    step (all kinds): the world's :class:`Tick` says how many that was, so a receiver knows when
    it has them all and puts them back in the sender's outbox order. ``run``: the world's run id.
    Without a barrier (realtime runs) ``step`` is the message's stamp, ``seq`` the sender's count
    of its messages and ``watermark`` the sender's watermark as it sent it (0 in lockstep).
    """

    message: AgentMessage
    step: int
    seq: int
    run: str = ""
    watermark: int = 0


@dataclass(frozen=True)
class Resend:
    """Agent → agents: a tick has waited too long for the step messages of ``peers`` for step
    ``t``; each of them publishes its batch of step ``t`` again (recovery from a lost sample)."""

    TYPE: ClassVar[str] = "resend"
    sender: int
    t: int
    peers: tuple[int, ...]
    run: str = ""  # the world's run id (strays of other runs are dropped)
    version: int = RUNTIME_VERSION


@dataclass(frozen=True)
class RunEnd:
    """The world stopped after ``steps`` steps. Like a :class:`Tick` for step ``steps`` without an
    observation: the agent finishes step ``last`` (comm module with ``peers``' batches), replays
    any skipped steps, then sends its :class:`AgentReport`."""

    TYPE: ClassVar[str] = "run_end"
    steps: int
    last: int
    completed: bool
    peers: tuple[int, ...] = ()
    counts: tuple[int, ...] = ()  # as in Tick
    run: str = ""  # the world's run id (strays of other runs are dropped)
    failed: tuple[AgentLost, ...] = ()  # as in Tick
    version: int = RUNTIME_VERSION


# One planned object of the global schedule (mirror of ``ost_ros.coordination.Assignment``):
# the same record a coordinator's ScheduleUpdate carries.
ScheduleEntry = ScheduledObject


@dataclass(frozen=True)
class AgentReport:
    """What an agent knows at the end of the run."""

    TYPE: ClassVar[str] = "agent_report"
    agent: int
    protocol: str
    trigger: str
    predicted_makespan: int | None
    coordinations: int
    schedule: tuple[ScheduleEntry, ...]
    found: tuple[tuple[int, int], ...]  # (object id, step found), in the agent's order
    warnings: tuple[str, ...]
    messages: int  # protocol messages this agent sent
    view: str = ""  # what agents must agree on (CCP: schedule, HCP: groups)
    run: str = ""  # the world's run id (strays of other runs are dropped)
    dropped: tuple[int, ...] = ()  # messages it dropped, by auth.REASONS: unsigned, forged, replayed, ...
    lag: float = -1.0  # realtime runs: the most a batch was taken after its stamp (steps); -1: lockstep
    version: int = RUNTIME_VERSION


@dataclass(frozen=True)
class RunInfo:
    """World → anyone (latched): the run's id, scenario and stepping rule — with the run's
    :class:`Ready`, :class:`Tick`, :class:`Acted` and :class:`AgentReport` messages enough to
    rebuild the run step by step without its nodes (``ost replay``, the live view)."""

    TYPE: ClassVar[str] = "run_info"
    run: str
    scenario: str  # the scenario as YAML (``dump_scenario``)
    fingerprint: str
    event_skipping: bool
    max_steps: int  # 0: the simulator's step limit
    version: int = RUNTIME_VERSION


RUNTIME_MESSAGES: tuple[type, ...] = (Ready, Tick, Acted, Resend, RunEnd, AgentReport, RunInfo)
