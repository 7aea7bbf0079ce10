"""``ost up --prepare`` (what ost_up.sh calls first): the run directory from one run
configuration — scenario, keys, each node role's parameter file, the processes, the DDS
environment — and every refusal one line, exit code 2, nothing left behind. (Runs themselves:
tests/ros/test_bringup.py.)"""

import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from ost_msgs_py.auth import load_team
from ost_ros.cli import main as ost
from ost_ros.commands import bringup
from ost_ros.runconfig import AGENT, WORLD, of_node


def prepare(tmp_path: Path, *args: str) -> Path:
    assert ost(["up", "--prepare", "--run-dir", str(tmp_path / "run"), *args]) == 0
    return tmp_path / "run"


@pytest.fixture(autouse=True)
def _release_domains(monkeypatch, tmp_path):
    """Domain locks of these prepared-but-never-run directories go to a scratch place."""
    monkeypatch.setattr(bringup, "DOMAIN_LOCKS", tmp_path / "locks")


def test_the_run_directory_of_a_generated_scenario(tmp_path, capsys):
    d = prepare(tmp_path, "--agents", "4", "--objects", "6", "--seed", "2", "--width", "30", "--height", "12",
                "--nmax", "3", "--protocol", "ncp", "--ncp-delta", "0.5", "--kill-agent", "2:40",
                "--spawn", "exec")  # fmt: skip
    assert capsys.readouterr().out.strip() == str(d.resolve())
    ost(["generate", "--agents", "4", "--objects", "6", "--seed", "2", "--width", "30", "--height", "12",
         "--nmax", "3"])  # fmt: skip
    assert (d / "scenario.yaml").read_text() == capsys.readouterr().out  # `ost generate`'s scenario
    assert sorted(load_team(d / "keys").keys) == [-2, -1, 0, 1, 2, 3]  # the monitor, the world, every agent
    agent = yaml.safe_load((d / "agent.params.yaml").read_text())["/**"]["ros__parameters"]
    world = yaml.safe_load((d / "world.params.yaml").read_text())["/**"]["ros__parameters"]
    assert set(agent) == {s.name for s in of_node(AGENT)} and set(world) == {s.name for s in of_node(WORLD)}
    assert (agent["protocol"], agent["ncp_delta"], agent["keys"]) == ("ncp", 0.5, str(d.resolve() / "keys"))
    assert (world["result_file"], world["ready_file"]) == (
        str(d.resolve() / "result.json"),
        str(d.resolve() / "ready"),
    )
    lines = [line.split("\t") for line in (d / "processes").read_text().splitlines()]
    assert [name for name, _host, _cmd in lines] == ["world", "agent_0", "agent_1", "agent_2", "agent_3"]
    agent_2 = shlex.split(lines[3][2])
    assert agent_2[-4:] == ["-p", "agent_id:=2", "-p", "die_at_step:=40"]
    env = (d / "env.sh").read_text()
    assert "ROS_DOMAIN_ID=" in env and "fastdds_localhost_udp.xml" in env
    run = bringup.Run.load(d)
    assert run.ids == [0, 1, 2, 3] and run.config["ncp_delta"] == 0.5


def test_a_team_replaces_the_scenarios(tmp_path):
    ost(
        [
            "generate",
            "--agents",
            "3",
            "--objects",
            "4",
            "--seed",
            "1",
            "--nmax",
            "3",
            "-o",
            str(tmp_path / "s.yaml"),
        ]
    )
    d = prepare(tmp_path, "--scenario", str(tmp_path / "s.yaml"), "--agents", "5", "--protocol", "hcp")
    assert [p.name for p in bringup.Run.load(d).processes][-1] == "agent_4"
    world = yaml.safe_load((d / "world.params.yaml").read_text())["/**"]["ros__parameters"]
    assert world["agents"] == 5 and world["scenario"] == str((tmp_path / "s.yaml").resolve())


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["--agents", "4", "--objects", "4", "--protocol", "bogus"], "--protocol: 'bogus' is not one of"),
        (["--agents", "4", "--objects", "4", "--protocol", "hcp", "--coordination", "coordinator"],
         "--protocol: the coordinator organisation"),
        (["--scenario", "{missing}"], "--scenario: "),
        (["--scenario", "{bad}"], "invalid YAML at line"),
        (["--agents", "2", "--objects", "2", "--width", "0"], "--width: must be at least 1"),
        (["--agents", "2", "--objects", "2", "--ci", "0"], "--ci: must be at least 1"),
        (["--agents", "2", "--objects", "2", "--record", "x.bag"], "--record: 'x.bag' must end in .mcap"),
        (["--agents", "2", "--objects", "2", "--namespace", "a-b"], "--namespace: 'a-b' is not a ROS"),
        (["--agents", "2", "--objects", "2", "--bogus"], "unrecognized arguments: --bogus"),
        (["--agents", "4", "--objects", "4", "--split", "0,1/2,3:10:5"],
         "--split: needs --realtime and --hosts K"),
        (["--agents", "4", "--objects", "4", "--realtime", "--split", "0,1:10:5"],
         "--split: expected two groups or more"),
        (["--agents", "4", "--objects", "4", "--realtime", "--split", "0,1/1,2:10:5"],
         "--split: a robot in two groups"),
        (["--agents", "4", "--objects", "4", "--join", "2:50"], "--join: needs --realtime"),
        (["--agents", "4", "--objects", "4", "--fanout", "monitor"], "--fanout: needs --realtime"),
        (["--agents", "4", "--objects", "4", "--realtime", "--fanout", "all"], "--fanout: 'all' is not one of"),
        (["--agents", "4", "--objects", "4", "--realtime", "--hosts", "3", "--split", "0,1/2,3:10:5",
          "--fanout", "monitor"], "--split: cuts robots apart, not the monitor"),
        (["--agents", "4", "--objects", "4", "--discovery", "static"], "--discovery: needs --hosts K"),
        (["--agents", "4", "--objects", "4", "--nmax", "2", "--realtime", "--join", "2:50", "--join", "2:60"],
         "--join: agent 2 joins twice"),
        (["--agents", "4", "--objects", "4", "--realtime", "--join", "2"], "--join: expected AGENT:STEP"),
        (["--agents", "4", "--objects", "4", "--nmax", "2", "--realtime", "--join", "7:50"],
         "--join: agent 7 is not in the team [0, 1, 2, 3]"),
        (["--agents", "4", "--objects", "4", "--nmax", "2", "--realtime", "--join", "2:0"],
         "--join: agent 2 at sim time 0"),
        (["--agents", "4", "--objects", "4", "--nmax", "2", "--realtime", "--join", "2:50", "--kill-agent",
          "2:80"],
         "--join: agent 2 both joins and is killed"),
        (["--agents", "2", "--objects", "4", "--nmax", "2", "--realtime", "--join", "0:50", "--join", "1:60"],
         "--join: every robot would join later"),
    ],
)  # fmt: skip
def test_errors_are_one_line_exit_2_and_leave_nothing(tmp_path, capsys, args, text):
    (tmp_path / "bad.yaml").write_text("grid: {width: 3\nobjects: [")
    paths = {"missing": str(tmp_path / "none.yaml"), "bad": str(tmp_path / "bad.yaml")}
    assert exit_code(["up", "--prepare", *(a.format(**paths) for a in args)]) == 2
    err = capsys.readouterr()
    assert text in err.err and len(err.err.strip().splitlines()) == 1 and not err.out
    assert not list((tmp_path / "locks").glob("*"))  # no domain kept


def test_a_robot_that_joins_is_started_by_the_supervisor_not_the_script(tmp_path):
    """``--join 2:50``: robot 2's process is not in ``processes`` (what ost_up.sh starts at once)
    but in run.json with the sim time it starts at; world and agents are told who joins."""
    d = tmp_path / "run"
    assert ost(["up", "--prepare", "--agents", "4", "--objects", "4", "--nmax", "2", "--realtime",
                "--join", "2:50", "--spawn", "exec", "--run-dir", str(d)]) == 0  # fmt: skip
    names = [line.split("\t")[0] for line in (d / "processes").read_text().splitlines()]
    assert "agent_2" not in names and "agent_3" in names
    run = bringup.Run.load(d)
    assert [(p.name, p.at) for p in run.processes if p.at >= 0] == [("agent_2", 50)]
    assert len(run.agents) == 4
    for role in ("world", "agent"):
        assert "joins: '2:50'" in (d / f"{role}.params.yaml").read_text()
    assert ost(["up", "--down", str(d)]) == 0


@pytest.mark.parametrize(
    "spawn, listed", [("fork", ["world"]), ("exec", ["world", "agent_0", "agent_1", "agent_2"])]
)
def test_robots_the_supervisor_forks_are_not_the_scripts(tmp_path, spawn, listed):
    """``--spawn fork`` (the default): the script starts the world, the supervisor forks the
    robots (ost_ros/commands/spawn.py); ``--spawn exec``: the script starts every process."""
    d = tmp_path / "run"
    assert ost(["up", "--prepare", "--agents", "3", "--objects", "4", "--nmax", "2", "--spawn", spawn,
                "--run-dir", str(d)]) == 0  # fmt: skip
    names = [line.split("\t")[0] for line in (d / "processes").read_text().splitlines()]
    assert names == listed
    run = bringup.Run.load(d)
    assert [run.forked(p) for p in run.processes] == [False] + [spawn == "fork"] * 3
    assert ost(["up", "--down", str(d)]) == 0


def test_a_supervisor_with_threads_does_not_fork(tmp_path):
    """spawn.preload: a process forks robots only while it has one thread (a fork copies only
    the calling thread); it imports the robot's code without starting one."""
    code = (
        "import threading, time\n"
        "from ost_ros.commands import spawn\n"
        "print(spawn.preload(), spawn.threads())\n"
        "threading.Thread(target=time.sleep, args=(2,)).start()\n"
        "print(spawn.preload())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["True", "1", "False"]


def test_a_forked_robot_keeps_no_descriptor_of_its_supervisor_and_its_ignored_sighup(tmp_path):
    """spawn._become_robot: every descriptor above 2 becomes /dev/null (a caller reading the
    supervisor's pipe to its end gets the end), the log is its stdout and stderr, and a SIGHUP the
    supervisor ignored before it took the signals over stays ignored."""
    code = f"""
import os, signal, sys
signal.signal(signal.SIGHUP, signal.SIG_IGN)  # nohup, ost_up.sh --background
from ost_ros.commands import spawn
signal.signal(signal.SIGHUP, lambda *a: None)  # the supervisor's own
signal.signal(signal.SIGTERM, lambda *a: None)
r, w = os.pipe()
pid = os.fork()
if pid == 0:
    spawn._become_robot({{"OST_TEST_ENV": "1"}}, {str(tmp_path / "robot.log")!r})
    print(signal.getsignal(signal.SIGHUP) is signal.SIG_IGN, signal.getsignal(signal.SIGTERM) is signal.SIG_DFL,
          os.environ["OST_TEST_ENV"], os.path.samestat(os.fstat(w), os.stat(os.devnull)))
    sys.stdout.flush()
    os._exit(0)
os.close(w)
print("eof" if os.read(r, 1) == b"" else "data")
os.waitpid(pid, 0)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.split() == ["eof"]
    assert (tmp_path / "robot.log").read_text().split() == ["True", "True", "1", "True"]


def exit_code(argv: list[str]) -> int:
    """What ``ost ARGV`` exits with (argparse itself exits on a bad flag)."""
    try:
        return ost(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def test_a_refused_run_removes_the_directory_it_made(tmp_path, monkeypatch, capsys):
    made = []
    real = bringup.tempfile.mkdtemp

    def mkdtemp(**kw):
        made.append(real(dir=tmp_path, prefix="ost_run."))
        return made[-1]

    monkeypatch.setattr(bringup.tempfile, "mkdtemp", mkdtemp)
    assert ost(["up", "--prepare", "--scenario", str(tmp_path / "none.yaml")]) == 2
    assert made and not Path(made[0]).exists()


def test_yaml_loads_as_pyyaml_safe_load(tmp_path):
    from ost_ros.yamlload import safe_load

    ost(
        [
            "generate",
            "--agents",
            "3",
            "--objects",
            "5",
            "--seed",
            "4",
            "--nmax",
            "3",
            "-o",
            str(tmp_path / "s.yaml"),
        ]
    )
    text = (tmp_path / "s.yaml").read_text()
    assert safe_load(text) == yaml.safe_load(text)
    with pytest.raises(yaml.YAMLError):
        safe_load("a: !!python/object/apply:os.system ['true']")


@pytest.mark.skipif(os.geteuid() != 0, reason="simulated hosts need root (the split's checks come after)")
@pytest.mark.parametrize(
    ("split", "text"),
    [
        (["0,1/2,3:10:5"], "--split: needs --hosts 3 or more: the world's host and one per group"),
        (["0,1/2,9:10:5"], "--split: 0,1/2,9:10:5: no agents [9] (team [0, 1, 2, 3])"),
        (["0,1/2,3:10:5", "0,2/1,3:50:5"], "--split: 0,2/1,3:50:5: robots [0, 1] share a host"),
        (["0,1/2:10:5", "0,1/2,3:50:5"], "--split: 0,1/2,3:50:5: robots [3] share a host"),
    ],
)
def test_a_split_that_cannot_be_made_is_one_line(tmp_path, capsys, split, text):
    hosts = "2" if "needs --hosts" in text else "3"
    args = ["--agents", "4", "--objects", "4", "--nmax", "3", "--realtime", "--hosts", hosts]
    args += ["--fanout", "direct"]
    for s in split:
        args += ["--split", s]
    assert exit_code(["up", "--prepare", "--run-dir", str(tmp_path / "run"), *args]) == 2
    err = capsys.readouterr().err
    assert text in err and len(err.strip().splitlines()) == 1, err


@pytest.mark.skipif(os.geteuid() != 0, reason="simulated hosts need root")
def test_a_split_places_each_group_on_hosts_of_its_own(tmp_path):
    """Group g of the first split on host g + 1; a robot in no group with the world and the
    membership node on host 0 (it reaches everyone)."""
    d = prepare(tmp_path, "--agents", "5", "--objects", "4", "--nmax", "3", "--realtime", "--hosts", "3",
                "--split", "0,1/3:10:5", "--fanout", "direct")  # fmt: skip
    try:
        hosts = {
            line.split("\t")[0]: line.split("\t")[1] for line in (d / "processes").read_text().splitlines()
        }
        ns = hosts["world"].rsplit("_", 1)[0]
        assert hosts["world"] == hosts["membership"] == hosts["agent_2"] == hosts["agent_4"] == f"{ns}_h0"
        assert hosts["agent_0"] == hosts["agent_1"] == f"{ns}_h1" and hosts["agent_3"] == f"{ns}_h2"
    finally:
        assert ost(["up", "--down", str(d)]) == 0
