"""Discovery that stops moving before the start — Fast DDS now and then never pairs one writer
with one reader while the rest of discovery completes — is renewed: a node creates the endpoints
whose matching has not moved for ``rediscover_s`` anew, and the renewed endpoints carry the run,
whose result is still ``ost sim``'s."""

import json

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import INSECURE, reference

RENEWED = "creating those endpoints anew"


def test_renewed_endpoints_of_agents_and_world_carry_the_run(tmp_path, procs):
    scenario = generate_scenario(2, 3, 1, Grid(30, 12), 2)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, "ccp", CoordinationPolicy(ci=1))
    result = tmp_path / "result.json"
    common = ["-p", f"scenario:={path}", "-p", "rediscover_s:=0.5", *INSECURE]
    # The world waits for one observer on every tick topic; the agents do not.
    procs.start("world", "world_node", *common, "-p", f"result_file:={result}", "-p", "observers:=1")
    procs.start("agent_0", "agent_node", *common, "-p", "agent_id:=0")
    # agent_1 is not up: agent_0's matching stops moving, and its lacking endpoints are renewed
    procs.wait_for("agent_0", RENEWED, timeout=60)
    procs.start("agent_1", "agent_node", *common, "-p", "agent_id:=1")
    procs.wait_for("agent_0", "ready: 2 agents", timeout=60)
    procs.wait_for("agent_1", "ready: 2 agents", timeout=60)
    # every agent is ready, no observer reads the ticks: the world renews its tick writers
    procs.wait_for("world", RENEWED, timeout=60)
    assert not result.exists()
    procs.start("watch", "watch_node", "-p", f"record:={tmp_path / 'run.mcap'}")
    assert procs.procs["world"].wait(120) == 0, procs.log("world")[-2000:]  # the run is over
    assert json.loads(result.read_text()) == expected
    for name in ("world", "agent_0", "agent_1"):
        assert "Traceback" not in procs.log(name)
