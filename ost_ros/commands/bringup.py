"""A run over DDS prepared from its :class:`~ost_ros.runconfig.RunConfig`: what ``ost up``,
``bringup_scripts/ost_up.sh`` and ``launch/team.launch.py`` start, decided in one place.

:func:`prepare` makes the run directory — the scenario (generated, or the given file; negotiated
search areas if asked), the run's keys, one ROS parameter file per node role, a free
``ROS_DOMAIN_ID`` and the DDS environment (simulated hosts if asked) — and lists the processes:
the watch node (with ``--record``/``--foxglove``), the world node and one agent node per robot.
:meth:`Run.write` leaves it in the directory for a shell (``env.sh``, ``processes``: one line
per process, ``NAME<TAB>HOST<TAB>COMMAND``) and for the supervisor (``run.json``). The nodes
signal the run's progress by files: ``ready`` (the world: every agent matched, step 0 sent),
``progress`` (step, deliveries), ``result.json`` (the result, as ``ost sim --json``).
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import sys
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ost_ros.errors import UsageError
from ost_ros.runconfig import AGENT, SETTINGS, WATCH, WORLD, ConfigError, RunConfig

DDS_PROFILES = Path(__file__).resolve().parents[1] / "dds"  # the Fast DDS profiles (package data)
LOCALHOST_PROFILE = DDS_PROFILES / "fastdds_localhost_udp.xml"
HOSTS_PROFILE = DDS_PROFILES / "fastdds_hosts_udp.xml"
DOMAIN_LOCKS = Path(tempfile.gettempdir()) / "ost_domain_locks"
RUN_FILE, ENV_FILE, PROCESSES = "run.json", "env.sh", "processes"
PROFILE_FILE = "fastdds.xml"  # a realtime run's own Fast DDS profile (dds_profile)
READY, PROGRESS, RESULT = "ready", "progress", "result.json"
DISCOVERY_PORT = 11811
Say = Callable[[str], None]


def dds_env(environ: dict[str, str] | None = None) -> dict[str, str]:
    """How every OST process talks DDS on this host (docs/ros.md, "Transport"): UDP on the
    loopback interface through our Fast DDS profile; rmw_fastrtps switches shared memory back on
    under ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, so with the profile the range is SUBNET (a
    subnet that is the loopback interface alone). A profile of the user's own is kept, with the
    usual LOCALHOST default. (``bringup_scripts/dds_env.sh`` is the same for a shell.)"""
    env = dict(os.environ if environ is None else environ)
    mine = env.get("FASTRTPS_DEFAULT_PROFILES_FILE", "")
    if not mine or _ours(mine):
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(LOCALHOST_PROFILE)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    else:
        env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return env


@dataclass
class Process:
    """One process of the run."""

    name: str  # world, agent_3, watch, discovery_server
    executable: str  # world_node, agent_node, watch_node, fast-discovery-server
    role: str = ""  # the node role whose parameter file it loads ('': not a node)
    params: dict[str, Any] = field(default_factory=dict)  # its own parameters, on top of the file
    args: list[str] = field(default_factory=list)  # arguments of a process that is not a node
    host: int = 0  # the simulated host it runs on (--hosts)
    remaps: list[tuple[str, str]] = field(default_factory=list)  # ROS remappings (from, to)
    at: int = -1  # the run's sim time it starts at (--join; -1: with the run)

    def argv(self, run: Run) -> list[str]:
        exe = self.executable if os.path.isabs(self.executable) else str(run.bin_dir / self.executable)
        if not self.role:
            return [exe, *self.args]
        out = [exe, "--ros-args", "--params-file", str(run.params_file(self.role))]
        out += ["-r", f"__ns:=/{run.config['namespace'].strip('/')}"]
        for old, new in self.remaps:
            out += ["-r", f"{old}:={new}"]
        for name, value in self.params.items():
            out += ["-p", f"{name}:={_param_text(value)}"]
        return out


def _param_text(value: Any) -> str:
    """A parameter value as ``-p name:=value`` takes it (YAML)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)  # quoted: an empty or numeric-looking string stays a string
    return str(value)


@dataclass
class Run:
    """A prepared run: its directory, configuration, environment and processes."""

    dir: Path
    config: RunConfig
    bin_dir: Path
    ids: list[int]
    env: dict[str, str] = field(default_factory=dict)  # set for every process (DDS, domain)
    processes: list[Process] = field(default_factory=list)
    netns: str = ""  # the simulated hosts' name ('': none)
    domain_lock: str = ""  # the lock directory of the domain it took ('': given)
    made_dir: bool = False

    def params_file(self, role: str) -> Path:
        return self.dir / f"{role}.params.yaml"

    def file(self, name: str) -> Path:
        return self.dir / name

    def host_of(self, p: Process) -> str:
        """The namespace a process runs in ('': this host)."""
        from ost_ros.commands.hosts import host

        return host(self.netns, p.host % self.config["hosts"]) if self.netns else ""

    def forked(self, p: Process) -> bool:
        """Whether the supervisor forks it (``--spawn fork``: a robot on this host,
        :mod:`ost_ros.commands.spawn`) rather than a shell or itself starting its executable."""
        return p.executable == "agent_node" and self.config["spawn"] == "fork" and not self.host_of(p)

    def listed(self, p: Process) -> bool:
        """Whether ``processes`` lists it (what a shell starts): not one that joins later, nor
        one the supervisor forks."""
        return p.at < 0 and not self.forked(p)

    @property
    def agents(self) -> list[Process]:
        return [p for p in self.processes if p.executable == "agent_node"]

    def write(self) -> None:
        """The run as files: run.json (the supervisor's), env.sh and processes (a shell's)."""
        data = {
            "config": {k: self.config.values[k] for k in sorted(self.config.given | {"namespace"})},
            "bin_dir": str(self.bin_dir),
            "ids": self.ids,
            "env": self.env,
            "processes": [asdict(p) for p in self.processes],
            "netns": self.netns,
            "domain_lock": self.domain_lock,
        }
        self.file(RUN_FILE).write_text(json.dumps(data, indent=1) + "\n")
        self.file(ENV_FILE).write_text(
            "".join(f"export {k}={shlex.quote(v)}\n" for k, v in sorted(self.env.items()))
            + "".join(
                f"unset {k}\n" for k in ("ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER") if k not in self.env
            )
        )
        self.file(PROCESSES).write_text(
            "".join(
                f"{p.name}\t{self.host_of(p) or '-'}\t{shlex.join(p.argv(self))}\n"
                for p in self.processes
                if self.listed(p)  # (the supervisor starts the rest: joiners, robots it forks)
            )
        )

    @classmethod
    def load(cls, directory: str | Path) -> Run:
        d = Path(directory).resolve()
        try:
            data = json.loads((d / RUN_FILE).read_text())
        except (OSError, ValueError) as exc:
            raise UsageError(
                f"{d}: not a prepared run ({exc.__class__.__name__} reading {RUN_FILE})"
            ) from None
        return cls(
            d,
            RunConfig.of(data["config"]),
            Path(data["bin_dir"]),
            data["ids"],
            data["env"],
            [Process(**p) for p in data["processes"]],
            data["netns"],
            data["domain_lock"],
        )


def free_domain(owner: int) -> tuple[int, str]:
    """A ROS_DOMAIN_ID in 10..99 no other run of this machine holds: a lock directory taken
    atomically (mkdir); a dead owner's lock is taken over. Returns the id and the lock."""
    DOMAIN_LOCKS.mkdir(parents=True, exist_ok=True)
    start = int.from_bytes(os.urandom(2), "little") % 90
    for k in range(90):
        d = (start + k) % 90 + 10
        lock = DOMAIN_LOCKS / str(d)
        try:
            lock.mkdir()
        except FileExistsError:
            try:
                pid = int((lock / "pid").read_text())
                os.kill(pid, 0)
                continue  # held by a live run
            except (OSError, ValueError):
                shutil.rmtree(lock, ignore_errors=True)  # a dead run's: take it over
                try:
                    lock.mkdir()
                except FileExistsError:
                    continue
        (lock / "pid").write_text(f"{owner}\n")
        return d, str(lock)
    raise UsageError("no free ROS_DOMAIN_ID in 10..99 (set --domain-id)")


def _scenario(cfg: RunConfig, d: Path, say: Say) -> tuple[str, int]:
    """The scenario file every node loads, and the team-size override they apply (0: none)."""
    from ost_ros.model import Grid
    from ost_ros.scenario import ScenarioError, dump_scenario, generate_scenario, load_scenario, with_team

    try:
        if cfg["scenario"]:
            path, team = str(Path(cfg["scenario"]).resolve()), cfg["agents"]
            scenario = load_scenario(path)
            if team:
                scenario = with_team(scenario, team)
        else:
            grid = Grid(cfg["width"], cfg["height"])
            try:
                scenario = generate_scenario(cfg["agents"], cfg["objects"], cfg["seed"], grid, cfg["nmax"])
            except ScenarioError as exc:
                raise UsageError(f"cannot generate the scenario: {exc}") from None
            path, team = str(d / "scenario.yaml"), 0
            Path(path).write_text(dump_scenario(scenario))
        if cfg["partition"] == "negotiated":
            from ost_ros.negotiation.errors import NegotiationError
            from ost_ros.negotiation.partition import negotiated_scenario

            try:
                scenario, result = negotiated_scenario(
                    scenario, delta=0.95, seed=0, max_rounds=200, rule="patience"
                )
            except NegotiationError as exc:
                raise ConfigError("partition", str(exc)) from None
            path = str(d / "scenario_negotiated.yaml")
            Path(path).write_text(dump_scenario(scenario))
            say(f"search areas negotiated: {result.table().splitlines()[-1]}")
    except ScenarioError as exc:
        raise ConfigError("scenario", str(exc)) from None
    cfg.check_protocol(scenario)
    return path, team


def prepare(
    cfg: RunConfig, say: Say, bin_dir: Path | None = None, owner: int | None = None, launch: bool = False
) -> Run:
    """Make the run directory and decide the processes (see the module docstring). A refused
    run leaves nothing behind (no directory of its making, no domain lock, no hosts).
    ``launch``: for ``ros2 launch``, which starts the processes in its own environment (its
    ROS_DOMAIN_ID; no simulated hosts) and has no supervisor: the world writes ``result_file``."""
    cfg.check_run(is_root=os.geteuid() == 0)
    if launch:
        for s in SETTINGS:
            if s.launch and s.name in cfg.given and cfg[s.name] != s.default:
                raise ConfigError(s.name, f"not in the launch file: {s.launch}")
    bin_dir = bin_dir or Path(sys.executable).parent
    if not launch and not (bin_dir / "world_node").exists():
        raise UsageError(f"{bin_dir / 'world_node'} not found (run bringup_scripts/setup.sh)")
    if cfg["run_dir"]:
        d = Path(cfg["run_dir"])
        try:
            d.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError("run_dir", f"cannot create {d} ({exc.strerror})") from None
        if (d / "world.pid").exists():
            raise ConfigError("run_dir", f"{d} holds a run (ost_down.sh it first)")
        for name in (READY, PROGRESS, RESULT, "started", PROFILE_FILE):  # a past run's: not this one's
            (d / name).unlink(missing_ok=True)
        made = False
    else:
        d, made = Path(tempfile.mkdtemp(prefix="ost_run.", dir="/tmp")), True
    run = Run(d.resolve(), cfg, bin_dir, [], made_dir=made)
    try:
        _prepare(run, say, os.getppid() if owner is None else owner, launch)
    except BaseException:
        release(run)
        raise
    return run


def _prepare(run: Run, say: Say, owner: int, launch: bool) -> None:
    cfg, d = run.config, run.dir
    if cfg["record"] and not Path(cfg["record"]).resolve().parent.is_dir():
        raise ConfigError("record", f"no such directory {Path(cfg['record']).parent}")
    scenario_path, team = _scenario(cfg, d, say)
    from ost_ros.scenario import load_scenario, with_team

    scenario = load_scenario(scenario_path)
    run.ids = [a.id for a in (with_team(scenario, team) if team else scenario).agents]
    cfg.check_joins(run.ids)
    hosts = _split_hosts(cfg, run.ids)  # (before the hosts are made: a bad split costs nothing)
    keys = cfg["keys"]
    if not cfg["insecure"] and not keys:
        from ost_msgs_py.auth import make_keys

        keys = str(d / "keys")
        shutil.rmtree(keys, ignore_errors=True)
        try:
            make_keys(keys, run.ids)
        except OSError as exc:
            raise ConfigError("keys", f"{keys}: cannot write keys ({exc.strerror})") from None
    if not launch:
        _environment(run, owner)
    else:
        run.env = launch_env(run)
    # Each node role's parameters: the configuration's, with the run's files.
    stay = cfg["background"]
    common = {"scenario": scenario_path, "agents": team, "keys": keys}
    world = cfg.parameters(
        WORLD,
        **common,
        result_file=cfg["result_file"] if launch and cfg["result_file"] else str(d / RESULT),
        progress_file=str(d / PROGRESS),
        ready_file=str(d / READY),
        checkpoint_file=str(d / "world.checkpoint") if cfg["respawn_world"] else "",
        exit_when_done=not stay,
    )
    agent = cfg.parameters(AGENT, **common)
    files = {WORLD: world, AGENT: agent}
    if cfg.observers:
        record = str(Path(cfg["record"]).resolve()) if cfg["record"] else ""
        files[WATCH] = cfg.parameters(WATCH, record=record, exit_when_done=not stay)
        run.processes.append(Process("watch", "watch_node", WATCH))
    for role, params in files.items():
        run.params_file(role).write_text(
            yaml.safe_dump({"/**": {"ros__parameters": params}}, sort_keys=False)
        )
    run.processes.append(Process("world", "world_node", WORLD))
    if cfg["realtime"] and cfg["membership"] == "node":  # who is in the team: apart from the world
        run.processes.append(Process("membership", "membership_node", WORLD))
    for slot, i in enumerate(run.ids, start=1):
        own: dict[str, Any] = {"agent_id": i}
        for name in ("die_at_step", "mute_negotiation_from"):
            value = cfg.parameters(AGENT, agent_id=i)[name]
            if value != agent[name]:
                own[name] = value
        remaps = []
        if cfg["realtime"]:  # on the run's sim time: the world's clock of its namespace
            own["use_sim_time"] = True
            remaps = [("/clock", f"/{cfg['namespace'].strip('/')}/clock")]
        host = hosts.get(i, 0) if hosts else slot  # (split: a robot in no group with the world)
        at = cfg.joins().get(i, -1)
        run.processes.append(Process(f"agent_{i}", "agent_node", AGENT, own, host=host, remaps=remaps, at=at))
    if cfg["background"]:
        (d / "background").touch()


def _split_hosts(cfg: RunConfig, ids: list[int]) -> dict[int, int]:
    """With --split: each robot's simulated host — group g of the first split on host g + 1, a
    robot in no group on the world's host 0 (it reaches everyone) — checked against every split
    (a host's robots in one group; the team's robots only). Without: {} (robots spread)."""
    splits = cfg.splits()
    if not splits:
        return {}
    team = set(ids)
    groups, _t, _s = splits[0]
    hosts = {a: 1 + g for g, members in enumerate(groups) for a in members}
    for groups, t, s in splits:
        text = f"{'/'.join(','.join(map(str, sorted(g))) for g in groups)}:{t}:{s}"
        unknown = sorted(frozenset().union(*groups) - team)
        if unknown:
            raise ConfigError("split", f"{text}: no agents {unknown} (team {sorted(team)})")
        for h in {hosts.get(a, 0) for a in team}:
            on = {a for a in team if hosts.get(a, 0) == h}
            cut = [g for g in groups if g & on]
            if len(cut) > 1 or (h == 0 and cut):
                raise ConfigError(
                    "split", f"{text}: robots {sorted(on)} share a host (the first split's groups place them)"
                )
    return hosts


def _environment(run: Run, owner: int) -> None:
    """A free domain of its own and DDS on loopback (or on the simulated hosts)."""
    cfg = run.config
    full = dds_env()  # (a profile of the user's own is kept)
    keep = ("FASTRTPS_DEFAULT_PROFILES_FILE", "ROS_AUTOMATIC_DISCOVERY_RANGE")
    env: dict[str, str] = {k: full[k] for k in keep if k in full}
    domain = cfg["domain_id"]
    if domain < 0:
        domain, run.domain_lock = free_domain(owner)
    env["ROS_DOMAIN_ID"] = str(domain)
    if "FASTRTPS_DEFAULT_PROFILES_FILE" in env:
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = _run_profile(run, env["FASTRTPS_DEFAULT_PROFILES_FILE"])
    if cfg["hosts"]:
        from ost_ros.commands import hosts

        run.netns = f"ost{domain}"
        ips = hosts.up(run.netns, cfg["hosts"], net=domain, loss=cfg["loss"],
                       block_multicast=cfg["discovery"] != "multicast")  # fmt: skip
        if cfg["split"] and shutil.which("nft") is None:
            raise ConfigError("split", "nft not found (Debian package nftables): it cuts the hosts apart")
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(HOSTS_PROFILE)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
        if cfg["discovery"] == "static":
            env["ROS_STATIC_PEERS"] = ";".join(ips)
        elif cfg["discovery"] == "server":
            env["ROS_DISCOVERY_SERVER"] = f"{ips[0]}:{DISCOVERY_PORT}"
            run.processes.append(_discovery_server(run, ips[0], DISCOVERY_PORT))
    run.env = env


def _ours(profile: str) -> bool:
    """Whether ``profile`` is our loopback profile (the same file by any path to it)."""
    return bool(profile) and Path(profile).resolve() == LOCALHOST_PROFILE


def _run_profile(run: Run, profile: str) -> str:
    """The Fast DDS profile a run's processes load: a realtime run on this host with our loopback
    profile gets its own, what every robot reads on multicast (``dds_profile``; docs/ros.md,
    "Transport"); anything else keeps ``profile``."""
    cfg = run.config
    if not (cfg["realtime"] and not cfg["hosts"] and _ours(profile)):
        return profile
    from ost_ros.commands.dds_profile import write_realtime_profile

    path = run.file(PROFILE_FILE)
    write_realtime_profile(
        path, LOCALHOST_PROFILE, cfg["namespace"], cfg["protocol"], cfg["coordination"], cfg["fanout"]
    )
    return str(path)


def launch_env(run: Run) -> dict[str, str]:
    """What ``ros2 launch`` adds to its environment for a run's nodes: a realtime run's own
    profile when the caller loads our loopback profile (else nothing: its environment as it is)."""
    mine = os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", "")
    profile = _run_profile(run, mine)
    return {} if profile == mine else {"FASTRTPS_DEFAULT_PROFILES_FILE": profile}


def _discovery_server(run: Run, ip: str, port: int) -> Process:
    """A Fast DDS discovery server on the first host (--discovery server). The wheel's binary
    finds Fast DDS in the venv's lib/, its bundled libraries beside the wheel."""
    venv = run.bin_dir.parent
    libs = [str(venv / "lib"), *map(str, venv.glob("lib/python3*/site-packages/ros_fastrtps.libs"))]
    old = os.environ.get("LD_LIBRARY_PATH")
    path = f"LD_LIBRARY_PATH={':'.join(libs + ([old] if old else []))}"
    exe = str(run.bin_dir / "fast-discovery-server")
    args = [path, exe, "-i", "0", "-l", ip, "-p", str(port)]
    return Process("discovery_server", shutil.which("env") or "/usr/bin/env", args=args)


def release(run: Run) -> None:
    """Undo what preparing took: the simulated hosts, the domain lock, a directory of its making."""
    if run.netns:
        from ost_ros.commands import hosts

        hosts.down(run.netns)
        run.netns = ""
    if run.domain_lock:
        shutil.rmtree(run.domain_lock, ignore_errors=True)
        run.domain_lock = ""
    if run.made_dir:
        shutil.rmtree(run.dir, ignore_errors=True)
