"""The boustrophedon sweep: hand-computed paths and full coverage of any subarea."""

from hypothesis import given
from hypothesis import strategies as st

from ost_ros.model import Subarea, manhattan
from ost_ros.search import SearchModule, SweepSummary, plan_length, route, sweep_plan, sweep_waypoints


def test_hand_computed_sweep_5x7():
    # ceil(7/3) = 3 passes on rows 1, 4 and 7 -> clamped to the last row, 6.
    area = Subarea(0, 0, 5, 7)
    assert sweep_waypoints(area) == [(0, 1), (4, 1), (4, 4), (0, 4), (0, 6), (4, 6)]
    assert plan_length(sweep_waypoints(area)) == 4 + 3 + 4 + 2 + 4


def test_paper_subarea_100x100():
    # 5x2 partition of 500x200: 34 passes of 99 moves and 98 moves down.
    s = SweepSummary.of(Subarea(100, 100, 100, 100), (100, 101))
    assert s.length == 34 * 99 + 98
    assert s.end == (100, 199)  # the 34th pass (index 33, odd) runs right to left


def test_base_away_from_start_walks_there_first():
    area = Subarea(10, 0, 4, 3)
    plan = sweep_plan(area, (0, 0))
    assert plan[:2] == [(0, 0), (10, 1)]
    path = route(plan)
    assert path[0] == (0, 0) and path[11] == (10, 1)


def test_search_module_follows_path_and_ends():
    area = Subarea(0, 0, 3, 3)
    mod = SearchModule.for_area(area, area.start)
    pos, steps = area.start, 0
    while not mod.at_end(pos):
        nxt = mod.next_cell(pos)
        assert manhattan(pos, nxt) == 1
        pos, steps = nxt, steps + 1
    assert steps == mod.length == 2


@given(st.integers(0, 5), st.integers(0, 5), st.integers(1, 25), st.integers(1, 25))
def test_sweep_senses_every_cell_of_the_subarea(x0, y0, w, h):
    area = Subarea(x0, y0, w, h)
    path = route(sweep_plan(area, area.start))
    assert all(manhattan(a, b) == 1 for a, b in zip(path, path[1:]))
    assert all(area.contains(c) for c in path)  # the sweep never leaves the subarea
    sensed = {(x + dx, y + dy) for x, y in path for dx in (-1, 0, 1) for dy in (-1, 0, 1)}
    cells = {(x, y) for x in range(x0, x0 + w) for y in range(y0, y0 + h)}
    assert cells <= sensed
    assert len(path) - 1 == SweepSummary.of(area, area.start).length
