"""Equal partition: the paper's Table 2, the aspect-ratio rule, and exact tiling."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ost_ros.model import Grid
from ost_ros.partition import TABLE2, choose_partition, split, subareas


@pytest.mark.parametrize("n,expected", sorted(TABLE2.items()))
def test_table2(n, expected):
    assert choose_partition(n, Grid(500, 200)) == expected


def test_other_counts_follow_aspect_ratio():
    assert choose_partition(4, Grid(500, 200)) == (4, 1)  # m/n = 4 is nearest 2.5 (vs 1)
    assert choose_partition(9, Grid(300, 300)) == (3, 3)
    assert choose_partition(1, Grid(500, 200)) == (1, 1)
    assert choose_partition(7, Grid(10, 100)) == (1, 7)


def test_split_is_as_equal_as_integer_division():
    assert split(500, 6) == [(0, 84), (84, 84), (168, 83), (251, 83), (334, 83), (417, 83)]


@given(st.integers(1, 60), st.integers(1, 60), st.integers(1, 6), st.integers(1, 6))
def test_subareas_tile_the_grid(w, h, m, n):
    if m > w or n > h:
        with pytest.raises(ValueError):
            subareas(Grid(w, h), (m, n))
        return
    areas = subareas(Grid(w, h), (m, n))
    assert len(areas) == m * n
    assert sum(a.width * a.height for a in areas) == w * h
    assert max(a.width for a in areas) - min(a.width for a in areas) <= 1
    covered = {
        (x, y) for a in areas for x in range(a.x0, a.x0 + a.width) for y in range(a.y0, a.y0 + a.height)
    }
    assert len(covered) == w * h
