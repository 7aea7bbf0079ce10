"""The message dataclasses on the ROS wire: conversion to and from the ``ost_msgs`` interfaces.

Every message dataclass on the wire — the protocols' (:mod:`ost_ros.messages` and each protocol's
own, as the registry lists them: :func:`ost_ros.protocols.messages`) and the lockstep's
(:mod:`ost_ros.lockstep.messages`) — has an interface of the same name in the ``ost_msgs``
package (``ost_msgs_py/ost_msgs/msg/``, and a protocol's own in ``ost_ros/protocols/<name>/msg/``),
field for field. The converters are built once, from
the dataclasses' type hints and the generated classes' field types, so a new message needs its
``.msg`` file and its dataclass, no code here.

Field mapping: ``int``/``str``/``bool`` as they are; ``str`` enums as their value (checked on the
way in); a cell ``tuple[int, int]`` as ``ost_msgs/Cell``; other fixed tuples positionally onto a
message (``found``: ``ost_msgs/FoundObject``); ``tuple[T, ...]`` as a sequence; nested dataclasses
as nested messages; ``int | None`` as ``-1`` for None; a plan (a sequence of ``PlanStep``) as
``ost_msgs/Plan``, parallel arrays (a 64-step plan would otherwise be 64 messages and 128 cells
to build and take apart on every action), decoded as :class:`~ost_ros.lockstep.messages.PlanColumns`
(steps built only where read). The dataclasses' ``version`` is the
interface itself (its type hash), so it is not a field on the wire.

A protocol message travels as a :class:`~ost_ros.lockstep.messages.Sample`: the message's fields plus
``run``, ``step`` (when it was broadcast) and ``seq`` (its place among everything the sender
broadcast in that step). Anything that
does not fit raises :class:`MessageError` naming the field, e.g.
``acted.action.kind: 'jump' is not one of wait, move, carry``.
"""

from __future__ import annotations

import array
import dataclasses
import enum
import types
import typing
from collections.abc import Callable, Sequence
from typing import Any

import ost_msgs.msg as ros

from ost_msgs_py import auth
from ost_msgs_py.errors import InterfaceError
from ost_ros import protocols
from ost_ros.lockstep import messages as _runtime
from ost_ros.lockstep.messages import PlanColumns, PlanStep, Sample
from ost_ros.messages import AgentLost
from ost_ros.realtime.messages import Digest, Lost, Mark, Need, RtStatus
from ost_ros.realtime.world import Detection


class MessageError(InterfaceError):
    """A message that does not fit its dataclass; the text names the offending field."""


# Agent-to-agent messages (every kind a registered protocol broadcasts, and a survivor's status
# without a barrier) travel as Samples; the world's notices (AgentLost) only inside Tick/RunEnd.
PROTOCOL_MESSAGES: tuple[type, ...] = (*protocols.messages(), RtStatus)
RUNTIME_MESSAGES: tuple[type, ...] = _runtime.RUNTIME_MESSAGES
# What realtime runs say besides (docs/realtime.md): watermarks, requests for them, the world's
# stamped failure notices, coordination digests, a robot's detections. Each has a ``run`` field
# on the wire that the node sets and checks (:func:`to_ros` ``run=``).
REALTIME_MESSAGES: tuple[type, ...] = (Mark, Need, Lost, Digest, Detection)
_NOT_ON_WIRE = {"version"}
_WORLD_FIELDS = {(AgentLost, "sender")}  # always WORLD: implied by the message kind

_ARRAY_CODES = {"int32": "i", "uint32": "I", "int64": "q", "uint64": "Q"}

ToRos = Callable[[Any], Any]
FromRos = Callable[[Any, str], Any]


def ros_type(cls: type) -> type:
    """The generated ``ost_msgs.msg`` class of a message dataclass (same name)."""
    return typing.cast(type, getattr(ros, cls.__name__))


def type_name(cls: type) -> str:
    """``ost_msgs/msg/<Name>``: the interface's full name, as ``ros2 topic list -t`` shows it."""
    return f"ost_msgs/msg/{cls.__name__}"


def _describe(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _ros_class(field_type: str) -> type | None:
    """``ost_msgs/Cell`` (or ``sequence<ost_msgs/Cell>``) → the generated class."""
    inner = field_type.removeprefix("sequence<").removesuffix(">")
    if inner.startswith("ost_msgs/"):
        return typing.cast(type, getattr(ros, inner.split("/")[1]))
    return None


def _converters(hint: Any, field_type: str, where: str) -> tuple[ToRos, FromRos]:
    """(to ROS, from ROS) for one field of the given type hint and ROS field type."""
    if field_type == "ost_msgs/Plan":
        return _plan_to_ros, _plan_from_ros
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return _optional(hint, where)
    if origin is tuple:
        return _tuple(typing.get_args(hint), field_type, where)
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        return _enum(hint)
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        c = _codec(hint)
        return c.to_ros, c.from_ros
    if hint in (int, str, bool):
        return (lambda v: v), (lambda v, w: v)
    if hint is float:
        return float, (lambda v, w: float(v))
    raise TypeError(f"{where}: unsupported field type {hint!r}")


def _optional(hint: Any, where: str) -> tuple[ToRos, FromRos]:
    """``int | None``: -1 is None."""
    if [a for a in typing.get_args(hint) if a is not type(None)] != [int]:
        raise TypeError(f"{where}: unsupported union {hint!r}")

    def from_opt(v: Any, w: str) -> int | None:
        if v < -1:
            raise MessageError(f"{w}: {v} (expected -1 for none, or a value >= 0)")
        return None if v == -1 else int(v)

    return (lambda v: -1 if v is None else v), from_opt


def _tuple(args: tuple[Any, ...], field_type: str, where: str) -> tuple[ToRos, FromRos]:
    target: Any = _ros_class(field_type)
    if len(args) == 2 and args[1] is Ellipsis and field_type.startswith("sequence<"):
        inner = field_type[len("sequence<") : -1]
        if target is not None:  # a sequence of messages
            to_elem, from_elem = _converters(args[0], inner, f"{where}[]")
            return (
                lambda v: [to_elem(x) for x in v],
                lambda v, w: tuple(from_elem(x, f"{w}[{k}]") for k, x in enumerate(v)),
            )
        if args[0] is str:
            return list, lambda v, w: tuple(v)
        code = _ARRAY_CODES[inner]
        # array.array: what the generated setter checks fastest
        return (lambda v: array.array(code, v)), (lambda v, w: tuple(int(x) for x in v))
    if target is not None:  # a fixed tuple onto a message, positionally (Cell, FoundObject)
        names = list(target.get_fields_and_field_types())
        if len(names) != len(args):
            raise TypeError(f"{where}: {args!r} does not fit {field_type}")
        return (
            lambda v: target(**dict(zip(names, v))),
            lambda v, w: tuple(int(getattr(v, n)) for n in names),
        )
    raise TypeError(f"{where}: unsupported tuple {args!r} for {field_type}")


def _enum(hint: type[enum.Enum]) -> tuple[ToRos, FromRos]:
    allowed = ", ".join(str(m.value) for m in hint)

    def from_enum(v: Any, w: str) -> Any:
        try:
            return hint(v)
        except ValueError:
            raise MessageError(f"{w}: {_describe(v)} is not one of {allowed}") from None

    return (lambda v: v.value), from_enum


def _plan_to_ros(plan: Sequence[PlanStep]) -> Any:
    """A plan as ``ost_msgs/Plan``: its columns, no message object per step."""
    p = PlanColumns.of(plan)
    return ros.Plan(**{name: getattr(p, name) for name in PlanColumns.COLUMNS})


def _plan_from_ros(msg: Any, where: str) -> PlanColumns:
    """The columns as they came (:class:`PlanColumns` checks them): steps are built only where
    read — the world reads a plan only as far as it skips."""
    try:
        return PlanColumns(**{name: getattr(msg, name) for name in PlanColumns.COLUMNS})
    except ValueError as exc:
        raise MessageError(f"{where}.{exc}") from None


@dataclasses.dataclass
class _Codec:
    cls: type
    target: type
    fields: list[tuple[str, ToRos, FromRos]]

    def to_ros(self, value: Any, **extra: Any) -> Any:
        msg = self.target()
        for name, to, _ in self.fields:
            setattr(msg, name, to(getattr(value, name)))
        for name, v in extra.items():
            setattr(msg, name, v)
        return msg

    def from_ros(self, msg: Any, where: str) -> Any:
        kwargs = {name: frm(getattr(msg, name), f"{where}.{name}") for name, _, frm in self.fields}
        try:
            return self.cls(**kwargs)
        except (TypeError, ValueError) as exc:  # a class's own __post_init__ checks
            raise MessageError(f"{where}: {exc}") from None


_CODECS: dict[type, _Codec] = {}


def _codec(cls: type) -> _Codec:
    known = _CODECS.get(cls)
    if known is not None:
        return known
    target: Any = ros_type(cls)
    types_ = target.get_fields_and_field_types()
    module = __import__(cls.__module__, fromlist=["_"])
    hints = typing.get_type_hints(cls, globalns=dict(vars(module)))
    fields = []
    for f in dataclasses.fields(cls):
        if f.name in _NOT_ON_WIRE or any(issubclass(cls, c) and f.name == n for c, n in _WORLD_FIELDS):
            continue
        if f.name not in types_:
            raise TypeError(f"{cls.__name__}.{f.name}: no such field in {type_name(cls)}")
        to, frm = _converters(hints[f.name], types_[f.name], f"{cls.__name__}.{f.name}")
        fields.append((f.name, to, frm))
    _CODECS[cls] = c = _Codec(cls, target, fields)
    return c


# ----------------------------------------------------------------------------- public


def to_ros(value: Any, run: str | None = None) -> Any:
    """The ``ost_msgs`` message of a dataclass, or of a :class:`Sample` (with ``run``/``seq``);
    ``run``: the run id of a realtime message."""
    if isinstance(value, Sample):
        return _codec(type(value.message)).to_ros(
            value.message, run=value.run, step=value.step, seq=value.seq
        )
    if run is not None:
        return _codec(type(value)).to_ros(value, run=run)
    return _codec(type(value)).to_ros(value)


def from_ros(msg: Any) -> Any:
    """The dataclass of an ``ost_msgs`` message (a :class:`Sample` for a protocol message)."""
    cls = _BY_ROS.get(type(msg))
    if cls is None:
        raise MessageError(f"{type(msg).__name__}: not an ost_msgs message this runtime knows")
    tag = getattr(cls, "TYPE", cls.__name__)
    value = _codec(cls).from_ros(msg, tag)
    if cls in PROTOCOL_MESSAGES:
        return Sample(value, int(msg.step), int(msg.seq), msg.run)
    return value


def to_ros_cell(cell: tuple[int, int]) -> Any:
    """A cell as ``ost_msgs/Cell``."""
    return ros.Cell(x=int(cell[0]), y=int(cell[1]))


def from_ros_value(cls: type, msg: Any, where: str) -> Any:
    """A nested message (an ``ost_msgs/ObjectInfo`` in a service's answer, say) as its dataclass."""
    return _codec(cls).from_ros(msg, where)


def round_trip(value: Any) -> Any:
    """A message as a receiver gets it: through its ``ost_msgs`` interface and back (the
    lockstep in one process, ``ost_ros.lockstep.inprocess``, with ``carry=round_trip``)."""
    return from_ros(to_ros(value))


def sender_of(msg: Any) -> str:
    """Who a (possibly invalid) message claims to be from, for warnings."""
    try:
        who = auth.claimed_signer(msg)
    except AttributeError:
        who = None
    return "unknown" if not isinstance(who, int) else auth.signer_name(who)


_BY_ROS: dict[type, type] = {}
for _cls in (*PROTOCOL_MESSAGES, *RUNTIME_MESSAGES, *REALTIME_MESSAGES):
    _BY_ROS[ros_type(_cls)] = _cls
    _codec(_cls)
