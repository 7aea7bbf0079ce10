"""The ``ost`` command as a user runs it: real subprocesses, exit codes, one-line errors."""

import json
import subprocess
import sys

import pytest

from ost_ros import protocols

OST = [sys.executable, "-m", "ost_ros"]


def ost(*args, stdin=None):
    return subprocess.run(
        OST + [str(a) for a in args], capture_output=True, text=True, input=stdin, timeout=120
    )


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli") / "s.yaml"
    r = ost(
        "generate",
        "--agents",
        4,
        "--objects",
        6,
        "--seed",
        1,
        "--width",
        40,
        "--height",
        20,
        "--nmax",
        4,
        "-o",
        path,
    )
    assert r.returncode == 0, r.stderr
    return path


def test_help_lists_verbs():
    r = ost("--help")
    assert r.returncode == 0
    for verb in ("generate", "sim", "schedule"):
        assert verb in r.stdout
    for verb in ("generate", "sim", "schedule"):
        assert ost(verb, "--help").returncode == 0


def test_generate_is_reproducible(scenario):
    again = ost(
        "generate", "--agents", 4, "--objects", 6, "--seed", 1, "--width", 40, "--height", 20, "--nmax", 4
    )
    assert again.stdout == scenario.read_text()


def test_sim_json(scenario):
    r = ost("sim", scenario, "--ci", 2, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["completed"] and out["makespan"] == out["predicted_makespan"]
    assert {"makespan", "last_delivery", "agents", "objects"} <= set(out)
    assert set(out["agents"][0]) >= {"id", "cost", "idle", "carry"}
    assert set(out["objects"][0]) >= {"id", "agents", "start", "delivered"}
    assert max(a["cost"] for a in out["agents"]) == out["makespan"]
    assert max(o["delivered"] for o in out["objects"]) == out["last_delivery"]
    assert r.stdout == ost("sim", scenario, "--ci", 2, "--json").stdout  # deterministic


def test_sim_ncp(scenario):
    r = ost("sim", scenario, "--protocol", "ncp", "--ci", 6, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["protocol"] == "ncp" and out["completed"] and out["agreement"]
    assert out["makespan"] == out["predicted_makespan"]
    slower = json.loads(
        ost("sim", scenario, "--protocol", "ncp", "--ci", 6, "--ncp-delta", 0.95, "--json").stdout
    )
    assert slower["messages"] > out["messages"]  # a slower claim schedule takes more rounds


def test_sim_text_and_team_override(scenario):
    r = ost("sim", scenario, "--agents", 8)
    assert r.returncode == 0, r.stderr
    assert "makespan" in r.stdout and "completed" in r.stdout
    assert len([ln for ln in r.stdout.splitlines() if ln.strip()[:1].isdigit()]) == 8


def test_schedule(tmp_path):
    state = {
        "agents": [{"id": 0, "cost": 0, "location": [0, 0]}, {"id": 1, "cost": 5, "location": [10, 0]}],
        "objects": [
            {"id": 0, "location": [2, 0], "destination": [2, 3], "required": 1},
            {"id": 1, "location": [8, 0], "destination": [8, 1], "required": 2},
        ],
    }
    path = tmp_path / "state.json"
    path.write_text(json.dumps(state))
    r = ost("schedule", path, "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == {
        "schedule": [
            {"object": 0, "agents": [0], "start": 2, "finish": 5},
            {"object": 1, "agents": [0, 1], "start": 14, "finish": 15},
        ],
        "agents": [{"id": 0, "cost": 15, "location": [8, 1]}, {"id": 1, "cost": 15, "location": [8, 1]}],
    }
    assert ost("schedule", "-", stdin=json.dumps(state)).returncode == 0


BAD_YAML = {
    "malformed.yaml": ("grid: {width: 3\nobjects: [", "invalid YAML at line"),
    "unknown.yaml": (
        "grid: {width: 10, height: 5}\nagents: [{id: 0}]\nobjects: []\nspeed: 3\n",
        "unknown key 'speed'",
    ),
    "offgrid.yaml": (
        "grid: {width: 10, height: 5}\nagents: [{id: 0}]\n"
        "objects: [{id: 0, location: [12, 1], destination: [1, 1], required: 1}]\n",
        "objects[0].location: [12, 1] is off the 10x5 grid",
    ),
    "toomany.yaml": (
        "grid: {width: 10, height: 5}\nagents: [{id: 0}, {id: 1}]\n"
        "objects: [{id: 0, location: [2, 1], destination: [1, 1], required: 3}]\n",
        "nmax: 3 exceeds the team of 2 agents",
    ),
    "negative.yaml": (
        "grid: {width: -10, height: 5}\nagents: [{id: 0}]\nobjects: []\n",
        "grid.width: must be at least 1, got -10",
    ),
}


@pytest.mark.parametrize("name", sorted(BAD_YAML))
def test_bad_scenario_one_line_exit_2(tmp_path, name):
    text, needle = BAD_YAML[name]
    path = tmp_path / name
    path.write_text(text)
    r = ost("sim", path)
    assert r.returncode == 2
    assert needle in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "args,needle",
    [
        (["generate", "--agents", 10, "--objects", 5, "--seed", 1, "--width", -5], "--width"),
        (["generate", "--agents", 4, "--objects", 5, "--seed", 1], "nmax: 10 exceeds the team of 4"),
        (["generate", "--agents", 10, "--objects", "many", "--seed", 1], "--objects"),
        (["sim", "missing.yaml"], "missing.yaml: no such file"),
        (["sim", "x.yaml", "--ci", 0], "--ci"),
        (["sim", "x.yaml", "--ci", 2, "--interval", 5], "not allowed with"),
        (["sim", "x.yaml", "--protocol", "xyz"], "--protocol"),
        (
            ["sim", "x.yaml", "--protocol", "ncp", "--ncp-delta", 1],
            "--ncp-delta: NCP discount factor must be in (0, 1)",
        ),
        (["sim", "x.yaml", "--protocol", "ncp", "--ncp-delta", 0], "--ncp-delta"),
        (["sim", "x.yaml", "--protocol", "ncp", "--ncp-timeout", 0], "--ncp-timeout"),
        (["schedule", "missing.json"], "missing.json: no such file"),
        (["frobnicate"], "invalid choice"),
    ],
)
def test_bad_flags_one_line_exit_2(args, needle):
    r = ost(*args)
    assert r.returncode == 2
    assert needle in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "state,needle",
    [
        ("{", "invalid JSON"),
        ('{"agents": [], "objects": []}', "at least one agent"),
        (
            '{"agents": [{"id": 0, "cost": 0, "location": [0, 0]}], "objects": '
            '[{"id": 0, "location": [1, 1], "destination": [2, 2], "required": 2}]}',
            "exceeds the team",
        ),
        ('{"agents": [{"id": 0, "cost": -1, "location": [0, 0]}], "objects": []}', "agents[0].cost"),
        ('{"agents": [{"id": 0, "cost": 0, "where": [0, 0]}], "objects": []}', "unknown key 'where'"),
    ],
)
def test_bad_state_one_line_exit_2(state, needle):
    r = ost("schedule", "-", stdin=state)
    assert r.returncode == 2
    assert needle in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_sim_plot(scenario, tmp_path):
    png = tmp_path / "run.png"
    r = ost("sim", scenario, "--plot", png)
    assert r.returncode == 0, r.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    bad = ost("sim", scenario, "--plot", tmp_path / "no" / "such" / "dir.png")
    assert bad.returncode == 2 and "cannot write" in bad.stderr


def test_sim_with_a_failing_robot(scenario):
    r = ost("sim", scenario, "--json", "--agents", 5, "--fail", "1:30")  # 4 survive: nmax
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["failures"] == [{"agent": 1, "step": 30}] and d["completed"]
    assert d["agents"][1]["cost"] is None
    text = ost("sim", scenario, "--fail", "1:30").stdout  # 3 survive: some objects stay
    assert "failed          agent 1 in step 30" in text and "cannot be delivered" in text


@pytest.mark.parametrize(
    "args, text",
    [
        (["--fail", "9:3"], "no such agent"),
        (["--fail", "1:x"], "expected AGENT:STEP"),
        (["--fail", "1:3", "--fail", "1:5"], "only once"),
        (["--fail", "1:3", "--engine", "event"], "step engine"),
    ],
)
def test_sim_bad_failures_are_one_line(scenario, args, text):
    r = ost("sim", scenario, *args)
    assert r.returncode == 2 and text in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_faults_report_quick(tmp_path):
    out = tmp_path / "faults.md"
    r = ost("faults", "report", "--quick", "--out", out)
    assert r.returncode == 0, r.stderr
    assert "| scenario | fault | delivered / total |" in r.stdout
    assert "20/20" in r.stdout and "too few survivors" in r.stdout
    assert out.read_text().startswith("# Fault report")
    rows = json.loads(ost("faults", "report", "--quick", "--json").stdout)
    assert rows[0]["fault"] == "none" and rows[0]["overhead vs fault-free"] == "+0.0%"


def test_sim_coordinator_organisation(scenario):
    r = ost("sim", scenario, "--json", "--coordination", "coordinator")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["trigger"] == "CI=1, coordinator"
    for args, text in [
        (["--protocol", "hcp"], "for ccp only"),
        (["--engine", "event"], "step engine"),
    ]:
        bad = ost("sim", scenario, "--coordination", "coordinator", *args)
        assert bad.returncode == 2 and text in bad.stderr, bad.stderr
    # The organisation recovers from a failure like the others: the lowest survivor coordinates.
    r = ost("sim", scenario, "--json", "--coordination", "coordinator", "--agents", 5, "--fail", "0:30")
    assert r.returncode == 0 and json.loads(r.stdout)["completed"], r.stderr


@pytest.mark.parametrize(
    "protocol", [n for n, spec in protocols.REGISTRY.items() if spec.capabilities.recovers_failures]
)
def test_sim_every_protocol_recovers_from_a_failure(scenario, protocol):
    r = ost("sim", scenario, "--json", "--protocol", protocol, "--agents", 5, "--fail", "1:30")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["failures"] == [{"agent": 1, "step": 30}] and d["completed"]


def test_keys_make_and_show(scenario, tmp_path):
    r = ost("keys", "make", tmp_path / "k", "--scenario", scenario, "--run", "run1")
    assert (
        r.returncode == 0 and "keys for the world, the membership monitor and 4 agents, run run1" in r.stdout
    )
    assert sorted(p.name for p in (tmp_path / "k").iterdir()) == [
        "agent_0.key", "agent_1.key", "agent_2.key", "agent_3.key", "membership.key", "team.yaml", "world.key",
    ]  # fmt: skip
    shown = json.loads(ost("keys", "show", tmp_path / "k", "--json").stdout)
    assert shown["run"] == "run1" and sorted(shown["signers"]) == ["0", "1", "2", "3", "membership", "world"]


@pytest.mark.parametrize(
    "args, needle",
    [
        (["keys", "make", "K"], "give --scenario FILE or --agents N"),
        (["keys", "make", "K", "--agents", "0"], "--agents: 0 (must be at least 1)"),
        (["keys", "make", "K", "--agents", "2", "--run", "a/b"], "--run: 'a/b' (letters and digits only)"),
        (["keys", "show", "/nonexistent"], "/nonexistent/team.yaml: cannot read"),
    ],
)
def test_keys_bad_input_one_line_exit_2(tmp_path, args, needle):
    r = subprocess.run(OST + args, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert r.returncode == 2 and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
