"""RunResult: JSON round trip (result files written by a DDS run are read back by tools)."""

from ost_ros.bounds import lower_bound
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.result import RunResult
from ost_ros.scenario import generate_scenario


def test_round_trip():
    scenario = generate_scenario(4, 6, 2, Grid(30, 12), 3)
    result = simulate(scenario)
    result.lower_bound = lower_bound(scenario).value
    d = result.to_dict()
    assert RunResult.from_dict(d).to_dict() == d
    assert RunResult.from_dict(d).summary() == result.summary()
