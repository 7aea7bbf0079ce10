"""What a cooperation protocol is to the rest of the system: the agent interface every engine
and node drives, and the spec the registry (:mod:`ost_ros.protocols`) holds for each protocol.

An agent touches the world only through :class:`~ost_ros.messages.Observation` in and
:class:`~ost_ros.messages.Action` out, and other agents only through messages; so the same
object runs in the step engine, the event engine and inside a ROS 2 node. Per step t:

1. ``act(obs)`` — sense, decide, move: this step's action;
2. ``outbox()`` — the messages this step produced (broadcast to every team mate);
3. ``communicate(t, messages)`` — every agent's messages of step t (its own included, the world's
   failure notices last), in the team's id order.

Engines and the DDS runtime skip steps in which nothing happens: ``plan`` describes the steps an
agent will take without a word (:mod:`ost_ros.protocols.plans`), ``skip`` tells it the event
engine took some. At the end, ``summary`` is what the agent knows (what the result reports and
what agents must agree on).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from ost_ros.coordination import Assignment, CoordinationPolicy
from ost_ros.errors import OstError
from ost_ros.messages import Action, AgentMessage, ObjectInfo, Observation
from ost_ros.model import Cell
from ost_ros.protocols.plans import Plan, Segment
from ost_ros.team import TeamInfo


class ProtocolError(OstError):
    """A protocol name or a combination of options the protocol cannot run (one line)."""


@dataclass(frozen=True)
class AgentSummary:
    """What an agent knows at the end of a run."""

    trigger: str  # the coordination trigger it ran (HCP: "help")
    predicted_makespan: int | None  # what its schedule predicted (None: no prediction)
    coordinations: int  # coordinations (or negotiations) it took part in
    schedule: tuple[Assignment, ...]  # the planned objects, in scheduling order
    found: Mapping[int, int]  # object id -> step it learnt of it
    warnings: tuple[str, ...]  # peers' messages it refused, and why
    view: str  # what all agents must hold alike (agreement)


class ProtocolAgent(Protocol):
    """One robot running a cooperation protocol (see the module docstring for the step order)."""

    id: int
    protocol: str

    def act(self, obs: Observation) -> Action:
        """Search and motion for step ``obs.t``: this step's action."""
        ...

    def outbox(self) -> list[AgentMessage]:
        """The messages produced since the last call."""
        ...

    def communicate(self, t: int, messages: Sequence[AgentMessage]) -> None:
        """The comm module for step ``t``: every message of the step."""
        ...

    def plan(self, t: int, position: Cell) -> Plan:
        """The steps from ``t`` on (standing at ``position``, its comm module done with step
        t-1) that it takes without a word, provided no message reaches it and its sensor shows
        nothing it reacts to. Empty: it decides something (and may speak) in step t."""
        ...

    def next_event(self, t: int) -> int | None:
        """The first step s >= t in which its comm module acts with no message (a coordination
        trigger, a negotiation round); None: nothing happens until a message comes."""
        ...

    def skip(self, t: int, position: Cell, segment: Segment, steps: int) -> None:
        """The event engine executed ``steps`` steps of ``segment`` (the first of its last plan,
        settled): it is now step ``t`` and the agent stands at ``position``."""
        ...

    def news(self, obj: ObjectInfo) -> bool:
        """Whether sensing ``obj`` makes the agent act differently (e.g. report a find)."""
        ...

    def group(self) -> int | None:
        """The object whose carrying group it has joined (going to it, holding or carrying)."""
        ...

    def departures(self) -> Mapping[int, int]:
        """Object id -> the step its carry starts, for carries the agent knows the start of (a
        sweeping agent then no longer expects to sense it where it lay)."""
        ...

    def summary(self) -> AgentSummary:
        """What it knows at the end of the run."""
        ...

    @property
    def warnings(self) -> list[str]: ...


@dataclass(frozen=True)
class Capabilities:
    """What a protocol supports beyond the paper's basic run (the registry checks requests)."""

    recovers_failures: bool = False  # survivors re-plan after a robot fails
    organisations: tuple[str, ...] = ("distributed",)  # who coordinates (paper §3)
    own_sweeps: bool = False  # robots with their own sweeps (negotiated areas)
    heterogeneous: bool = False  # robots slower than one cell per step
    triggers: bool = False  # the coordination triggers (CI, interval, area)
    team_knowledge: bool = False  # every agent holds the same public state: one comm
    # module (the spec's team_comm) computes the whole run (the analytic engine)


@dataclass(frozen=True)
class Option:
    """A protocol parameter: the field of its settings, the node parameter ``name``, the CLI
    flag ``--name`` (underscores as dashes)."""

    name: str
    field: str
    help: str

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")


@dataclass(frozen=True)
class ProtocolSpec:
    """One protocol, as the registry knows it."""

    name: str
    label: str  # a few words: "cost-balanced"
    title: str  # one line, for --help and listings
    make_agent: Callable[[int, TeamInfo, CoordinationPolicy, Any], ProtocolAgent]
    messages: tuple[type[AgentMessage], ...]  # the agent messages it broadcasts (over DDS: a topic each)
    states: tuple[str, ...]  # its global states, in FSA order
    capabilities: Capabilities = Capabilities()
    settings: type | None = None  # its settings dataclass (shared by the team)
    options: tuple[Option, ...] = ()  # the settings users may set
    team_comm: Callable[[TeamInfo, CoordinationPolicy, Any], Any] | None = None
    # with team_knowledge: the one comm module speaking for the whole team (analytic engine)
    silence: Callable[[Any, int], None] | None = None
    # fault injection (tests, demos): the agent sends no protocol moves from the given step on
    note: str = ""  # for reports: what it is, beside the paper

    def __post_init__(self) -> None:
        if self.capabilities.team_knowledge != (self.team_comm is not None):
            raise ProtocolError(f"{self.name}: team_knowledge and a team_comm go together")

    def default_settings(self) -> Any:
        return None if self.settings is None else self.settings()
