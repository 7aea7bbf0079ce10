"""The direct CDR codec (ost_msgs_py/cdr.py) is rclpy's own, both ways, for every interface the
wire knows: random messages serialised by rclpy decode to the same fields here, and the bytes
encoded here deserialise in rclpy to the same message — at the level of the generated classes
(every field type over its whole range) and of the message dataclasses (``wire.to_cdr`` /
``wire.from_cdr``). Plus: truncated or foreign bytes are a ``MessageError``, never anything else."""

from __future__ import annotations

import array
import dataclasses
import importlib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message

from ost_msgs_py import cdr, wire
from ost_msgs_py.errors import MessageError
from ost_ros.lockstep.messages import Sample
from ost_ros.messages import ObjectInfo
from ost_ros.realtime.messages import BaseClock, BaseEvent, Digest, Lost, Mark, Need, RtStatus
from tests.ost_msgs_py.test_wire import built, protocol_msgs, runtime_msgs

INTERFACES = sorted(
    {wire.ros_type(c) for c in (*wire.PROTOCOL_MESSAGES, *wire.RUNTIME_MESSAGES, *wire.REALTIME_MESSAGES)},
    key=lambda c: c.__name__,
)
RANGES = {
    "int8": (-(2**7), 2**7 - 1), "uint8": (0, 2**8 - 1), "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1), "int32": (-(2**31), 2**31 - 1), "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1), "uint64": (0, 2**64 - 1),
}  # fmt: skip
# rclpy's strings are C strings: a NUL inside one ends it there (this codec keeps it)
TEXT = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\0"), max_size=12)


def values(field_type: str):
    """Any value of a field of the generated classes."""
    if field_type in RANGES:
        return st.integers(*RANGES[field_type])
    if field_type == "boolean":
        return st.booleans()
    if field_type in ("double", "float"):
        return st.floats(allow_nan=False, width=64 if field_type == "double" else 32)
    if field_type == "string":
        return TEXT
    if field_type.startswith("sequence<"):
        return st.lists(values(field_type[len("sequence<") : -1]), max_size=5)
    package, name = field_type.split("/")
    return messages(getattr(importlib.import_module(f"{package}.msg"), name))


def messages(cls):
    fields = cls.get_fields_and_field_types()
    return st.builds(lambda kw: cls(**kw), st.fixed_dictionaries({n: values(t) for n, t in fields.items()}))


def plain(msg):
    """A message (generated or light) as nested dicts and lists, for comparison."""
    if hasattr(msg, "get_fields_and_field_types") or isinstance(msg, cdr.Light):
        names = (
            msg.get_fields_and_field_types() if hasattr(msg, "get_fields_and_field_types") else msg.__slots__
        )
        return {n: plain(getattr(msg, n)) for n in names}
    if isinstance(msg, (list, tuple, array.array)):
        return [plain(x) for x in msg]
    return msg


def light(msg):
    """A generated message as its light twin, field by field."""
    cls = cdr.message_class(type(msg))
    kwargs = {}
    for name, t in msg.get_fields_and_field_types().items():
        v = getattr(msg, name)
        if "/" in t:
            v = [light(x) for x in v] if t.startswith("sequence<") else light(v)
        kwargs[name] = v
    return cls(**kwargs)


@settings(max_examples=40, deadline=None)
@given(data=st.data(), cls=st.sampled_from(INTERFACES))
def test_rclpys_bytes_decode_here_and_ours_in_rclpy(data, cls):
    msg = data.draw(messages(cls))
    theirs = serialize_message(msg)
    got, end = cdr.decode(cls, theirs)
    assert plain(got) == plain(msg)
    ours = bytes(cdr.encode(light(msg)))
    assert plain(deserialize_message(ours, cls)) == plain(msg)
    # the same bytes, padding aside: rclpy's may run on past the end (Fast CDR sizes its buffer by
    # an estimate and hands all of it over) but never end sooner
    assert end == len(ours) <= len(theirs)
    assert cdr.decode(cls, ours) == (got, end)
    # byte for byte where ours is not zero (padding, written as zeros here, is whatever Fast
    # CDR's buffer held)
    assert all(b == theirs[k] for k, b in enumerate(ours) if b)


def _realtime():
    floats = st.floats(allow_nan=False, allow_infinity=False, width=64)
    infos = built(ObjectInfo)
    return st.one_of(
        st.builds(Mark, st.integers(-1, 99), st.integers(-(2**40), 2**40), st.integers(0, 2**40)),
        st.builds(Need, st.integers(-1, 99), st.integers(-(2**40), 2**40)),
        st.builds(Digest, st.integers(-1, 99), st.integers(0, 2**40), st.integers(0, 99), TEXT, TEXT),
        st.builds(
            Lost,
            st.integers(0, 99),
            st.integers(0, 2**40),
            st.lists(infos, max_size=2).map(tuple),
            seq=st.integers(0, 2**40),
            at=st.tuples(st.integers(0, 500), st.integers(0, 200)),
            delivered=st.lists(st.integers(0, 99), max_size=3).map(tuple),
        ),
        st.builds(
            BaseEvent,
            st.integers(0, 99),
            st.integers(0, 2**31),
            st.sampled_from(["started", "stalled", "lifted", "detected", "ended"]),
            st.integers(0, 2**40),
            floats,
            st.tuples(st.integers(0, 500), st.integers(0, 200)),
            st.integers(0, 1),
            floats,
            floats,
            floats,
            st.integers(-1, 99),
            st.lists(st.integers(0, 99), max_size=4).map(tuple),
            st.lists(infos, max_size=2).map(tuple),
            st.lists(infos, max_size=3).map(tuple),
            st.text(max_size=8),
        ),
        st.builds(BaseClock, floats, st.lists(st.integers(0, 2**31), max_size=60).map(tuple)),
    )


def _texts_ok(value) -> bool:
    """No NUL in any string of a dataclass (rclpy's strings end at one)."""
    if isinstance(value, str):
        return "\0" not in value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return all(_texts_ok(getattr(value, f.name)) for f in dataclasses.fields(value))
    if isinstance(value, (tuple, list)):
        return all(_texts_ok(x) for x in value)
    return True


@settings(max_examples=150, deadline=None)
@given(
    value=st.one_of(
        runtime_msgs,
        st.builds(Sample, protocol_msgs, st.integers(0, 99), st.integers(0, 99), TEXT),
        _realtime(),
    ),
    run=TEXT,
)
def test_every_dataclass_through_our_bytes_is_rclpys_message(value, run):
    """Dataclass values: our bytes, deserialised by rclpy, are the message rclpy would have made;
    rclpy's bytes, decoded here, give the dataclass back."""
    if not _texts_ok(value):
        return
    run_of = run if isinstance(value, wire.REALTIME_MESSAGES) else None
    kind = type(value.message) if isinstance(value, Sample) else type(value)
    ours = bytes(wire.to_cdr(value, run=run_of))
    expected = wire.to_ros(value, run=run_of)
    assert plain(deserialize_message(ours, wire.ros_type(kind))) == plain(expected)
    assert wire.from_cdr(kind, serialize_message(expected)) == value
    assert wire.round_trip(value) == value


def test_every_interface_compiles_and_rtstatus_is_a_protocol_message():
    for cls in INTERFACES:
        assert cdr.ros_class(cdr.message_class(cls)) is cls
        assert cdr.message_class(cls).__name__ == cls.__name__
    assert RtStatus in wire.PROTOCOL_MESSAGES


@settings(max_examples=60, deadline=None)
@given(data=st.data(), cls=st.sampled_from(INTERFACES))
def test_cut_or_foreign_bytes_are_a_message_error(data, cls):
    whole = bytes(cdr.encode(light(data.draw(messages(cls)))))
    cut = data.draw(st.integers(0, len(whole) - 1))
    for bad in (whole[:cut], data.draw(st.binary(max_size=64)), b"\x00\x00\x00\x00" + whole[4:]):
        try:
            _, end = cdr.decode(cls, bad)
        except MessageError:
            continue
        assert end <= len(bad)  # (a prefix can be a whole message of its own)


def test_what_the_codec_does_not_carry_is_refused_at_compile_time():
    """Types no interface of ours uses (fixed and bounded arrays, wide strings, bytes, chars)."""
    for field_type in ("int32[3]", "sequence<int32, 4>", "string<=8", "wstring", "octet", "char"):
        odd = type("Odd", (), {"get_fields_and_field_types": staticmethod(lambda t=field_type: {"a": t})})
        with pytest.raises(TypeError, match="no CDR codec for the field type"):
            cdr.message_class(odd)
