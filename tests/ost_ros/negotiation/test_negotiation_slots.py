"""The slot negotiation is one piece of code: NCP's comm modules run it round by round over the
OST's messages, ``ost negotiate slots`` runs it standalone — and they agree group for group."""

import json
import subprocess
import sys

from hypothesis import given, settings

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.negotiation.slots import after_search, negotiate_slots
from ost_ros.scenario import dump_scenario
from tests.strategies import scenarios


@settings(max_examples=60)
@given(scenarios(agents=(1, 6), objects=(1, 9)))
def test_ncp_after_the_search_agrees_with_the_library(scenario):
    # CI > M: NCP negotiates once, after the whole search — the library's after_search problem
    run = simulate(scenario, "ncp", CoordinationPolicy(ci=1000))
    neg, _ = negotiate_slots(*after_search(scenario))
    agreed = neg.groups(tuple(a.id for a in scenario.agents))
    assert {o.id: tuple(o.agents) for o in run.objects} == {k: tuple(v) for k, v in agreed.items()}
    assert run.coordinations == 1 and run.completed


def test_cli(tmp_path):
    from ost_ros.model import Grid
    from ost_ros.scenario import generate_scenario

    s = generate_scenario(4, 6, 3, Grid(40, 16), 3)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(s))
    r = subprocess.run(
        [sys.executable, "-m", "ost_ros", "negotiate", "slots", "--scenario", str(path), "--json"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    ncp = simulate(s, "ncp", CoordinationPolicy(ci=1000))
    assert out["groups"] == {str(o.id): list(o.agents) for o in ncp.objects}
    bad = subprocess.run(
        [sys.executable, "-m", "ost_ros", "negotiate", "slots", "--scenario", str(path), "--delta", "1"],
        capture_output=True,
        text=True,
    )
    assert bad.returncode == 2 and "(0, 1)" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
