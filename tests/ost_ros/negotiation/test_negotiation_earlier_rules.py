"""The earlier rules stay byte-identical behind their labels: ``stopping="overlap"`` (areas; the
OST search areas use it) and ``drop_rule="reward"`` (targets) send exactly the messages the
library sent before the paper's rules became the defaults. The digests were recorded from that
code (commit c82bdfc: its defaults, ``drop_rule="farthest"`` then) on the same inputs."""

import hashlib
import json

import numpy as np

from ost_ros.negotiation import AgentSpec, AreaTask, TargetTask, make_task_polygon, negotiate
from ost_ros.negotiation.proposals import AreaSearch
from ost_ros.negotiation.rewards import TargetReward

AREA_DIGEST = "a42f0f8c794fe5c9b328a05677f97c6e7160482cad79a2d42cc97214020a7c53"
TARGET_DIGEST = "cb8466f85379c73bd2bcbf50c0fb2c13fe67dd50a4ba88408a2a76bfd871c86f"


def digest(logs: list) -> str:
    return hashlib.sha256(json.dumps(logs).encode()).hexdigest()


def test_overlap_stopping_sends_what_the_earlier_default_sent():
    fast = AreaSearch(population=8, generations=2)
    logs = []
    for robots in (2, 3, 4):
        for seed in (0, 1):
            res = negotiate(
                AreaTask(make_task_polygon(0.673)),
                [AgentSpec(0.9)] * robots,
                seed=seed,
                search=fast,
                trace=False,
                stopping="overlap",
            )
            logs.append([m.to_dict() for m in res.log])
    assert digest(logs) == AREA_DIGEST


def test_reward_drop_rule_sends_what_the_earlier_default_sent():
    logs = []
    for seed in range(100):
        rng = np.random.default_rng(seed)
        n, robots = int(rng.integers(1, 9)), int(rng.integers(2, 8))
        task = TargetTask.from_points(rng.random((n, 2)))
        for strategy in ("rounds", "all-against-all"):
            res = negotiate(
                task,
                [AgentSpec(0.9, TargetReward())] * robots,
                strategy=strategy,
                drop_rule="reward",
                seed=seed,
                trace=False,
            )
            logs.append([m.to_dict() for m in res.log])
    assert digest(logs) == TARGET_DIGEST
