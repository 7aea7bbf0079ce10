"""The message dataclasses on the ROS wire: every message survives conversion to its ``ost_msgs``
interface, CDR serialization (as DDS carries it) and back; a value that does not fit its dataclass
is a ``MessageError`` naming the field; every dataclass field has its interface field."""

import dataclasses
import enum
import typing

import pytest
from hypothesis import given
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message

from ost_msgs_py import wire
from ost_ros import protocols
from ost_ros.lockstep.messages import (
    RUNTIME_MESSAGES,
    Acted,
    AgentReport,
    PlanStep,
    Ready,
    Resend,
    RunEnd,
    Sample,
    Tick,
)
from ost_ros.messages import (
    Action,
    ActionKind,
    AgentLost,
    ObjectInfo,
    Observation,
    ScheduledObject,
    SearchDone,
)

ints = st.integers(-5, 10**6)
ids = st.integers(-1, 10**4)
counts = st.integers(0, 10**4)
steps = st.integers(-1, 10**12)  # int64 on the wire
cells = st.tuples(ints, ints)
moves = st.tuples(st.integers(-1, 1), st.integers(-1, 1))
texts = st.text(max_size=8)
id_lists = st.lists(ints, max_size=4).map(tuple)
infos = st.builds(ObjectInfo, ids, cells, cells, st.integers(1, 10))
scheduled = st.builds(ScheduledObject, ids, id_lists, steps, steps)
lost = st.builds(AgentLost, ids, steps, st.lists(infos, max_size=2).map(tuple))
observations = st.builds(Observation, ids, steps, cells, st.lists(infos, max_size=3).map(tuple))
actions = st.builds(Action, ids, steps, st.sampled_from(list(ActionKind)), cells, ids, texts)
_RANGES = {"int32": 31, "int64": 63}  # signed: [-2^b, 2^b - 1]
_UNSIGNED = {"uint8": 8, "uint16": 16, "uint32": 32, "uint64": 64}


def _field(hint, ros: str):
    """Values of one dataclass field, over the whole range its interface field takes."""
    if hint is int:
        if ros in _UNSIGNED:
            return st.integers(0, 2 ** _UNSIGNED[ros] - 1)
        return st.integers(-(2 ** _RANGES[ros]), 2 ** _RANGES[ros] - 1)
    if hint is str:
        return texts
    if hint is bool:
        return st.booleans()
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        return st.sampled_from(list(hint))
    if dataclasses.is_dataclass(hint):
        return built(hint)
    args = typing.get_args(hint)
    if typing.get_origin(hint) is tuple and args[-1] is Ellipsis:  # a sequence
        return st.lists(_field(args[0], ros[len("sequence<") : -1]), max_size=3).map(tuple)
    if typing.get_origin(hint) is tuple:  # a fixed tuple onto a message: a cell
        return st.tuples(*(_field(a, "int32") for a in args))
    if set(args) == {int, type(None)}:  # -1 on the wire is None
        return st.none() | st.integers(0, 2 ** _RANGES[ros] - 1)
    raise TypeError(f"no strategy for {hint!r} ({ros})")


def built(cls):
    """Any value of a message dataclass, from its type hints and its interface's field types."""
    ros = wire.ros_type(cls).get_fields_and_field_types()
    hints = typing.get_type_hints(cls)
    return st.builds(
        cls,
        **{
            f.name: _field(hints[f.name], ros[f.name])
            for f in dataclasses.fields(cls)
            if f.name != "version" and (cls, f.name) != (AgentLost, "sender")
        },
    )


# Every agent message kind of the registry (its specs' messages): a new protocol's are drawn too.
protocol_msgs = st.one_of(*(built(cls) for cls in protocols.messages()))
peers_counts = st.lists(st.tuples(ids, counts), max_size=4).map(
    lambda pc: (tuple(p for p, _ in pc), tuple(c for _, c in pc))
)
runtime_msgs = st.one_of(
    st.builds(Sample, protocol_msgs, steps, counts, texts),
    st.builds(Ready, ids, texts, texts, texts),
    peers_counts.flatmap(
        lambda pc: st.builds(
            Tick,
            steps,
            steps,
            observations,
            st.just(pc[0]),
            st.just(pc[1]),
            texts,
            st.lists(lost, max_size=2).map(tuple),
        )
    ),
    st.builds(
        Acted,
        actions,
        counts,
        st.lists(
            st.builds(
                PlanStep, cells, st.booleans(), id_lists, st.sampled_from(list(ActionKind)), moves, ids, texts
            ),
            max_size=3,
        ).map(tuple),
        texts,
    ),
    st.builds(Resend, ids, steps, id_lists, texts),
    peers_counts.flatmap(
        lambda pc: st.builds(
            RunEnd,
            steps,
            steps,
            st.booleans(),
            st.just(pc[0]),
            st.just(pc[1]),
            texts,
            st.lists(lost, max_size=2).map(tuple),
        )
    ),
    st.builds(
        AgentReport,
        ids,
        texts,
        texts,
        st.none() | st.integers(0, 10**9),
        ints,
        st.lists(scheduled, max_size=3).map(tuple),
        st.lists(st.tuples(ids, steps), max_size=3).map(tuple),
        st.lists(st.text(max_size=12), max_size=2).map(tuple),
        counts,
        texts,
        texts,
    ),
)


def over_dds(value):
    """As a receiver gets it: converted, serialized to CDR, deserialized, converted back."""
    msg = wire.to_ros(value)
    return wire.from_ros(deserialize_message(serialize_message(msg), type(msg)))


@given(runtime_msgs)
def test_every_message_round_trips_through_cdr(value):
    assert over_dds(value) == value


def test_every_dataclass_has_its_interface():
    for cls in (*protocols.messages(), AgentLost, *RUNTIME_MESSAGES):
        fields = wire.ros_type(cls).get_fields_and_field_types()
        own = (
            {f.name for f in dataclasses.fields(cls)}
            - {"version"}
            - ({"sender"} if cls is AgentLost else set())
        )
        assert own <= set(fields), (cls.__name__, own - set(fields))
        if cls in wire.PROTOCOL_MESSAGES:  # the stamp of a sample
            assert {"run", "step", "seq"} <= set(fields)
        assert wire.type_name(cls) == f"ost_msgs/msg/{cls.__name__}"


def test_bad_values_name_the_field():
    step = PlanStep((0, 0), False, (), ActionKind.MOVE, (1, 0), -1, "S")
    acted = wire.to_ros(Acted(Action(1, 2, ActionKind.WAIT), 0, (step, step)))
    acted.action.kind = "fly"
    with pytest.raises(
        wire.MessageError, match=r"acted\.action\.kind: 'fly' is not one of wait, move, carry"
    ):
        wire.from_ros(acted)
    acted.action.kind = "wait"
    acted.plan.kind[1] = 7
    with pytest.raises(wire.MessageError, match=r"acted\.plan\.kind\[1\]: 7 is not one of 0 \(wait\)"):
        wire.from_ros(acted)
    acted.plan.kind[1] = 1
    acted.plan.dy = [0]
    with pytest.raises(wire.MessageError, match=r"acted\.plan\.dy: 1 entries, x has 2"):
        wire.from_ros(acted)
    report = wire.to_ros(AgentReport(1, "ccp", "CI=1", None, 0, (), (), (), 0))
    assert wire.from_ros(report).predicted_makespan is None
    report.predicted_makespan = -7
    with pytest.raises(wire.MessageError, match=r"agent_report\.predicted_makespan: -7"):
        wire.from_ros(report)


def test_a_foreign_message_is_refused_and_senders_are_named():
    from std_msgs.msg import String

    with pytest.raises(wire.MessageError, match="not an ost_msgs message"):
        wire.from_ros(String(data="{}"))
    assert wire.sender_of(wire.to_ros(Sample(SearchDone(4, 1), 1, 0))) == "agent 4"
    assert wire.sender_of(wire.to_ros(Acted(Action(2, 1, ActionKind.WAIT), 0))) == "agent 2"
    assert wire.sender_of(String()) == "unknown"
