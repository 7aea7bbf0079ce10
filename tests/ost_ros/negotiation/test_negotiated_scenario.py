"""A negotiated partition inside the OST: every robot sweeps its negotiated region
(``AgentSpec.sweep``), never a cell of its forbidden zones, the sweeps together sense every cell,
and the run delivers everything — with the step and event engines equal, CCP and NCP; scenario
files carry the sweeps (round trip), and bad ones are refused with one line."""

from dataclasses import replace

import numpy as np
import pytest

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.negotiation.partition import negotiated_scenario
from ost_ros.negotiation.proposals import AreaSearch
from ost_ros.scenario import (
    ScenarioError,
    build_scenario,
    dump_scenario,
    generate_scenario,
    scenario_from_dict,
)
from ost_ros.search import agent_plan, route

CHEAP = AreaSearch(population=8, generations=3)  # a cheaper proposal search for tests


def heterogeneous(
    periods=(1, 1, 2, 3),
    zones=(((0, 0, 12, 6),), (), (), ((30, 10, 39, 15),)),
    grid=Grid(40, 16),
    objects=8,
    seed=1,
):
    s = generate_scenario(len(periods), objects, seed, grid, 2)
    agents = [replace(a, period=p, forbidden=z) for a, p, z in zip(s.agents, periods, zones)]
    return build_scenario(s.grid, list(s.objects), partition=s.partition, agents=agents, nmax=s.nmax)


@pytest.fixture(scope="module")
def negotiated():
    s = heterogeneous()
    return s, *negotiated_scenario(s, search=CHEAP)


def test_regions_tile_the_grid_and_avoid_forbidden_zones(negotiated):
    s, ns, result = negotiated
    owner = result.owner
    assert owner.shape == (s.grid.height, s.grid.width) and (owner >= 0).all()
    for k, a in enumerate(s.agents):
        for x0, y0, x1, y1 in a.forbidden:
            assert not (owner[y0 : y1 + 1, x0 : x1 + 1] == k).any()
    # the sweeps together sense every cell (the scenario builder checks it too)
    seen = np.zeros((s.grid.height + 2, s.grid.width + 2), dtype=bool)
    for area, a in zip(ns.subareas, ns.agents):
        cells = np.array(route(agent_plan(area, a.base, a.sweep)))
        for dx in range(3):
            for dy in range(3):
                seen[cells[:, 1] + dy, cells[:, 0] + dx] = True
    assert seen[1:-1, 1:-1].all()


@pytest.mark.parametrize("protocol", ["ccp", "ncp"])
def test_runs_deliver_everything_and_engines_agree(negotiated, protocol):
    _, ns, _ = negotiated
    policy = CoordinationPolicy(ci=2)
    step = simulate(ns, protocol, policy, engine="step")
    assert step.completed and step.agreement and not step.rejections
    assert step.predicted_makespan == step.makespan
    assert simulate(ns, protocol, policy, engine="event").to_dict() == step.to_dict()


def test_scenario_file_round_trip_and_hcp_refused(negotiated):
    _, ns, _ = negotiated
    again = scenario_from_dict(__import__("yaml").safe_load(dump_scenario(ns)))
    assert again == ns and all(a.sweep for a in again.agents)
    assert again.agents[0].forbidden == ((0, 0, 12, 6),)
    with pytest.raises(ValueError, match="hcp cannot run robots with their own sweeps"):
        simulate(ns, "hcp")


def test_negotiated_search_is_faster_for_an_unequal_team(negotiated):
    _, _, result = negotiated
    assert result.team_time < result.equal_team_time


def bad(**agent0):
    d = {
        "grid": {"width": 12, "height": 6},
        "agents": [{"id": 0, "base": [0, 1], **agent0}, {"id": 1, "base": [6, 1]}],
        "objects": [],
        "nmax": 1,
    }
    return d


@pytest.mark.parametrize(
    "agent0, text",
    [
        ({"sweep": [[0, 1], [11, 1]]}, "agents[1].sweep: missing"),
        ({"sweep": [[0, 1], [40, 1]]}, "agents[0].sweep[1]: [40, 1] is off the 12x6 grid"),
        ({"forbidden": [[0, 0, 99, 1]]}, "agents[0].forbidden[0]"),
        ({"forbidden": [[0, 0, 1]]}, "expected [x0, y0, x1, y1]"),
    ],
)
def test_bad_sweeps_and_zones_are_one_line(agent0, text):
    with pytest.raises(ScenarioError, match=__import__("re").escape(text)):
        scenario_from_dict(bad(**agent0))


def test_sweeps_that_leave_cells_unsensed_are_refused():
    d = bad(sweep=[[0, 1], [11, 1]])
    d["agents"][1]["sweep"] = [[6, 1]]  # nobody senses rows 3..5
    with pytest.raises(ScenarioError, match="sensed by no agent's sweep"):
        scenario_from_dict(d)
