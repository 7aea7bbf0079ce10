"""The JSON codec: every registered message round-trips; invalid input names the field."""

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ost_msgs_py import codec
from ost_msgs_py.codec import MessageError, decode, encode
from ost_msgs_py.messages import (
    ALL_MESSAGES,
    Action,
    ActionKind,
    ObjectFound,
    ObjectInfo,
    Observation,
    SearchDone,
    Selection,
)
from ost_msgs_py.runtime import (
    RUNTIME_MESSAGES,
    Acted,
    AgentReport,
    PlanStep,
    Ready,
    RunEnd,
    ScheduleEntry,
    StepMessages,
    Tick,
)

ints = st.integers(-5, 10**6)
cells = st.tuples(ints, ints)
infos = st.builds(ObjectInfo, ints, cells, cells, st.integers(1, 10))
protocol_msgs = st.one_of(
    st.builds(ObjectFound, ints, ints, infos),
    st.builds(SearchDone, ints, ints),
    st.builds(Selection, ints, ints, ints, st.lists(ints, max_size=6).map(tuple)),
)
all_msgs = st.one_of(
    protocol_msgs,
    st.builds(Observation, ints, ints, cells, st.lists(infos, max_size=4).map(tuple)),
    st.builds(Action, ints, ints, st.sampled_from(list(ActionKind)), cells, ints, st.text(max_size=10)),
    st.builds(StepMessages, ints, ints, st.lists(protocol_msgs, max_size=4).map(tuple)),
    st.builds(Ready, ints, st.text(max_size=8), st.text(max_size=8)),
    st.builds(RunEnd, ints, ints, st.booleans(), st.lists(ints, max_size=3).map(tuple)),
    st.builds(
        Tick,
        ints,
        ints,
        st.builds(Observation, ints, ints, cells, st.lists(infos, max_size=2).map(tuple)),
        st.lists(ints, max_size=3).map(tuple),
    ),
    st.builds(
        Acted,
        st.builds(Action, ints, ints, st.sampled_from(list(ActionKind)), cells, ints),
        ints,
        st.lists(
            st.builds(
                PlanStep,
                cells,
                st.booleans(),
                st.lists(ints, max_size=3).map(tuple),
                st.sampled_from(list(ActionKind)),
                cells,
                ints,
                st.text(max_size=5),
            ),
            max_size=3,
        ).map(tuple),
    ),
    st.builds(
        AgentReport,
        ints,
        st.text(max_size=5),
        st.text(max_size=5),
        st.none() | ints,
        ints,
        st.lists(
            st.builds(ScheduleEntry, ints, st.lists(ints, max_size=3).map(tuple), ints, ints), max_size=3
        ).map(tuple),
        st.lists(st.tuples(ints, ints), max_size=3).map(tuple),
        st.lists(st.text(max_size=12), max_size=2).map(tuple),
        ints,
    ),
)


@given(all_msgs)
def test_round_trip(msg):
    text = encode(msg)
    assert decode(text) == msg
    assert json.loads(text)["type"] == msg.TYPE


def test_every_message_class_is_registered():
    for cls in (*ALL_MESSAGES.values(), *RUNTIME_MESSAGES):
        assert codec.REGISTRY[cls.TYPE] is cls


def _obs() -> dict:
    return json.loads(encode(Observation(1, 3, (2, 3), (ObjectInfo(1, (1, 2), (3, 4), 2),))))


@pytest.mark.parametrize(
    "mutate, field",
    [
        (lambda d: d.pop("t"), "observation.t: missing"),
        (lambda d: d.update(t="3"), "observation.t: expected an integer"),
        (lambda d: d.update(t=True), "observation.t: expected an integer"),
        (lambda d: d.update(extra=1), "observation.extra: unknown field"),
        (lambda d: d.update(version=2), "observation.version: unsupported version 2"),
        (lambda d: d.pop("version"), "observation.version: missing"),
        (lambda d: d.update(type="nope"), "message.type: unknown message type"),
        (lambda d: d["sensed"][0].update(location=[1, "a"]), "observation.sensed[0].location[1]"),
        (lambda d: d["sensed"][0].update(location=[1, 2, 3]), "observation.sensed[0].location: expected 2"),
        (lambda d: d.update(position=None), "observation.position: expected a list"),
    ],
)
def test_invalid_fields_are_named(mutate, field):
    d = _obs()
    mutate(d)
    with pytest.raises(MessageError, match=field.replace("[", r"\[").replace("]", r"\]")):
        decode(json.dumps(d))


def test_nested_message_errors_name_the_path():
    d = json.loads(encode(StepMessages(1, 2, (SearchDone(1, 2),))))
    d["messages"][0]["sender"] = "x"
    with pytest.raises(MessageError, match=r"step_messages.messages\[0\].sender: expected an integer"):
        decode(json.dumps(d))


def test_bad_enum_and_expected_type():
    d = json.loads(encode(Action(1, 2, ActionKind.WAIT)))
    d["kind"] = "fly"
    with pytest.raises(MessageError, match=r"action\.kind: 'fly' is not one of wait, move, carry"):
        decode(json.dumps(d))
    with pytest.raises(MessageError, match="not accepted here"):
        decode(encode(SearchDone(1, 2)), Action)


@pytest.mark.parametrize("text", ["", "{", "[]", "null", "3", '"x"', "[" * 100000])
def test_garbage_is_a_message_error(text):
    with pytest.raises(MessageError):
        decode(text)


def test_size_limit():
    big = '{"type":"search_done","sender":1,"t":1,"version":1,"pad":"' + "x" * codec.MAX_BYTES + '"}'
    with pytest.raises(MessageError, match="exceeds"):
        decode(big)


def test_sender_of_invalid_message():
    assert codec.sender_of('{"sender": 4, "t": "bad"}') == "agent 4"
    assert codec.sender_of('{"agent": 2}') == "agent 2"
    assert codec.sender_of("{") == "unknown"
