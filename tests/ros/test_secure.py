"""Only the team's robots speak for the team: a foreign process attacks a secure run over DDS.

The intruder (tests/ros/intruder.py) sits on the run's domain before the run starts, knows the
run id (the world's public run_info) and holds one robot's real key (agent 1's, stolen). It
sends forged messages of every kind on every topic — unsealed, sealed with its own key, sealed
with agent 1's key as agent 1 while claiming another robot or the world, sealed with agent 1's
key in agent 2's (or the world's) name for every other receiver, sealed for another run — and
replays captured genuine messages, on their own topic and on another robot's. Every one is
dropped, counted in the run's transport stats and warned about naming topic and claimed sender;
the run's result is that of ``ost sim``. And a dead robot's message relayed byte for byte by
another process is accepted by every receiver (tests/ros/relay.py).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import pytest

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import make_keys, reference

pytestmark = pytest.mark.dds

INTRUDER = Path(__file__).with_name("intruder.py")
RELAY = Path(__file__).with_name("relay.py")


def wait_file(path: Path, procs, seconds: float = 120) -> None:
    end = time.monotonic() + seconds
    while not path.exists():
        assert time.monotonic() < end, procs.log("world")[-3000:]
        assert procs.procs["world"].poll() is None, procs.log("world")[-3000:]
        time.sleep(0.1)


def test_forged_and_replayed_messages_are_dropped_and_the_run_is_unchanged(tmp_path, procs):
    scenario = generate_scenario(3, 6, 2, Grid(40, 16), 2)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, "ccp", CoordinationPolicy())
    keys = make_keys(tmp_path, path)
    result = tmp_path / "result.json"
    common = ["-p", f"scenario:={path}", *keys]
    # every step a round trip: the run lasts long enough to be attacked throughout
    procs.start("world", "world_node", *common, "-p", f"result_file:={result}", "-p", "event_skipping:=false")
    for i in (0, 1):
        procs.start(f"agent_{i}", "agent_node", *common, "-p", f"agent_id:={i}")
    procs.wait_for("world", "waiting for 3 agents")
    procs.run(
        "intruder",
        [
            sys.executable,
            str(INTRUDER),
            "--agents",
            "0,1,2",
            "--stolen-key",
            str(tmp_path / "keys/agent_1.key"),
            "--team",
            str(tmp_path / "keys"),
        ],
    )
    procs.wait_for("intruder", "matched")
    # Before the run: a forged Ready for the missing agent 2 does not start the world.
    procs.wait_for("world", "dropped message on /ost/ready from agent 2: unsigned")
    procs.wait_for("world", "dropped message on /ost/ready from agent 2: forged")
    procs.wait_for("world", "dropped message on /ost/ready from agent 0: replayed")
    assert "agents ready" not in procs.log("world")
    procs.start("agent_2", "agent_node", *common, "-p", "agent_id:=2")
    wait_file(result, procs)
    assert json.loads(result.read_text()) == expected

    procs.procs["intruder"].wait(30)
    sent = json.loads(procs.log("intruder").strip().splitlines()[-1])
    sent.pop("refused by DDS", None)  # (a flood of keep-all samples: DDS may refuse some)
    assert set(sent) == {"unsigned", "own key", "stolen key, own id", "stolen key, other id",
                         "stolen key, other run", "replay", "replay, other topic"}, sent  # fmt: skip
    stats = json.loads(Path(f"{result}.transport.json").read_text())["auth"]
    assert stats["secure"] is True
    assert all(stats["dropped"][k] > 0 for k in ("unsigned", "forged", "replayed")), stats

    logs = {name: procs.log(name) for name in ("world", "agent_0", "agent_1", "agent_2")}
    everything = "\n".join(logs.values())
    # every topic a node of the run reads was attacked, and each receiver said so
    for topic, reader in [("acted", "world"), ("ready", "world"), ("reports", "world"),
                          ("agent_0/tick", "agent_0"), ("agent_1/tick", "agent_1"),
                          ("run_end", "agent_0"), ("resend", "agent_0"), ("object_found", "agent_0"),
                          ("selection", "agent_2"), ("search_done", "agent_0")]:  # fmt: skip
        assert f"dropped message on /ost/{topic} from " in logs[reader], (topic, reader)
    # agent 1's key cannot speak for the world or for agent 2, neither as itself nor in their names
    assert "/ost/agent_0/tick from the world: forged: sealed by agent 1, sent as the world" in logs["agent_0"]
    assert "from agent 2: forged: sealed by agent 1, sent as agent 2" in everything
    assert "/ost/agent_0/tick from the world: forged: the tag does not match" in logs["agent_0"]
    for topic in ("object_found", "selection"):  # agent 1's key makes agent 0 accept nothing of agent 2's
        assert f"/ost/{topic} from agent 2: forged: the tag does not match" in logs["agent_0"], topic
    assert "/ost/ready from agent 2: forged: the tag does not match" in logs["world"]
    # a tick sealed for agent 0 alone, moved to agent 1's topic
    assert "/ost/agent_1/tick from the world: forged: no tag for agent 1" in logs["agent_1"]
    assert "replayed: counter" in everything
    assert "Traceback" not in everything
    for i in (0, 1, 2):
        procs.procs[f"agent_{i}"].wait(30)
        assert procs.procs[f"agent_{i}"].returncode == 0, logs[f"agent_{i}"][-2000:]


def test_a_node_without_keys_refuses_to_start(tmp_path, procs):
    """Secure by default: no keys and no insecure:=true is one line naming the parameter."""
    scenario = generate_scenario(2, 2, 1, Grid(12, 6), 2)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    for exe, extra in (("world_node", []), ("agent_node", ["-p", "agent_id:=0"])):
        p = procs.start(exe, exe, "-p", f"scenario:={path}", *extra)
        assert p.wait(30) == 2
        log = procs.log(exe)
        assert "error: keys: a secure run needs its key directory" in log and "Traceback" not in log
    keys = make_keys(tmp_path, path)
    (tmp_path / "keys/agent_0.key").chmod(0o644)
    p = procs.start("open_key", "agent_node", "-p", f"scenario:={path}", "-p", "agent_id:=0", *keys)
    assert p.wait(30) == 2
    assert "agent_0.key: readable by others (mode 644; chmod 600 it)" in procs.log("open_key")


def test_a_dead_robots_message_relayed_by_another_process_is_accepted_by_every_receiver(tmp_path, procs):
    """Agent 2 seals a Selection for the team and exits; a process without keys kept its bytes and
    publishes them again to the world, agent 0 and agent 1 — the world relays a dead robot's
    messages so in a realtime run — and each accepts it; a copy with one byte changed is dropped."""
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(generate_scenario(3, 2, 1, Grid(12, 6), 2)))
    keys = make_keys(tmp_path, path)[1].removeprefix("keys:=")
    relay = procs.run("relay", [sys.executable, str(RELAY), "relay", "--readers", "3"])
    procs.run("speaker", [sys.executable, str(RELAY), "speak", "--keys", keys, "--agent", "2"])
    procs.wait_for("relay", "kept")
    assert procs.procs["speaker"].wait(30) == 0, procs.log("speaker")
    names = {"world": "-1", "agent_0": "0", "agent_1": "1"}
    for name, agent in names.items():  # only now: none of them heard the speaker itself
        procs.run(name, [sys.executable, str(RELAY), "listen", "--keys", keys, "--agent", agent])
    assert relay.wait(60) == 0, procs.log("relay")
    for name in names:
        assert procs.procs[name].wait(30) == 0, procs.log(name)
        log = procs.log(name)
        assert "accepted selection 7 from agent 2" in log, log
        assert "from agent 2: forged: the tag does not match" in log, log  # the altered copy
        assert "Traceback" not in log
