"""Scenario files: generation, round trip, and every kind of bad input naming its field."""

import pytest
import yaml

from ost_ros.model import Grid
from ost_ros.scenario import (
    MAX_CELLS,
    ScenarioError,
    dump_scenario,
    generate_objects,
    generate_scenario,
    load_scenario,
    scenario_from_dict,
    with_team,
)


def test_generate_is_deterministic_and_sorted_by_location():
    a = generate_objects(50, seed=3)
    assert a == generate_objects(50, seed=3)
    assert a != generate_objects(50, seed=4)
    assert [o.id for o in a] == list(range(50))
    assert [o.location for o in a] == sorted(o.location for o in a)
    assert len({o.location for o in a}) == 50
    assert all(1 <= o.required <= 10 and o.location != o.destination for o in a)
    assert all(Grid().contains(o.location) and Grid().contains(o.destination) for o in a)


def test_objects_do_not_depend_on_team_size():
    assert generate_scenario(10, 20, 7).objects == generate_scenario(50, 20, 7).objects


def test_dump_load_round_trip(tmp_path):
    s = generate_scenario(10, 30, 1)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(s))
    assert load_scenario(path) == s
    assert s.partition == (5, 2) and s.agents[3].base == (300, 1)


def test_defaults_team_from_partition():
    s = scenario_from_dict(
        {
            "grid": {"width": 20, "height": 10},
            "partition": [2, 1],
            "objects": [{"id": 0, "location": [1, 1], "destination": [5, 5], "required": 2}],
        }
    )
    assert [a.base for a in s.agents] == [(0, 1), (10, 1)]
    assert s.nmax == 2


def test_agents_without_base_get_their_subarea_start():
    s = scenario_from_dict(
        {"grid": {"width": 20, "height": 10}, "agents": [{"id": 4}, {"id": 2, "base": [3, 3]}], "objects": []}
    )
    assert [(a.id, a.base) for a in s.agents] == [(2, (3, 3)), (4, (10, 1))]


def test_with_team_keeps_objects():
    s = generate_scenario(10, 5, 2)
    t = with_team(s, 20)
    assert t.objects == s.objects and t.partition == (5, 4) and len(t.agents) == 20


GOOD = {
    "grid": {"width": 20, "height": 10},
    "partition": [2, 1],
    "objects": [{"id": 0, "location": [1, 1], "destination": [5, 5], "required": 2}],
}


def variant(path, value):
    data = yaml.safe_load(yaml.safe_dump(GOOD))
    node = data
    for key in path[:-1]:
        node = node[key]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


@pytest.mark.parametrize(
    "data,needle",
    [
        (variant(["colour"], "red"), "unknown key 'colour'"),
        (variant(["objects", 0, "weight"], 3), "objects[0]: unknown key 'weight'"),
        (variant(["objects", 0, "location"], [25, 1]), "objects[0].location: [25, 1] is off the 20x10 grid"),
        (variant(["objects", 0, "destination"], [1, -1]), "objects[0].destination: [1, -1] is off"),
        (variant(["objects", 0, "destination"], [1, 1]), "objects[0].destination: equals its location"),
        (variant(["objects", 0, "required"], 3), "nmax: 3 exceeds the team of 2 agents"),
        (variant(["objects", 0, "required"], 0), "objects[0].required: must be at least 1"),
        (variant(["objects", 0, "required"], "two"), "objects[0].required: expected an integer"),
        (variant(["objects", 0, "location"], [1]), "objects[0].location: expected [x, y]"),
        (variant(["objects", 0, "id"], KeyError), "objects[0]: missing key 'id'"),
        (variant(["grid", "width"], -5), "grid.width: must be at least 1, got -5"),
        (variant(["partition"], [3, 0]), "partition[1]: must be at least 1"),
        (variant(["partition"], [30, 1]), "partition: partition 30x1 does not fit"),
        (variant(["objects"], {"a": 1}), "objects: expected a list"),
        ({"objects": [], "nmax": 2, "agents": [{"id": 0}, {"id": 0}]}, "agents[1].id: duplicate id 0"),
        ({"objects": []}, "agents: missing"),
        ([1, 2], "scenario: expected a mapping"),
        (None, "the file is empty"),
        ({"objects": [], "agents": [{"id": 0}], "nmax": 3}, "nmax: 3 exceeds the team of 1 agents"),
    ],
)
def test_bad_scenarios_name_the_field(data, needle):
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict(data)
    assert needle in str(err.value)
    assert "\n" not in str(err.value)


def test_bad_files(tmp_path):
    with pytest.raises(ScenarioError, match="no such file"):
        load_scenario(tmp_path / "missing.yaml")
    p = tmp_path / "broken.yaml"
    p.write_text("grid: {width: 3\nobjects: [")
    with pytest.raises(ScenarioError, match="invalid YAML at line"):
        load_scenario(p)


def test_generation_limits():
    with pytest.raises(ScenarioError, match="do not fit"):
        generate_objects(10, 0, Grid(3, 3))
    with pytest.raises(ScenarioError, match="nmax: 10 exceeds the team of 4 agents"):
        generate_scenario(4, 3, 0)


def test_grids_beyond_what_a_run_can_hold_are_refused_at_once():
    # 10^5 x 10^5 used to end in a MemoryError after a minute (sweeps are kept cell by cell)
    for make in (
        lambda: generate_scenario(10, 20, 1, Grid(100_000, 100_000)),
        lambda: scenario_from_dict(
            {"grid": {"width": 100_000, "height": 100_000}, "partition": [5, 2], "objects": []}
        ),
    ):
        with pytest.raises(ScenarioError, match=r"grid: 100000x100000 has 10,000,000,000 cells, more than"):
            make()
    largest = scenario_from_dict(
        {"grid": {"width": 40_000, "height": 25_000}, "partition": [5, 2], "objects": []}
    )
    assert largest.grid.cells == MAX_CELLS
