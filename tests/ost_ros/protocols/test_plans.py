"""Quiet plans: a segment step by step (``unroll``) and in bulk (``advance``) agree, and the rules
of motion are the world's (one cell per movable step, x first; a carry moves on its group's
steps; a hold never moves)."""

from hypothesis import given
from hypothesis import strategies as st

from ost_ros.messages import ActionKind
from ost_ros.protocols.plans import Segment, advance, rest, unroll
from ost_ros.search import route


def test_walk_with_a_period_waits_between_moves():
    seg = Segment("walk", "HELPING", 4, period=2, target=(2, 1))
    steps = unroll((seg,), 3, (0, 0), 10)
    assert [(s.t, s.position, s.kind) for s in steps] == [
        (3, (0, 0), ActionKind.WAIT),
        (4, (0, 0), ActionKind.MOVE),
        (5, (1, 0), ActionKind.WAIT),
        (6, (1, 0), ActionKind.MOVE),
    ]
    assert advance(seg, 3, (0, 0), 4) == ((2, 0), 2)


def test_hold_then_carry_and_open_ended_cut_at_the_limit():
    plan = (
        Segment("hold", "WAITING", 2, target=(5, 0), object=7),
        Segment("carry", "MOVING", None, target=(5, 0), object=7),
    )
    steps = unroll(plan, 0, (2, 0), 5)
    assert [s.position for s in steps] == [(2, 0), (2, 0), (2, 0), (3, 0), (4, 0)]
    assert all(s.kind is ActionKind.CARRY and s.object == 7 and s.direction == (1, 0) for s in steps)
    assert [s.state for s in steps] == ["WAITING"] * 2 + ["MOVING"] * 3


def test_sweep_follows_its_path_and_reads_the_sensor():
    path = route([(0, 1), (3, 1), (3, 4)])
    seg = Segment("sweep", "SEARCHING", 4, path=path, index=1)
    steps = unroll((seg,), 10, path[1], 10)
    assert [s.position for s in steps] == path[1:5] and all(s.reads_sensor for s in steps)
    assert advance(seg, 10, path[1], 4) == (path[5], 4)
    assert rest(seg, 10, 3) == Segment("sweep", "SEARCHING", 1, path=path, index=4)


segments = st.one_of(
    st.builds(
        lambda tx, ty, p: Segment("walk", "HELPING", None, period=p, target=(tx, ty)),
        st.integers(-6, 6),
        st.integers(-6, 6),
        st.integers(1, 3),
    ),
    st.builds(
        lambda tx, ty, p: Segment("carry", "MOVING", None, period=p, target=(tx, ty), object=1),
        st.integers(-6, 6),
        st.integers(-6, 6),
        st.integers(1, 3),
    ),
)


@given(segments, st.integers(0, 20), st.integers(1, 15))
def test_bulk_equals_step_by_step(seg, t, k):
    steps = unroll((seg,), t, (0, 0), k + 1)
    end, moves = advance(seg, t, (0, 0), k)
    assert steps[k].position == end
    assert moves == sum(a.position != b.position for a, b in zip(steps, steps[1:]))
