"""A plan as it travels (``PlanColumns``): the same steps as the tuple it was made from, in every
way the world and the agent read it — indexed, column by column, compared, pickled (the world's
checkpoint) and through the wire."""

import pickle
from dataclasses import FrozenInstanceError, fields

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ost_msgs_py import wire
from ost_ros.lockstep.messages import Acted, PlanColumns, PlanStep
from ost_ros.messages import Action, ActionKind

cells = st.tuples(st.integers(-5, 10**6), st.integers(-5, 10**6))
moves = st.tuples(st.integers(-1, 1), st.integers(-1, 1))
plans = st.lists(
    st.builds(
        PlanStep,
        cells,
        st.booleans(),
        st.lists(st.integers(0, 10**4), max_size=4).map(tuple),
        st.sampled_from(list(ActionKind)),
        moves,
        st.integers(-1, 10**4),
        st.sampled_from(["searching", "moving", "waiting", "é"]),
    ),
    max_size=12,
).map(tuple)


@given(plans)
def test_columns_are_the_steps(steps):
    plan = PlanColumns.of(steps)
    assert len(plan) == len(steps)
    assert plan == steps and steps == plan  # either way round
    assert list(plan) == list(steps)
    assert plan[:] == steps and plan[1:3] == steps[1:3]
    for k, s in enumerate(steps):
        assert plan[k] == s and plan[k - len(steps)] == s
        assert plan.position(k) == s.position and plan.sensed_at(k) == s.sensed
        a = Action(7, 100 + k, s.kind, s.direction, s.object, s.state)
        b = plan.action(7, 100 + k, k)  # built without Action's __init__ (the world's skip)
        assert b == a and hash(b) == hash(a) and vars(b) == vars(a) and plan.same_action(k, a)
    assert hash(plan) == hash(steps)
    assert pickle.loads(pickle.dumps(plan)) == plan
    assert PlanColumns.of(plan) is plan


@given(plans)
def test_the_wire_gives_columns_that_seal_alike(steps):
    acted = Acted(Action(3, 5, ActionKind.WAIT), 0, steps, "run")
    for back in (wire.from_ros(wire.to_ros(acted)), wire.from_cdr(Acted, bytes(wire.to_cdr(acted)))):
        assert isinstance(back.plan, PlanColumns)
        assert back == acted
        # the sealed bytes do not depend on how the plan was held
        assert wire.to_cdr(back) == wire.to_cdr(acted)


def test_an_action_is_its_fields():
    # PlanColumns.action fills an Action's __dict__ instead of calling its __init__: right only
    # while Action is a plain frozen dataclass whose fields are all it holds.
    assert not hasattr(Action, "__post_init__") and "__slots__" not in vars(Action)
    a = PlanColumns.of((PlanStep((0, 0), False, (), ActionKind.MOVE, (1, 0), -1, "w"),)).action(2, 9, 0)
    assert type(a) is Action and list(vars(a)) == [f.name for f in fields(Action)]
    with pytest.raises(FrozenInstanceError):
        a.t = 3  # type: ignore[misc]


def test_a_different_step_is_unequal():
    s = PlanStep((0, 0), True, (4,), ActionKind.MOVE, (1, 0), -1, "searching")
    plan = PlanColumns.of((s, s))
    assert plan != (s,)
    assert plan != (s, PlanStep((0, 0), True, (5,), ActionKind.MOVE, (1, 0), -1, "searching"))
    assert plan != PlanColumns.of((s, PlanStep((0, 1), True, (4,), ActionKind.MOVE, (1, 0), -1, "searching")))
    with pytest.raises(AttributeError):
        plan.x = None  # type: ignore[misc]


def test_inconsistent_columns_are_refused():
    good = {c: getattr(PlanColumns.of(()), c) for c in PlanColumns.COLUMNS}
    with pytest.raises(ValueError, match="y: 1 entries, x has 0"):
        PlanColumns(**{**good, "y": [3]})
    with pytest.raises(ValueError, match="sensed: 1 ids, sensed_count says 0"):
        PlanColumns(**{**good, "sensed": [3]})
    one = {
        c: getattr(PlanColumns.of((PlanStep((0, 0), False, (), ActionKind.WAIT, (0, 0), -1, "w"),)), c)
        for c in PlanColumns.COLUMNS
    }
    with pytest.raises(ValueError, match=r"kind\[0\]: 3 is not one of 0 \(wait\)"):
        PlanColumns(**{**one, "kind": [3]})
