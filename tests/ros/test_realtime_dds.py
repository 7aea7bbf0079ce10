"""Realtime runs over DDS (``ost_up.sh --realtime``): one process per robot, no barrier, each robot
commanding its base through an action served by the world. Time is real here, so the tests assert
what the protocol promises — every object delivered by exactly its n_i robots, the same schedule on
every robot (0 disagreements, every final view alike), a failed robot recovered from — never exact
steps (those live in the in-process latency model, tests/ost_ros/realtime)."""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time

import pytest

from ost_ros.model import Grid
from ost_ros.realtime.run import REALTIME
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import (
    BIN,
    Processes,
    free_domain,
    kept_its_promise,
    ost_up,
    release_domain,
    result_json,
)

pytestmark = pytest.mark.dds


def _scenario(tmp_path, agents=4, objects=6, seed=1):
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(generate_scenario(agents, objects, seed, Grid(30, 12), 3)))
    return path


@pytest.mark.parametrize("protocol", [*REALTIME, "ccp-improved"])
def test_a_realtime_run_keeps_the_protocols_promise(tmp_path, protocol):
    path = _scenario(tmp_path)
    how = (
        ["--protocol", "ccp", "--planner", "improved"]
        if protocol == "ccp-improved"
        else ["--protocol", protocol]
    )
    run = ost_up(
        "--scenario", str(path), *how, "--realtime", "--rtf", "200",
        "--json", "--run-dir", str(tmp_path / "run"), "--timeout", "180",
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    result = result_json(run.stdout)
    kept_its_promise(result, 6)
    assert result["rtf"] == 200
    for a in result["agents"]:  # the record is the world's: every robot came home
        assert a["cost"] > 0


def test_the_improved_planner_delivers_everything_with_ten_robots(tmp_path):
    """Admitted without a barrier (docs/realtime.md, "What each protocol guarantees"): its gate
    holds a carry until the batches that could re-plan it are known, with ten robots at once.
    (Every protocol with four robots: above; with ten and more, in process:
    tests/ost_ros/realtime/test_run.py and benchmarks/bench_realtime.py.)"""
    how = ("--protocol", "ccp", "--planner", "improved")
    path = tmp_path / "scenario.yaml"
    scenario = generate_scenario(10, 12, 4, Grid(60, 20), 3)
    path.write_text(dump_scenario(scenario))
    run = ost_up(
        "--scenario", str(path), *how, "--realtime", "--rtf", "100",
        "--json", "--run-dir", str(tmp_path / "run"), "--timeout", "240",
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    result = result_json(run.stdout)
    kept_its_promise(result, 12)
    for o, spec in zip(result["objects"], scenario.objects):  # each by exactly its n_i robots
        assert len(o["agents"]) == spec.required


@pytest.mark.parametrize("monitor", ["node", "world"])
def test_a_robot_killed_mid_run_is_recovered_from(tmp_path, monitor):
    """Who declares it: the membership node ``ost up`` starts beside the world (the default), or
    the membership role in the world's own process (``--membership world``)."""
    path = _scenario(tmp_path, agents=5, objects=8, seed=2)
    run = ost_up(
        "--scenario", str(path), "--realtime", "--rtf", "50", "--kill-agent", "2:40",
        "--membership", monitor,
        "--json", "--run-dir", str(tmp_path / "run"), "--timeout", "180",
    )  # fmt: skip
    assert run.returncode in (0, 1), run.stderr[-3000:]
    result = result_json(run.stdout)
    assert [f["agent"] for f in result["failures"]] == [2]
    assert result["membership"]["monitor"] == monitor and result["membership"]["declared"] == 1
    assert result["membership"]["fanout"] == "monitor"  # (the default)
    who = "membership" if monitor == "node" else "world"
    assert "agent 2 out" in (tmp_path / "run" / f"{who}.log").read_text()
    assert ("membership node" in run.stderr) == (monitor == "node")
    assert result["disagreements"] == 0 and result["agreement"]
    movable = [o for o in result["objects"] if o["delivered"] is not None]
    # every object the four survivors can carry is delivered (n_i <= 3 here: all of them)
    assert len(movable) == 8, result.get("error")
    assert "agent_2" in run.stderr and "died mid-run" in run.stderr


def _run_prepared(tmp_path, edit, extra=None, options=(), late=None):
    """A prepared realtime run (``ost up --prepare``) started by the test, each process's command
    changed by ``edit(name, argv)``, ``extra`` processes beside it; ``late=(name, who, text)``
    starts process ``name`` only once ``who`` has logged ``text``. Its result and processes."""
    path = _scenario(tmp_path)
    run_dir = tmp_path / "run"
    # (--spawn exec: every process listed in `processes`, the test starting each as a shell does)
    prep = [str(BIN / "ost"), "up", "--prepare", "--scenario", str(path), "--realtime", "--rtf", "50",
            "--spawn", "exec", "--run-dir", str(run_dir), *options]  # fmt: skip
    subprocess.run(prep, check=True, capture_output=True)
    lines = [line.split("\t") for line in (run_dir / "processes").read_text().splitlines()]
    agents = [name for name, _host, _cmd in lines if name.startswith("agent_")]
    domain = free_domain()
    procs = Processes(run_dir, domain)
    try:
        for name, argv in (extra or (lambda _agents: {}))(agents).items():
            procs.run(name, argv)
        for name, _host, cmd in lines:
            if late is None or name != late[0]:
                procs.run(name, edit(name, shlex.split(cmd)))
        if late is not None:
            procs.wait_for(late[1], late[2], timeout=60)
            procs.run(late[0], edit(late[0], shlex.split(next(c for n, _h, c in lines if n == late[0]))))
        end = time.monotonic() + 180
        while not (run_dir / "result.json").exists():  # written whole (tmp + rename)
            assert procs.procs["world"].poll() is None, procs.log("world")[-3000:]
            assert time.monotonic() < end, (
                f"no result in 180 s; progress {(run_dir / 'progress').read_text()}"
            )
            time.sleep(0.2)
        result = json.loads((run_dir / "result.json").read_text())
    finally:
        procs.stop()
        release_domain(domain)
    return result, agents, procs


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (("--protocol", "hcp", "--join", "1:5"), "join: hcp takes no robot into the team"),
        (("--respawn-world", "1"), "--respawn-world: is for the lockstep run"),
    ],
)
def test_what_does_not_run_without_a_barrier_is_one_line(tmp_path, args, text):
    path = _scenario(tmp_path)
    run = ost_up("--scenario", str(path), "--realtime", *args, "--run-dir", str(tmp_path / "run"))
    assert run.returncode == 2
    assert text in run.stderr and len(run.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "run" / "world.pid").exists()


def test_lockstep_only_options_need_realtime(tmp_path):
    path = _scenario(tmp_path)
    run = ost_up("--scenario", str(path), "--rtf", "100", "--run-dir", str(tmp_path / "run"))
    assert run.returncode == 2 and "--rtf: needs --realtime" in run.stderr


# The bases' clock, relayed to one robot from 2 s (wall) after it first ticks, byte for byte: that
# robot starts late, after its peers have started and spoken.
LATE_CLOCK = r"""
import time, rclpy
from ost_msgs.msg import BaseClock
from ost_ros.node.transport import LOCKSTEP_QOS
rclpy.init()
node = rclpy.create_node("late_clock", namespace="/ost")
pub = node.create_publisher(BaseClock, "late_base_clock", LOCKSTEP_QOS)
first = []

def relay(data):
    first.append(time.monotonic()) if not first else None
    if time.monotonic() - first[0] >= 2.0:
        pub.publish(data)

node.create_subscription(BaseClock, "base_clock", relay, LOCKSTEP_QOS, raw=True)
rclpy.spin(node)
"""


# Membership messages that do not fit the team, on an insecure run (anyone may publish there):
# a Hello from a robot not on the team and one for a life older than robot 1's, again and again
# until the run's result is out.
STALE_HELLOS = r"""
import time, rclpy
from rclpy.qos import QoSProfile
from ost_msgs_py import wire
from ost_ros.node import realtime as rtp
from ost_ros.node.signing import node_auth
from ost_ros.node.transport import LOCKSTEP_QOS
from ost_ros.realtime.messages import Hello
rclpy.init()
node = rclpy.create_node("stale", namespace="/ost")
pub = node.create_publisher(wire.ros_type(Hello), rtp.HELLOS, LOCKSTEP_QOS)
guard = node_auth("", True, 9)
end = time.monotonic() + 120
while time.monotonic() < end:
    guard.publish(pub, Hello(9, 1, 0, (0, 0)), run="")
    guard.publish(pub, Hello(1, -1, 0, (0, 0)), run="")
    rclpy.spin_once(node, timeout_sec=0.5)
"""


def test_membership_messages_that_do_not_fit_the_team_are_dropped_and_named(tmp_path):
    """Bad input: a Hello from a robot not on the team, or for a life older than the robot's,
    is dropped with a throttled warning naming it (``stale``), counted; the run keeps every
    promise, nobody is readmitted or leaves because of it."""
    stale = {"stale": [sys.executable, "-c", STALE_HELLOS]}
    result, _agents, procs = _run_prepared(tmp_path, lambda _n, argv: argv, lambda _a: stale, ["--insecure"])
    kept_its_promise(result, 6)
    assert result["membership"]["rejoins"] == 0 and result["failures"] == []
    said = procs.log("membership") + procs.log("agent_0")
    assert "stale: a hello for agent 9, not on the team" in said
    assert "stale: a hello for life -1 of agent 1, whose life now is 0" in said
    assert "Traceback" not in said


def test_a_robot_that_starts_late_keeps_what_its_peers_said(tmp_path):
    """A robot starts on the bases' first clock message, which reaches robots at different
    times: what its peers say before it starts is kept for its start (dropped, a message or a
    watermark was lost for good and its batch never completed: 11 of 50 robots waited on one
    peer's first batch for the rest of a run). (An insecure run: a sealed clock is sealed for its
    own topic, and the relay moves it to another.)"""

    def late(name, argv):
        return [*argv, "-r", "/ost/base_clock:=/ost/late_base_clock"] if name == "agent_0" else argv

    relay = {"late_clock": [sys.executable, "-c", LATE_CLOCK]}
    result, _agents, _procs = _run_prepared(tmp_path, late, lambda _agents: relay, ["--insecure"])
    kept_its_promise(result, 6)
    assert max(result["lag"].values()) >= 50  # it did start late: a batch waited 2 s (100 steps) for it


@pytest.mark.parametrize(("fanout", "late"), [("direct", "agent_3"), ("monitor", "membership")])
def test_endpoints_whose_discovery_stopped_moving_are_renewed_and_carry_the_run(tmp_path, fanout, late):
    """Fast DDS now and then never pairs one writer with one reader (a team of 50 once waited
    for good on one robot's ``needs``): a robot creates anew the endpoints whose matching has not
    moved for ``rediscover_s`` before the start. Here a process a robot waits for is not up yet —
    a peer (``--fanout direct``: it reads its peers' topics) or the membership monitor
    (``--fanout monitor``: it reads no peer's, only the monitor's bundles) — so its matching stops
    moving; its renewed endpoints carry the run."""

    def quick(name, argv):
        return [*argv, "-p", "rediscover_s:=0.5"] if name.startswith("agent_") else argv

    result, _agents, procs = _run_prepared(
        tmp_path, quick, options=("--fanout", fanout), late=(late, "agent_0", "creating those endpoints anew")
    )
    kept_its_promise(result, 6)
    assert "Traceback" not in procs.log("agent_0")


def test_a_robot_killed_mid_search_leaves_no_find_unreported(tmp_path):
    """Robot 2 dies at 80, mid-search, while its base goes on sensing until the monitor declares
    it: a robot commits a time only once its base's events up to it are in, and a notice counts a
    dead robot's sensing up to its last watermark among its counted messages — nothing its base
    sensed is lost, nothing is counted twice. (Deaths at any moment, declared late, bases across
    a network: in process, benchmarks/realtime_digests.py's "remote" runs and
    tests/ost_ros/realtime/test_run.py.)"""
    when = 80
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(generate_scenario(6, 10, 919, Grid(120, 60), 3)))
    run = ost_up(
        "--scenario", str(path), "--protocol", "ccp", "--ci", "1", "--realtime", "--rtf", "50",
        "--kill-agent", f"2:{when}", "--json", "--run-dir", str(tmp_path / "run"), "--timeout", "240",
    )  # fmt: skip
    assert run.returncode in (0, 1), run.stderr[-3000:]
    result = result_json(run.stdout)
    assert [f["agent"] for f in result["failures"]] == [2]
    assert result["disagreements"] == 0 and result["agreement"]
    assert all(o["delivered"] is not None for o in result["objects"]), result.get("error")


def _wait_for(what, cond, timeout=120.0):
    """Poll ``cond`` until it holds (a condition of the run, never a fixed sleep)."""
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def _sim_time(run_dir):
    try:
        return float((run_dir / "progress").read_text().split()[0])
    except (OSError, IndexError, ValueError):
        return -1.0


def test_a_robot_stopped_for_5_s_is_declared_out_comes_back_and_works_again(tmp_path):
    """The run that lost a robot for good (SIGSTOP of robot 2 for 5 s at rtf 20: declared failed,
    it left and the run never ended): now it is declared out, asks back when it runs again, is
    readmitted by the team and given work; every object delivered, 0 disagreements."""
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(generate_scenario(6, 10, 919, Grid(120, 60), 3)))
    run_dir = tmp_path / "run"

    def stop_robot_2():
        _wait_for("sim time 100", lambda: _sim_time(run_dir) >= 100)
        pid = int((run_dir / "agent_2.pid").read_text())
        os.kill(pid, signal.SIGSTOP)
        try:
            time.sleep(5.0)  # the fault itself: 5 s without the robot (failure timeout 1 s)
        finally:
            os.kill(pid, signal.SIGCONT)

    run = ost_up(
        "--scenario", str(path), "--realtime", "--rtf", "20", "--json",
        "--run-dir", str(run_dir), "--timeout", "300", during=stop_robot_2, timeout=320,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    result = result_json(run.stdout)
    kept_its_promise(result, 10)
    m = result["membership"]
    assert m["declared"] >= 1 and m["rejoins"] == m["declared"] and m["out_at_end"] == []
    assert result["failures"] == []  # nobody left
    back = max(t for kind, a, t in m["events"] if kind == "back" and a == 2)
    assert any(2 in o["agents"] and o["start"] > back for o in result["objects"])  # it works again


def test_a_robot_that_joins_mid_run_is_given_work(tmp_path):
    """``--join 2:T`` with ``--fanout direct`` (through the monitor: the next test): robot 2's
    process is started by the supervisor once the run's sim time reaches T; the monitor counted it
    out from the start, it asks to come in as a robot declared out does, its peers say
    everything again to its new readers — and the monitor says a dead robot's (robot 4, killed
    before the join: the one who joins awaits no peer, dead or alive) — and the team gives it
    work. Every object delivered, 0 disagreements, nobody else out."""
    join, kill = 150, 60
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(generate_scenario(6, 10, 919, Grid(120, 60), 3)))
    run_dir = tmp_path / "run"
    faults = ["--kill-agent", f"4:{kill}"] if kill else []
    run = ost_up(
        "--scenario", str(path), "--realtime", "--rtf", "20", "--join", f"2:{join}", *faults,
        "--fanout", "direct", "--json",
        "--run-dir", str(run_dir), "--timeout", "300", timeout=320,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    assert "agent_2 joins: its process started at sim time" in run.stderr
    result = result_json(run.stdout)
    kept_its_promise(result, 10, dead=(4,) if kill else ())
    m = result["membership"]
    [joined] = m["joins"]
    assert joined["agent"] == 2 and joined["at"] == join and joined["started"] >= join
    assert m["declared"] == 1 + bool(kill) and m["rejoins"] == 1
    assert m["out_at_end"] == ([4] if kill else [])
    assert [f["agent"] for f in result["failures"]] == ([4] if kill else [])
    back = max(t for kind, a, t in m["events"] if kind == "back" and a == 2)
    assert back >= joined["started"]
    assert any(2 in o["agents"] and o["start"] > back for o in result["objects"])  # it works
    said = (run_dir / "membership.log").read_text()
    assert "agent 2 out (joins later)" in said
    assert "replayed" not in said  # the copies said again to the new robot: skipped, not warned
    for name in ("membership", "world", "agent_0", "agent_2"):
        assert "Traceback" not in (run_dir / f"{name}.log").read_text()


def test_a_team_whose_messages_go_through_the_monitor_keeps_every_promise(tmp_path):
    """``--fanout monitor``: every robot's messages, watermarks and needs go to the membership
    monitor alone, which passes them on in bundles (docs/realtime.md, "Fan-out through the
    monitor"). The hardest run of the direct fan-out: robot 4 killed at 60 (its originals go out
    again in bundles with its notice) and robot 2 joining at 150 (it reads no peer's topic: the
    monitor says everything again to its new reader). Every object delivered, 0 disagreements,
    the robots' own topics read by the monitor alone, no copy warned about."""
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(generate_scenario(6, 10, 919, Grid(120, 60), 3)))
    run_dir = tmp_path / "run"
    run = ost_up(
        "--scenario", str(path), "--realtime", "--rtf", "20", "--join", "2:150", "--kill-agent", "4:60",
        "--fanout", "monitor", "--json", "--run-dir", str(run_dir), "--timeout", "300", timeout=320,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    result = result_json(run.stdout)
    kept_its_promise(result, 10, dead=(4,))
    m = result["membership"]
    assert m["fanout"] == "monitor" and m["rejoins"] == 1 and m["out_at_end"] == [4]
    back = max(t for kind, a, t in m["events"] if kind == "back" and a == 2)
    assert any(2 in o["agents"] and o["start"] > back for o in result["objects"])  # it works
    said = (run_dir / "membership.log").read_text()
    passed = re.search(r"passed on (\d+) messages in (\d+) bundles", said)
    assert passed is not None, said[-2000:]
    assert int(passed[1]) > int(passed[2]) > 0
    profile = (run_dir / "fastdds.xml").read_text()
    assert "/ost/bundles" in profile and "/ost/selection" not in profile  # robots read bundles
    for name in ("membership", "world", "agent_0", "agent_2"):
        text = (run_dir / f"{name}.log").read_text()
        assert "Traceback" not in text and "replayed" not in text and "dropped" not in text, name


def test_a_team_whose_world_has_no_membership_role_runs_with_a_membership_node(tmp_path):
    """``membership:=node`` (the default): the world serves bases, sensing and the clock only; a
    ``membership_node`` process of its own (the world's settings, its own key) watches
    liveliness, commits and declares — a robot killed mid-run here. Started by hand from what
    ``ost up --prepare`` lists, as a deployment would. The run keeps every promise of today's
    runs."""
    path = _scenario(tmp_path, agents=5, objects=8, seed=2)
    run_dir = tmp_path / "run"
    prep = [str(BIN / "ost"), "up", "--prepare", "--scenario", str(path), "--realtime", "--rtf", "50",
            "--spawn", "exec", "--run-dir", str(run_dir)]  # fmt: skip
    subprocess.run(prep, check=True, capture_output=True)
    lines = [line.split("\t") for line in (run_dir / "processes").read_text().splitlines()]
    domain = free_domain()
    procs = Processes(run_dir, domain)
    assert [name for name, _host, _cmd in lines][:2] == ["world", "membership"]
    assert "membership_node --ros-args" in next(cmd for name, _host, cmd in lines if name == "membership")
    assert "membership: node" in (run_dir / "world.params.yaml").read_text()
    try:
        for name, _host, cmd in lines:
            argv = shlex.split(cmd)
            if name == "agent_1":
                argv += ["-p", "die_at_step:=60"]
            procs.run(name, argv)
        end = time.monotonic() + 180
        while not (run_dir / "result.json").exists():  # written whole (tmp + rename)
            assert procs.procs["world"].poll() is None, procs.log("world")[-3000:]
            assert time.monotonic() < end, procs.log("membership")[-3000:]
            time.sleep(0.2)
        result = json.loads((run_dir / "result.json").read_text())
        said = procs.log("membership")
    finally:
        procs.stop()
        release_domain(domain)
    assert result["membership"]["monitor"] == "node" and result["membership"]["declared"] == 1
    assert [f["agent"] for f in result["failures"]] == [1]
    assert result["disagreements"] == 0 and result["agreement"]
    assert all(o["delivered"] is not None for o in result["objects"]), result.get("error")
    assert "agent 1 out" in said
