"""Behaviour kept without a barrier: seeded in-process runs of every protocol — latency and
jitter, unequal speeds, speed noise, stalls, failures, bases across a network, silences, joins,
kills and partitions — give the digests recorded before the realtime runtime was reshaped
(``benchmarks/realtime_digests.py``: a digest of the whole result, the realtime report and every
robot's coordination digests; 3 000 runs compared there, the first 30 of each family here).
A change that means to alter behaviour records them again and says why in its commit."""

import json
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
RECORDED = json.loads((REPO / "tests" / "corpus" / "realtime_digests.json").read_text())


@pytest.fixture(scope="module")
def digests():
    sys.path.insert(0, str(REPO / "benchmarks"))
    try:
        import realtime_digests
    finally:
        sys.path.remove(str(REPO / "benchmarks"))
    return realtime_digests


def test_enough_runs_are_kept():
    families = {k.split("/")[0] for k in RECORDED}
    assert families == {"agreement", "remote", "membership"} and len(RECORDED) >= 90


@pytest.mark.parametrize("run", sorted(RECORDED))
def test_a_recorded_run_gives_the_same_digest(run, digests):
    family, i = run.split("/")
    assert digests.digest_of(family, int(i)) == RECORDED[run], f"{run} changed"
