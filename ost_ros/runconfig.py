"""One run configuration for every way to start a team over DDS.

:data:`SETTINGS` names every choice a run makes, once: its name, type (the default's), default,
help, range or choices, and which nodes read it as a ROS parameter. Everything else is derived:

- each node's parameters (``ost_ros.node.params`` declares a node's settings read-only, with
  this description and range, and hands the values back here to be checked);
- the options of ``ost up`` and ``bringup_scripts/ost_up.sh`` and their ``--help``
  (``ost_ros.commands.up``);
- the arguments of ``launch/team.launch.py`` (the same names, as ``name:=value``);
- the parameters each process of a run gets (:meth:`RunConfig.parameters`) and the in-process
  lockstep the tests use (:meth:`RunConfig.policy`, :meth:`RunConfig.protocol_settings`).

A protocol's options come from the registry (:mod:`ost_ros.protocols`): a new protocol's options
are settings, flags, node parameters and launch arguments with no change here.

Settings a node never reads (the generator's ``objects``/``seed``, ``hosts``, ``background``, ...)
are bring-up options; node-only ones (``agent_id``, ``resume``, ...) have no option. A
:class:`ConfigError` names the setting it is about; the caller says it as a flag (``--ci``) or a
parameter (``ci``).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ost_ros import protocols
from ost_ros.coordination import ORGANISATIONS, CoordinationPolicy
from ost_ros.errors import UsageError
from ost_ros.model import DEFAULT_HEIGHT, DEFAULT_NMAX, DEFAULT_WIDTH
from ost_ros.protocols.shared.agent import PLAN_HORIZON
from ost_ros.realtime.net import parse_split
from ost_ros.realtime.topics import FANOUTS

# Node roles: the processes of a run that read settings as ROS parameters.
WORLD, AGENT, WATCH = "world", "agent", "watch"
INT_MAX = 2**31 - 1
# Liveliness lease (s) an agent offers and the world asks for: an agent whose liveliness is lost
# for it and then for as long again (with nothing heard from it) is declared failed by the world.
FAILURE_TIMEOUT_S = 1.0
# Endpoints whose matching has not moved for this long at start are created anew (s).
REDISCOVER_S = 15.0
# A realtime run's default pace: the demo's 11 240 steps in about 6 s of wall time.
RTF = 2000.0
# Quiet steps an agent plans ahead for event skipping (the protocols' plan horizon).
LOOKAHEAD = PLAN_HORIZON
NAMESPACE_RE = re.compile(r"^/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


class ConfigError(UsageError):
    """A bad setting; ``setting`` names it, the text says what is wrong with it."""

    def __init__(self, setting: str, text: str):
        super().__init__(text)
        self.setting = setting


@dataclass(frozen=True)
class Setting:
    """One choice of a run. Its type is its default's (a list: the option repeats)."""

    name: str
    default: Any
    help: str
    group: str  # the --help section: scenario, protocol, realtime, ROS, watch, run, faults
    nodes: tuple[str, ...] = ()  # the node roles that declare it as a ROS parameter
    lo: float | None = None  # inclusive range (nodes: the descriptor's range)
    hi: float | None = None
    choices: tuple[str, ...] = ()
    option: bool = True  # an option of ost up / ost_up.sh and an argument of the launch file
    flag: str = ""  # the option's spelling when it is not --name-with-dashes
    metavar: str = ""
    launch: str = ""  # why the launch file cannot do it ('': it can)
    parse: Callable[[str], Any] | None = None  # a value of its own syntax (AGENT:STEP)

    @property
    def type(self) -> type:
        return type(self.default)

    @property
    def cli(self) -> str:
        return self.flag or "--" + self.name.replace("_", "-")

    def describe(self) -> str:
        """The help line with its range or choices (a node parameter's description)."""
        return self.help


def agent_step_steps(text: str) -> tuple[int, int, int]:
    """AGENT:STEP:S (non-negative integers, S at least 1): a stall."""
    parts = text.split(":")
    if len(parts) != 3 or not all(p.isdigit() for p in parts) or int(parts[2]) < 1:
        raise ValueError(f"expected AGENT:STEP:S (S >= 1), got {text!r}")
    a, t, n = (int(p) for p in parts)
    return a, t, n


def agent_step(text: str) -> tuple[int, int]:
    """AGENT:STEP (non-negative integers)."""
    a, sep, s = text.partition(":")
    if not (sep and a.isdigit() and s.isdigit()):
        raise ValueError(f"expected AGENT:STEP, got {text!r}")
    return int(a), int(s)


def _protocol_settings() -> list[Setting]:
    """Every protocol's own options (the registry's), one setting each (shared names once)."""
    out: dict[str, Setting] = {}
    for spec in protocols.REGISTRY.values():
        for opt in spec.options:
            if opt.name in out:
                continue
            default = protocols.option_default(spec, opt)
            out[opt.name] = Setting(
                opt.name,
                default,
                f"{spec.name}: {opt.help}",
                "protocol",
                (AGENT,),
            )
    return list(out.values())


def _settings() -> tuple[Setting, ...]:
    S, W, A, X, WA = Setting, (WORLD,), (AGENT,), (WATCH,), (WORLD, AGENT)
    hosts_only = "simulated hosts are made by ost up / ost_up.sh"
    # fmt: off
    return (
        # ---------------------------------------------------------------- scenario
        S("scenario", "", "a scenario YAML (ost generate); every node of a run loads the same",
          "scenario", WA, metavar="FILE"),
        S("agents", 0, "team size (generating: required; with --scenario: replaces its team, 0 = keep)",
          "scenario", WA, 0, 100_000, metavar="N"),
        S("objects", 0, "generate the paper's random scenario with M objects", "scenario",
          lo=0, hi=1_000_000, metavar="M"),
        S("seed", 1, "its seed", "scenario", lo=0, hi=INT_MAX, metavar="S"),
        S("width", DEFAULT_WIDTH, "its grid width", "scenario", lo=1, hi=1_000_000, metavar="W"),
        S("height", DEFAULT_HEIGHT, "its grid height", "scenario", lo=1, hi=1_000_000, metavar="H"),
        S("nmax", DEFAULT_NMAX, "its largest group", "scenario", lo=1, hi=100_000, metavar="X"),
        S("partition", "equal", "search areas: equal, or negotiated first (by speed and zones)",
          "scenario", choices=("equal", "negotiated")),
        # ---------------------------------------------------------------- protocol
        S("protocol", "ccp", "cooperation protocol (ost protocols list)", "protocol", WA,
          choices=protocols.names()),
        S("ci", 1, "coordination trigger: coordinate after every ci-th found object", "protocol", A,
          1, INT_MAX, metavar="K"),
        S("interval", 0, "coordination trigger: every T steps instead (0: off)", "protocol", A,
          0, INT_MAX, metavar="T"),
        S("area_fraction", 0.0, "coordination trigger: per fraction f of the area searched (0: off)",
          "protocol", A, 0.0, 1.0, metavar="F"),
        S("coordination", "distributed", "who coordinates: every robot, or the lowest id alone",
          "protocol", WA, choices=ORGANISATIONS),
        *_protocol_settings(),
        S("event_skipping", True, "execute the agents' plans for quiet steps without a round trip",
          "protocol", W, flag="--no-skip"),
        S("max_steps", 0, "step limit (0: the simulator's)", "protocol", W, 0, INT_MAX, metavar="S"),
        S("lookahead", LOOKAHEAD, "quiet steps an agent plans ahead for event skipping (0: off)",
          "protocol", A, 0, 100_000, option=False),
        # ---------------------------------------------------------------- realtime
        S("realtime", False, "run without a barrier: robots move in sim time at --rtf, each commanding "
          "its base by an action, the same schedule kept by stamped messages (docs/realtime.md)",
          "realtime", WA),
        S("rtf", RTF, "real-time factor: steps (cells at unit speed) per wall second; 1 = a real robot's "
          "pace", "realtime", WA, 0.01, 1_000_000.0, metavar="R"),
        S("speed_jitter", 0.0, "each goal's time per cell times a seeded draw in [1, 1+X]", "realtime", W,
          0.0, 100.0, metavar="X"),
        S("stall", [], "robot AGENT stands still for S steps from step STEP (repeatable)", "realtime",
          metavar="AGENT:STEP:S", parse=agent_step_steps),
        S("stalls", "", "the stalls (AGENT:STEP:S, comma-separated)", "realtime", W, option=False),
        S("join", [], "robot AGENT is not in the team at the start: its process starts once the "
          "run's sim time reaches T, and it joins (repeatable)", "realtime", metavar="AGENT:T",
          parse=agent_step, launch="only ost up / ost_up.sh start a process late"),
        S("joins", "", "the robots that join mid-run (AGENT:T, comma-separated): not awaited at "
          "the start", "realtime", WA, option=False),
        S("noise_seed", 0, "seed of the speed noise", "realtime", W, 0, INT_MAX, metavar="S"),
        S("clock_hz", 50.0, "how often the world ticks (wall Hz): the bases' clock, at most 500 / team size", "realtime", W, 1.0,
          1000.0, metavar="HZ"),
        # ---------------------------------------------------------------- ROS
        S("namespace", "ost", "the run's namespace: two teams in two namespaces share a domain",
          "ROS", metavar="NS"),
        S("domain_id", -1, "ROS_DOMAIN_ID (-1: a free one in 10..99)", "ROS", lo=-1, hi=232,
          metavar="D", launch="the launch file runs in the caller's ROS_DOMAIN_ID"),
        S("executor", "events", "how the nodes wait for samples: rclpy's EventsExecutor, or "
          "SingleThreadedExecutor", "ROS", WA, choices=("events", "single")),
        S("insecure", False, "no signed messages (default: every message is signed with keys made "
          "for the run; receivers drop the rest)", "ROS", WA),
        S("keys", "", "the run's key directory (ost keys make; '': fresh keys for the run)", "ROS",
          WA, metavar="DIR"),
        S("failure_timeout", FAILURE_TIMEOUT_S, "liveliness lease (s): a silent agent fails after "
          "about 2 x this (0: off)", "ROS", WA, 0.0, 3600.0, metavar="SEC"),
        S("membership", "node", "realtime runs: who declares a silent robot out — node (a "
          "membership_node process of its own, started beside the world; the world has no "
          "membership role) or world (the role in the world's process)", "ROS", W,
          choices=("node", "world")),
        S("fanout", "monitor", "realtime runs: how a robot's messages reach its peers — monitor "
          "(to the membership monitor alone, which passes them on in bundles: N + N deliveries "
          "when every robot speaks) or direct (each sample to every peer: N x N)", "ROS", WA,
          choices=FANOUTS),
        S("spawn", "fork", "how ost up / ost_up.sh start the robots on this host: fork (the robot "
          "node's code imported once, a process forked per robot: a team of 50 comes up sooner) or "
          "exec (each from its executable, as on robots)", "ROS", choices=("fork", "exec"),
          launch="ros2 launch starts each process from its executable"),
        S("param_services", False, "the robots' nodes answer `ros2 param` (rclpy's parameter and "
          "type-description services: 14 DDS endpoints a robot that every process of the run "
          "discovers; off, a team of 50 comes up sooner)", "ROS", A),
        S("rediscover_s", REDISCOVER_S, "create anew the endpoints whose matching has not moved for "
          "this long at start (s)", "ROS", WA, 0.1, 3600.0, option=False),
        S("observers", 0, "readers beside the team (a recorder, a live view) the start waits for",
          "ROS", WA, 0, 16, option=False),
        # ---------------------------------------------------------------- watch
        S("record", "", "record every topic of the run (rosbag2-style MCAP; ost replay FILE)",
          "watch", X, metavar="FILE.mcap"),
        S("foxglove", 0, "live view: a Foxglove WebSocket server on ws://127.0.0.1:PORT (bare: 8765)",
          "watch", lo=0, hi=65535, metavar="PORT"),
        S("marker_every", 1, "publish markers every k ticks while subscribed (0: never)", "watch",
          W, 0, INT_MAX, option=False),
        S("foxglove_port", 0, "serve a Foxglove WebSocket live view on this port (0: none)",
          "watch", X, 0, 65535, option=False),
        S("foxglove_host", "127.0.0.1", "address the live view listens on", "watch", X, option=False),
        S("foxglove_rate", 20.0, "live view updates per second at most", "watch", X, 0.1, 1000.0,
          option=False),
        S("grace", 1.0, "seconds after the result for samples still on their way", "watch", X,
          0.0, 60.0, option=False),
        # ---------------------------------------------------------------- run
        S("run_dir", "", "logs, PIDs, parameters, keys and result.json (default: a new "
          "/tmp/ost_run.XXXXXX)", "run", metavar="DIR"),
        S("json", False, "print the result as `ost sim --json` does", "run",
          launch="the launch file writes the result to result_file"),
        S("background", False, "return once the run has started; the world keeps the result on "
          "<ns>/result until bringup_scripts/ost_down.sh DIR", "run",
          launch="ros2 launch runs in the foreground"),
        S("timeout", 0, "stop a run without a result after SEC seconds (0: never)", "run", lo=0,
          hi=INT_MAX, metavar="SEC", launch="ros2 launch has no time-out"),
        S("result_file", "", "also write the result JSON (as ost sim --json) there", "run", W,
          metavar="FILE"),
        S("progress_file", "", "write 'step delivered objects' there as the run goes ('': none)",
          "run", W, option=False),
        S("ready_file", "", "write the bring-up time there once every agent is matched and step 0 "
          "is sent ('': none)", "run", W, option=False),
        S("exit_when_done", True, "leave once the run is over (false: stay until stopped)", "run",
          (WORLD, WATCH), option=False),
        S("linger", 10.0, "with exit_when_done: seconds to wait at most for the agents to leave",
          "run", W, 0.0, 86_400.0, option=False),
        # ---------------------------------------------------------------- set per process
        S("agent_id", -1, "this robot's id in the scenario's team (-1: unset)", "run", A,
          -1, 1_000_000, option=False),
        S("checkpoint_file", "", "write the truth there before every step ('': none)", "run", W,
          option=False),
        S("resume", False, "start from checkpoint_file (a restarted world continues the run)",
          "run", W, option=False),
        S("die_at_step", -1, "fault injection: SIGKILL this process on the tick of this step "
          "(-1: never)", "faults", A, -1, INT_MAX, option=False),
        S("mute_negotiation_from", -1, "fault injection: no negotiation moves from this step on "
          "(-1: never)", "faults", A, -1, INT_MAX, option=False),
        # ---------------------------------------------------------------- faults
        S("kill_agent", [], "that agent's process SIGKILLs itself at that step (repeatable)",
          "faults", metavar="AGENT:STEP", parse=agent_step),
        S("mute_negotiation", "", "that NCP negotiator stops answering from that step", "faults",
          metavar="AGENT:STEP", parse=agent_step),
        S("respawn_world", 0, "restart a dead world node from its checkpoint (K times)", "faults",
          lo=0, hi=1000, metavar="K", launch="only ost up / ost_up.sh supervise the world"),
        S("hosts", 0, "(root) spread the processes over K simulated hosts (network namespaces)",
          "faults", lo=0, hi=64, metavar="K", launch=hosts_only),
        S("loss", 0, "with --hosts: packet loss on every host (%)", "faults", lo=0, hi=100,
          metavar="PCT", launch=hosts_only),
        S("discovery", "multicast", "with --hosts: how participants find each other", "faults",
          choices=("multicast", "static", "server"), launch=hosts_only),
        S("split", [], "with --realtime --hosts K: no traffic between groups of robots from sim "
          "time T for S wall seconds (each group on hosts of its own; the world's host, with the "
          "membership node, reaches every robot; repeatable)", "faults", metavar="GROUPS:T:S",
          launch=hosts_only, parse=parse_split),
    )
    # fmt: on


SETTINGS: tuple[Setting, ...] = _settings()
BY_NAME: dict[str, Setting] = {s.name: s for s in SETTINGS}


def of_node(role: str) -> list[Setting]:
    """The settings a node of ``role`` declares as ROS parameters."""
    return [s for s in SETTINGS if role in s.nodes]


def options() -> list[Setting]:
    """The options of ``ost up`` / ``ost_up.sh`` and the launch file's arguments."""
    return [s for s in SETTINGS if s.option]


def check_value(s: Setting, given: Any) -> Any:
    """``given`` as setting ``s`` takes it (a string is parsed), or a :class:`ConfigError`."""
    value: Any = given
    if isinstance(value, str) and s.type is not str:
        value = parse_text(s, value)
    if s.type is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if s.type is list:
        items = [str(x) for x in value]
        for x in items:
            if s.parse is not None:
                try:
                    s.parse(x)
                except ValueError as exc:
                    raise ConfigError(s.name, str(exc)) from None
        return items
    if not isinstance(value, s.type) or (s.type is int and isinstance(value, bool)):
        raise ConfigError(s.name, f"expected {s.type.__name__}, got {value!r}")
    if s.choices and value not in s.choices:
        raise ConfigError(s.name, f"{value!r} is not one of {', '.join(s.choices)}")
    if s.lo is not None and float(value) < s.lo:  # type: ignore[arg-type]  # a number: it has a range
        raise ConfigError(s.name, f"must be at least {_num(s.lo)}, got {value}")
    if s.hi is not None and float(value) > s.hi:  # type: ignore[arg-type]
        raise ConfigError(s.name, f"must be at most {_num(s.hi)}, got {value}")
    return value


def parse_text(s: Setting, text: str) -> Any:
    """A setting's value from text (an option, a launch argument)."""
    try:
        if s.parse is not None and s.type is not list:
            s.parse(text)  # its syntax checked; the text is the value
            return text
        if s.type is bool:
            low = text.strip().lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ConfigError(s.name, f"expected true or false, got {text!r}")
            return low in ("true", "1", "yes")
        if s.type is int:
            return int(text)
        if s.type is float:
            return float(text)
        if s.type is list:
            items = [x for x in re.split(r"[,\s]+", text.strip()) if x]
            for x in items:
                if s.parse is not None:
                    s.parse(x)
            return items
    except ConfigError:
        raise
    except ValueError as exc:
        raise ConfigError(s.name, str(exc) if s.parse else f"invalid {s.type.__name__} {text!r}") from None
    return text


def _num(x: float) -> str:
    return f"{x:g}"


@dataclass
class RunConfig:
    """A checked set of settings (defaults for the rest) and which of them were given."""

    values: dict[str, Any]
    given: frozenset[str] = field(default_factory=frozenset)

    @classmethod
    def of(cls, given: Mapping[str, Any] | None = None) -> RunConfig:
        """Settings by name (values or their text); unknown names and bad values are errors."""
        given = dict(given or {})
        values = {s.name: (list(s.default) if s.type is list else s.default) for s in SETTINGS}
        for name, value in given.items():
            s = BY_NAME.get(name)
            if s is None:
                raise ConfigError(name, f"unknown setting {name!r}")
            values[name] = check_value(s, value)
        cfg = cls(values, frozenset(given))
        cfg._check_protocol()
        return cfg

    def __getitem__(self, name: str) -> Any:
        return self.values[name]

    # ------------------------------------------------------------------ what the agents run

    def _check_protocol(self) -> None:
        if self["interval"] and self["area_fraction"]:
            raise ConfigError("interval", "choose one trigger: interval or area_fraction")
        for name in protocols.names():  # every protocol's options are valid values
            try:
                protocols.settings_from(name, self.values)
            except protocols.ProtocolError as exc:
                raise ConfigError("protocol", str(exc)) from None

    def policy(self) -> CoordinationPolicy:
        return CoordinationPolicy(
            ci=self["ci"],
            interval=self["interval"] or None,
            area_fraction=self["area_fraction"] or None,
            organisation=self["coordination"],
        )

    def protocol_settings(self) -> Any:
        return protocols.settings_from(self["protocol"], self.values)

    def check_protocol(self, scenario: Any = None) -> protocols.ProtocolSpec:
        """What the protocol can run, asked of the registry (the scenario's team, the
        organisation, a silenced negotiator, own sweeps) — and, with ``realtime``, whether it
        runs without a barrier."""
        silence = bool(self["mute_negotiation"]) or self["mute_negotiation_from"] >= 0
        try:
            spec = protocols.check(self["protocol"], scenario=scenario, policy=self.policy(), silence=silence)
            if self["realtime"]:
                from ost_ros.realtime.run import check_realtime

                check_realtime(self["protocol"], self.policy())
            return spec
        except protocols.ProtocolError as exc:
            raise ConfigError("protocol", str(exc)) from None

    def stalls(self) -> list[tuple[int, float, float]]:
        """The stalls (agent, from step, for steps), from the option or the world's parameter."""
        items = self["stall"] or [x for x in self["stalls"].split(",") if x.strip()]
        return [(a, float(t), float(n)) for a, t, n in map(agent_step_steps, items)]

    # ------------------------------------------------------------------ a whole run's checks

    def check_run(self, is_root: bool) -> None:
        """The checks of a bring-up (ost up, ost_up.sh, the launch file): one error each."""
        self._check_scenario()
        if not NAMESPACE_RE.match(self["namespace"]):
            raise ConfigError(
                "namespace", f"{self['namespace']!r} is not a ROS namespace (letters, digits, _ and /)"
            )
        if self["record"] and not self["record"].endswith(".mcap"):
            raise ConfigError("record", f"{self['record']!r} must end in .mcap")
        if self["split"]:
            if not (self["realtime"] and self["hosts"]):
                raise ConfigError("split", "needs --realtime and --hosts K (it cuts simulated hosts apart)")
            need = 1 + max(len(groups) for groups, _t, _s in self.splits())
            if self["hosts"] < need:
                raise ConfigError(
                    "split", f"needs --hosts {need} or more: the world's host and one per group"
                )
        if self["split"] and self["fanout"] == "monitor":
            raise ConfigError(
                "split",
                "cuts robots apart, not the monitor: with --fanout monitor their messages "
                "would go round it (use --fanout direct)",
            )
        if self["hosts"]:
            if not is_root:
                raise ConfigError("hosts", "simulated hosts need root (network namespaces)")
        elif self["loss"] or self["discovery"] != "multicast":
            raise ConfigError("loss" if self["loss"] else "discovery", "needs --hosts K")
        if self["keys"] and self["insecure"]:
            raise ConfigError("keys", "--keys and --insecure exclude each other")
        self._check_modes()
        self.check_protocol()

    def _check_scenario(self) -> None:
        if self["scenario"]:
            if self.given & {"objects", "seed", "width", "height", "nmax"}:
                raise ConfigError("", "--scenario excludes --objects/--seed (and the generator's sizes)")
        elif not (self["agents"] >= 1 and self["objects"] >= 1):
            raise ConfigError("", "give --agents N --objects M [--seed S], or --scenario FILE")
        if self["partition"] == "negotiated" and self["scenario"] and self["agents"]:
            raise ConfigError(
                "partition", "negotiated: --agents would replace the scenario's team; give a scenario with it"
            )

    def _check_modes(self) -> None:
        """Options of another protocol, or of the other mode (lockstep / realtime)."""
        spec = protocols.get(self["protocol"])
        for other in protocols.REGISTRY.values():
            for opt in other.options:
                if opt.name in self.given and opt not in spec.options:
                    raise ConfigError(opt.name, f"an option of {other.name}, not of {spec.name}")
        if self["realtime"]:
            for name in ("respawn_world", "foxglove", "mute_negotiation"):
                if self[name]:
                    raise ConfigError(name, "is for the lockstep run, not with --realtime")
            return
        named = name_given(
            self.given, ("rtf", "speed_jitter", "stall", "noise_seed", "clock_hz", "join", "fanout")
        )
        if named:
            raise ConfigError(named, "needs --realtime")

    # ------------------------------------------------------------------ per process

    @property
    def observers(self) -> int:
        """A recorder or live view: every node's start waits for it too."""
        return int(bool(self["record"] or self["foxglove"]))

    def splits(self) -> list[tuple[tuple[frozenset[int], ...], int, int]]:
        """The network partitions over simulated hosts: (groups, from sim time, for wall s)."""
        return [parse_split(x) for x in self["split"]]

    def joins(self) -> dict[int, int]:
        """The robots that join mid-run: agent -> the sim time its process starts at (from the
        option or the nodes' parameter)."""
        items = self["join"] or [x for x in self["joins"].split(",") if x.strip()]
        pairs = [agent_step(x) for x in items]
        twice = sorted({a for a, _ in pairs if sum(b == a for b, _ in pairs) > 1})
        if twice:
            raise ConfigError("join", f"agent {twice[0]} joins twice")
        return dict(pairs)

    def check_joins(self, team: list[int]) -> None:
        """--join against the team (once the scenario is known): one error each."""
        joins, kills = self.joins(), self.kills()
        if joins:
            from ost_ros.realtime.run import refused

            why = refused(self["protocol"], "join")
            if why:
                raise ConfigError("join", why)
        for a, t in sorted(joins.items()):
            if a not in team:
                raise ConfigError("join", f"agent {a} is not in the team {team}")
            if t <= 0:
                raise ConfigError(
                    "join", f"agent {a} at sim time {t}: must be > 0 (at 0 it is simply in the team)"
                )
            if a in kills:
                raise ConfigError("join", f"agent {a} both joins and is killed (--kill-agent)")
        if joins and len(joins) >= len(team):
            raise ConfigError("join", "every robot would join later: someone must start the run")

    def kills(self) -> dict[int, int]:
        return dict(agent_step(x) for x in self["kill_agent"])

    def mute(self) -> tuple[int, int] | None:
        return agent_step(self["mute_negotiation"]) if self["mute_negotiation"] else None

    def parameters(self, role: str, **node: Any) -> dict[str, Any]:
        """The ROS parameters of one process of the run: its role's settings as configured, with
        ``node`` (per-process values: agent_id, paths the bring-up chose) on top."""
        out = {s.name: self.values[s.name] for s in of_node(role)}
        if "observers" in out:
            out["observers"] = self.observers
        if role == AGENT:
            aid = node.get("agent_id", out["agent_id"])
            out["die_at_step"] = self.kills().get(aid, out["die_at_step"])
            mute = self.mute()
            if mute is not None and mute[0] == aid:
                out["mute_negotiation_from"] = mute[1]
        if role == WATCH:
            out["foxglove_port"] = self["foxglove"] or out["foxglove_port"]
        if role == WORLD and self["stall"]:
            out["stalls"] = ",".join(self["stall"])
        if role in (WORLD, AGENT) and self["join"]:
            out["joins"] = ",".join(self["join"])
        out.update(node)
        for name, value in out.items():
            check_value(BY_NAME[name], value)
        return out


def name_given(given: frozenset[str], names: tuple[str, ...]) -> str:
    """The first of ``names`` that was given ('' if none)."""
    return next((n for n in names if n in given), "")


def from_parameters(values: Mapping[str, Any]) -> RunConfig:
    """A node's configuration from its declared parameters (their values as rclpy read them)."""
    return RunConfig.of(values)


def names(settings: Iterable[Setting]) -> list[str]:
    return [s.name for s in settings]
