"""Watching real DDS runs: ``ost_up.sh --record`` (rosbag2-style MCAP), ``ost record info``,
``ost replay`` and the live Foxglove view (``--foxglove``), with real node processes."""

import json
import os
import pty
import socket
import subprocess
import sys
import threading

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import UP, ost_up, reference, result_json
from tests.ros.foxglove_client import collect, connect_when_up

OST = [sys.executable, "-m", "ost_ros"]
LOCKSTEP = {"acted", "run_info", "ready", "reports", "run_end", "result", "clock", "markers"}


def scenario_file(tmp_path, n=4, m=6, seed=1, w=40, h=16, nmax=3):
    scenario = generate_scenario(n, m, seed, Grid(w, h), nmax)
    path = tmp_path / "scenario.yaml"
    path.write_text(dump_scenario(scenario))
    return scenario, path


@pytest.mark.parametrize("protocol, kill", [("ccp", ()), ("hcp", ("--kill-agent", "2:60"))])
def test_a_recording_rebuilds_the_run(tmp_path, protocol, kill):
    scenario, path = scenario_file(tmp_path)
    bagfile = tmp_path / "run.mcap"
    run = ost_up(
        "--scenario", str(path), "--protocol", protocol, "--json", "--record", str(bagfile),
        "--run-dir", str(tmp_path / "run"), *kill,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "recording every topic of /ost" in run.stderr
    expected = result_json(run.stdout)
    if kill:
        assert [f["agent"] for f in expected["failures"]] == [2]
    else:
        assert expected == reference(scenario, protocol, CoordinationPolicy())

    # Every message decodes from the file's own schemas, without rclpy (mcap-ros2-support).
    with open(bagfile, "rb") as f:
        decoded = list(make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    topics = {m.channel.topic for m in decoded}
    assert {f"/ost/{t}" for t in LOCKSTEP} <= topics
    assert {f"/ost/agent_{a.id}/tick" for a in scenario.agents} <= topics
    assert all(m.schema.encoding == "ros2msg" and m.channel.message_encoding == "cdr" for m in decoded)
    recorded = [json.loads(m.decoded_message.data) for m in decoded if m.channel.topic == "/ost/result"]
    assert recorded == [expected]

    info = subprocess.run([*OST, "record", "info", str(bagfile), "--json"], capture_output=True, text=True)
    assert info.returncode == 0, info.stderr
    summary = json.loads(info.stdout)
    counts = {t["topic"]: t["count"] for t in summary["topics"]}
    assert summary["messages"] == len(decoded) == sum(counts.values())
    assert counts["/ost/run_info"] == 1 and counts["/ost/result"] == 1
    assert counts["/ost/acted"] >= len(scenario.agents)

    # The run rebuilt from the recording alone: the result the world published, byte for byte.
    gif = tmp_path / "replay.gif"
    replay = subprocess.run(
        [*OST, "replay", str(bagfile), "--json", "--animate", str(gif), "--plot", str(tmp_path / "t.png")],
        capture_output=True,
        text=True,
    )
    assert replay.returncode == 0, replay.stderr
    assert replay.stdout == run.stdout
    assert "identical to the result the world published" in replay.stderr
    assert gif.stat().st_size > 0 and (tmp_path / "t.png").stat().st_size > 0


def test_live_view_frames_are_the_worlds(tmp_path):
    scenario, path = scenario_file(tmp_path, 4, 8, 2, 100, 40, 3)
    truth: dict[int, list] = {0: [a.base for a in scenario.agents]}

    def positions(world, _actions):
        truth[world.t] = [world.positions[a.id] for a in scenario.agents]

    expected = simulate(scenario, "ccp", CoordinationPolicy(), on_step=positions, engine="step")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out: dict = {}
    up = threading.Thread(
        target=lambda: out.update(
            run=ost_up(
                "--scenario", str(path), "--json", "--foxglove", str(port), "--run-dir", str(tmp_path / "run")
            )
        )
    )
    up.start()
    try:
        connect_when_up(port)
        got = collect(port, ("/ost/robots", "/ost/scene"), seconds=120)
    finally:
        up.join(300)
    run = out["run"]
    assert run.returncode == 0, run.stderr
    assert result_json(run.stdout)["makespan"] == expected.makespan
    assert got.channels["/ost/scene"]["schemaName"] == "foxglove.SceneUpdate"
    assert got.channels["/ost/robots"]["schemaName"] == "ost.Robots"
    frames = [json.loads(m) for m in got.messages["/ost/robots"]]
    assert len({f["step"] for f in frames}) >= 2
    for f in frames:
        assert [(r["x"], r["y"]) for r in f["robots"]] == [tuple(p) for p in truth[f["step"]]]
    assert frames[-1]["step"] == expected.steps and frames[-1]["delivered"] == len(scenario.objects)
    assert len(got.messages["/ost/scene"]) >= 1 and all(got.messages["/ost/scene"])


def test_progress_line_on_a_terminal_only(tmp_path):
    _, path = scenario_file(tmp_path, 3, 4, 3, 30, 12, 2)
    env = dict(os.environ, OST_VENV=str(sys.prefix))
    env.pop("ROS_DOMAIN_ID", None)
    leader, follower = pty.openpty()
    chunks: list[bytes] = []

    def drain() -> None:  # read as it comes: a full pty buffer would block ost_up.sh
        while True:
            try:
                data = os.read(leader, 65536)
            except OSError:  # EIO: every writer has closed the terminal
                return
            if not data:
                return
            chunks.append(data)

    reader = threading.Thread(target=drain)
    reader.start()
    try:
        p = subprocess.run(
            ["bash", str(UP), "--scenario", str(path), "--run-dir", str(tmp_path / "tty")],
            stdout=subprocess.PIPE, stderr=follower, env=env, timeout=240,
        )  # fmt: skip
    finally:
        os.close(follower)
        reader.join(30)
        os.close(leader)
    assert p.returncode == 0
    tty = b"".join(chunks).decode(errors="replace")
    assert "ost up: step " in tty and "delivered 4/4" in tty
    quiet = ost_up("--scenario", str(path), "--run-dir", str(tmp_path / "pipe"))
    assert quiet.returncode == 0 and "delivered" not in quiet.stderr
