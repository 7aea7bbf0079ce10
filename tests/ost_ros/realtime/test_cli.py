"""``ost sim --latency`` as a user runs it: the realtime fields in JSON only, the lockstep JSON
untouched at latency 0, failures, noise and stalls as options, bad values in one line (exit 2)."""

import json
import subprocess
import sys

import pytest

OST = [sys.executable, "-m", "ost_ros"]


def ost(*args):
    return subprocess.run(OST + [str(a) for a in args], capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    path = tmp_path_factory.mktemp("rt") / "s.yaml"
    args = ("--agents", 4, "--objects", 6, "--seed", 1, "--width", 40, "--height", 20, "--nmax", 3)
    assert ost("generate", *args, "-o", path).returncode == 0
    return path


def test_latency_zero_adds_the_realtime_fields_to_ost_sims_json(scenario):
    plain = ost("sim", scenario, "--json")
    rt = ost("sim", scenario, "--latency", 0, "--json")
    assert plain.returncode == rt.returncode == 0, rt.stderr
    a, b = json.loads(plain.stdout), json.loads(rt.stdout)
    assert "mode" not in a  # the lockstep JSON keeps its bytes
    extra = {k: b.pop(k) for k in list(b) if k not in a}
    assert a == b
    assert extra["mode"] == "realtime" and extra["latency"] == [0, 0] and extra["disagreements"] == 0
    assert set(extra["lag"]) == {"0", "1", "2", "3"} and all(v == 0 for v in extra["lag"].values())


def test_a_run_with_latency_noise_stalls_and_a_failure(scenario):
    r = ost(
        "sim", scenario, "--latency", "8:12", "--latency-seed", 4, "--speed-jitter", 0.3,
        "--stall", "1:40:30", "--fail", "2:60", "--protocol", "ncp", "--json",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["completed"] and d["disagreements"] == 0 and d["latency"] == [8, 12]
    assert d["failures"] == [{"agent": 2, "step": 60}] and d["stalls"] == [[1, 40.0, 30.0]]
    assert max(d["lag"].values()) >= 8
    text = ost("sim", scenario, "--latency", "8:12", "--protocol", "auction")
    assert text.returncode == 0 and "disagreements 0 in" in text.stdout


@pytest.mark.parametrize("args", [("--planner", "improved"), ("--protocol", "greedy")])
def test_the_improved_planner_and_greedy_run_without_a_barrier(scenario, args):
    """Admitted: at latency 0 ``ost sim``'s run; under latency every object, 0 disagreements."""
    plain = json.loads(ost("sim", scenario, *args, "--json").stdout)
    rt = json.loads(ost("sim", scenario, *args, "--latency", 0, "--json").stdout)
    assert {k: v for k, v in rt.items() if k in plain} == plain
    r = ost("sim", scenario, *args, "--latency", "20:20", "--fail", "1:50", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["completed"] and d["disagreements"] == 0
    # bases across a network, as agent nodes have them
    r = ost("sim", scenario, *args, "--latency", "1:1", "--base-delay", "1:2", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["completed"] and d["disagreements"] == 0 and d["base_delay"] == [1, 2]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--latency", "x"), "expected L or L:J"),
        (("--latency", "-1"), "must be finite and ≥ 0"),
        (("--latency", "2:-1"), "must be finite and ≥ 0"),
        (("--stall", "1:2:3"), "--stall needs --latency"),
        (("--base-delay", "1"), "--base-delay needs --latency"),
        (("--latency", 1, "--base-delay", "1:x"), "expected L or L:J"),
        (("--latency", 1, "--stall", "1:2"), "expected AGENT:STEP:STEPS"),
        (("--latency", 1, "--stall", "9:2:3"), "no agent 9"),
        (("--latency", 1, "--speed-jitter", "-0.5"), "must be ≥ 0"),
        (("--latency", 1, "--protocol", "hcp", "--join", "1:5"), "--join: hcp takes no robot into the team"),
        (("--latency", 1, "--engine", "step"), "--engine is for the lockstep engines"),
        (("--latency", 1, "--animate", "x.avi"), "--animate: x.avi: unsupported format '.avi'"),
        (("--latency", 1, "--animate", "/nonexistent/x.gif"), "no such directory"),
        (("--latency", 1, "--plot", "/nonexistent/x.png"), "/nonexistent/x.png: cannot write"),
        (("--latency", 1, "--fail", "9:3"), "no such agent"),
    ],
)
def test_bad_values_are_one_line_errors(scenario, args, message):
    r = ost("sim", scenario, *args)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_a_robot_silent_past_the_timeout_and_one_that_joins(scenario):
    r = ost(
        "sim", scenario, "--latency", "4:4", "--silence", "1:30:60", "--join", "3:50",
        "--failure-timeout", 8, "--json",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    m = d["membership"]
    assert (m["declared"], m["rejoins"], m["out_at_end"], m["failure_timeout"]) == (2, 2, [], 8)
    assert d["completed"] and d["disagreements"] == 0 and d["failures"] == []
    text = ost("sim", scenario, "--latency", "4:4", "--join", "3:50")
    assert "membership      1 declared out (timeout 10 steps), 1 back, out at the end: none" in text.stdout


@pytest.mark.parametrize(
    "args, why",
    [
        (("--silence", "1:30:60"), "--silence needs --latency"),
        (("--latency", 1, "--join", "9:5"), "--join: no agent 9"),
        (("--latency", 1, "--join", "1:0"), "expected AGENT:STEP (≥ 0, ≥ 1)"),
        (("--latency", 1, "--join", "1:5", "--join", "1:9"), "--join: an agent can join only once"),
        (("--latency", 1, "--join", "1:5", "--fail", "1:9"), "--join: agent 1 also fails"),
        (("--latency", 1, "--failure-timeout", "-1"), "must be > 0"),
        (("--latency", 1, "--split", "0,1/1,2:5:5"), "a robot in two groups"),
        (("--latency", 1, "--split", "0,1:5:5"), "two groups or more"),
        (("--latency", 1, "--split", "0/9:5:5"), "--split: no agents [9]"),
        (("--latency", 1, "--split-mode", "lost"), "--split-mode needs --split"),
        (("--split", "0,1/2,3:5:5", "--split-mode", "lost"), "--split needs --latency"),
        (("--latency", 1, "--split", "0,1/2,3:5:5", "--split-mode", "gone"), "invalid choice: 'gone'"),
    ],
)
def test_bad_membership_flags_are_one_line(scenario, args, why):
    r = ost("sim", scenario, *args)
    assert r.returncode == 2 and why in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) <= 2, r.stderr


def test_a_partition_that_loses_what_crosses_it_heals_by_the_robots_saying_it_again(scenario):
    """``--split-mode lost``: copies between the groups are gone (as over DDS once a peer's lease
    ends); at the heal each robot says its messages and its watermark again, and asks again for
    the batch it waits for — the same schedule everywhere, every object delivered."""
    r = ost("sim", scenario, "--latency", "4:4", "--split", "0,1/2,3:20:80", "--split-mode", "lost", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["completed"] and d["disagreements"] == 0
    m = d["membership"]
    assert m["splits"] == [["0,1/2,3", 20, 80, "lost"]] and m["lost"] > 0 and m["held"] == 0
    text = ost("sim", scenario, "--latency", "4:4", "--split", "0,1/2,3:20:80", "--split-mode", "lost")
    assert f"partitions      1; {m['lost']} copies lost, said again when they healed" in text.stdout


def test_a_partition_holds_what_crosses_it_and_the_team_agrees_after_the_heal(scenario):
    r = ost("sim", scenario, "--latency", "4:4", "--split", "0,1/2,3:20:80", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["completed"] and d["disagreements"] == 0
    assert d["membership"]["splits"] == [["0,1/2,3", 20, 80]] and d["membership"]["held"] > 0


def test_the_plot_of_a_run_without_a_barrier_shows_who_was_out_when(scenario, tmp_path):
    from ost_ros.plot import Timeline

    png = tmp_path / "run.png"
    r = ost(
        "sim", scenario, "--latency", "4:4", "--silence", "1:30:60", "--split", "0,1/2,3:20:40", "--plot", png
    )
    assert r.returncode == 0, r.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    tl = Timeline.of_labels({1: [(0.0, "SEARCHING"), (38.5, "OUT"), (120.0, "DECISION")]}, 200.0)
    assert tl.runs[1] == [["SEARCHING", 0, 38], ["OUT", 39, 119], ["DECISION", 120, 199]]


def test_the_animation_of_a_run_without_a_barrier(scenario, tmp_path):
    """A frame every K steps plus every decision point (in the team too), as the recorder keeps
    them in process; the run's output is the same with or without it."""
    from PIL import Image

    from ost_ros.model import Grid
    from ost_ros.realtime.net import Latency, Split
    from ost_ros.realtime.run import run_realtime
    from ost_ros.scenario import load_scenario
    from ost_ros.watch.frames import RealtimeRecorder

    faults = ("--latency", "4:4", "--silence", "1:30:60", "--join", "3:50", "--split", "0,1/2,3:100:40")
    gif = tmp_path / "run.gif"
    r = ost("sim", scenario, *faults, "--json", "--animate", gif, "--every", 20)
    assert r.returncode == 0, r.stderr
    assert r.stdout == ost("sim", scenario, *faults, "--json").stdout  # watching changes nothing
    s = load_scenario(scenario)
    assert s.grid == Grid(40, 20)
    rec = RealtimeRecorder(s, every=20)
    run_realtime(
        s,
        latency=Latency(4, 4),
        silences=[(1, 30.0, 60.0)],
        joins={3: 50.0},
        splits=[Split((frozenset({0, 1}), frozenset({2, 3})), 100.0, 40.0)],
        observe=rec,
    )
    n = len(rec.finish())
    assert f"animation: {gif} ({n} frames" in r.stderr
    with Image.open(gif) as im:
        assert im.n_frames == n
    mp4 = ost("sim", scenario, "--latency", "4:4", "--animate", tmp_path / "run.mp4", "--every", 50)
    assert mp4.returncode == 0 and (tmp_path / "run.mp4").stat().st_size > 0, mp4.stderr
