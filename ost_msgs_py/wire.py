"""The message dataclasses on the ROS wire: conversion to and from the ``ost_msgs`` interfaces.

Two ways: to and from the generated message classes (:func:`to_ros`, :func:`from_ros`: what tools
and a realtime robot's action carry), and to and from the CDR bytes DDS carries, without a
generated object (:func:`to_cdr`, :func:`decode`, :func:`from_cdr`; the codec is :mod:`.cdr`):
every message a node publishes or receives, every recorded one read back. Both go through the
same converters, built for each target: the generated classes or their light twins.

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
``acted.action.kind: 'jump' is not one of wait, move, carry`` (the field paths are built only
for a message that fails: a receiver converts thousands a second).
"""

from __future__ import annotations

import array
import dataclasses
import enum
import functools
import operator
import types
import typing
from collections.abc import Callable, Sequence
from typing import Any

import ost_msgs.msg as ros

from ost_msgs_py import auth, cdr
from ost_msgs_py.errors import MessageError
from ost_ros import protocols
from ost_ros.lockstep import messages as _runtime
from ost_ros.lockstep.messages import PlanColumns, PlanStep, Sample
from ost_ros.messages import AgentLost
from ost_ros.realtime.messages import (
    Back,
    BaseClock,
    BaseEvent,
    BaseGoal,
    BaseStopped,
    Digest,
    Hello,
    Lost,
    Mark,
    Need,
    RtStatus,
    StopBase,
)

# Agent-to-agent messages (every kind a registered protocol broadcasts, and a survivor's status
# without a barrier) travel as Samples; the world's notices (AgentLost) only inside Tick/RunEnd.
PROTOCOL_MESSAGES: tuple[type, ...] = (*protocols.messages(), RtStatus, Back)
RUNTIME_MESSAGES: tuple[type, ...] = _runtime.RUNTIME_MESSAGES
# What realtime runs say besides (docs/realtime.md): watermarks, requests for them, the world's
# stamped failure notices, coordination digests, a robot's detections. Each has a ``run`` field
# on the wire that the node sets and checks (:func:`to_ros` ``run=``).
REALTIME_MESSAGES: tuple[type, ...] = (
    Mark,
    Need,
    Lost,
    Hello,
    Digest,
    BaseEvent,
    BaseClock,
    BaseGoal,
    StopBase,
    BaseStopped,
)
_NOT_ON_WIRE = {"version"}
_WORLD_FIELDS = {(AgentLost, "sender")}  # always WORLD: implied by the message kind

_ARRAY_CODES = {"int32": "i", "uint32": "I", "int64": "q", "uint64": "Q"}

ToRos = Callable[[Any], Any]
# (value, where): ``where`` names the field for an error, or is None on the first attempt — the
# field paths are then built only for a message that fails (:func:`_from`)
FromRos = Callable[[Any, "str | None"], Any]


def ros_type(cls: type) -> type:
    """The generated ``ost_msgs.msg`` class of a message dataclass (same name)."""
    return typing.cast(type, getattr(ros, cls.__name__))


def type_name(cls: type) -> str:
    """``ost_msgs/msg/<Name>``: the interface's full name, as ``ros2 topic list -t`` shows it."""
    return f"ost_msgs/msg/{cls.__name__}"


def _describe(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _target(name: str, light: bool) -> type:
    """The class a converter builds: the generated one, or its light twin (:mod:`.cdr`)."""
    generated = typing.cast(type, getattr(ros, name))
    return cdr.message_class(generated) if light else generated


def _ros_class(field_type: str, light: bool) -> type | None:
    """``ost_msgs/Cell`` (or ``sequence<ost_msgs/Cell>``) → the class it is built as."""
    inner = field_type.removeprefix("sequence<").removesuffix(">")
    if inner.startswith("ost_msgs/"):
        return _target(inner.split("/")[1], light)
    return None


def _as_it_is(v: Any, w: str | None) -> Any:
    return v


def _converters(hint: Any, field_type: str, where: str, light: bool) -> tuple[ToRos, FromRos]:
    """(to ROS, from ROS) for one field of the given type hint and ROS field type."""
    if field_type == "ost_msgs/Plan":
        return _plan_to(_target("Plan", light)), _plan_from_ros
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return _optional(hint, where)
    if origin is tuple:
        return _tuple(typing.get_args(hint), field_type, where, light)
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        return _enum(hint)
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        c = _codec(hint, light)
        return c.to_ros, c.from_ros
    if hint in (int, str, bool):
        return (lambda v: v), _as_it_is
    if hint is float:
        return float, (lambda v, w: float(v))
    raise TypeError(f"{where}: unsupported field type {hint!r}")


def _optional(hint: Any, where: str) -> tuple[ToRos, FromRos]:
    """``int | None``: -1 is None."""
    if [a for a in typing.get_args(hint) if a is not type(None)] != [int]:
        raise TypeError(f"{where}: unsupported union {hint!r}")

    def from_opt(v: Any, w: str | None) -> int | None:
        if v < -1:
            raise MessageError(f"{w}: {v} (expected -1 for none, or a value >= 0)")
        return None if v == -1 else int(v)

    return (lambda v: -1 if v is None else v), from_opt


def _tuple(args: tuple[Any, ...], field_type: str, where: str, light: bool) -> tuple[ToRos, FromRos]:
    target: Any = _ros_class(field_type, light)
    if len(args) == 2 and args[1] is Ellipsis and field_type.startswith("sequence<"):
        inner = field_type[len("sequence<") : -1]
        if target is not None:  # a sequence of messages
            to_elem, from_elem = _converters(args[0], inner, f"{where}[]", light)

            def from_seq(v: Any, w: str | None) -> tuple[Any, ...]:
                if w is None:
                    return tuple([from_elem(x, None) for x in v])
                return tuple(from_elem(x, f"{w}[{k}]") for k, x in enumerate(v))

            return (lambda v: [to_elem(x) for x in v]), from_seq
        if args[0] is str:
            return list, lambda v, w: tuple(v)
        code = _ARRAY_CODES[inner]
        # array.array: what the generated setter checks fastest, and the CDR encoder copies as is
        return (lambda v: array.array(code, v)), (lambda v, w: tuple(v))
    if target is not None:  # a fixed tuple onto a message, positionally (Cell, FoundObject)
        names = list(target.get_fields_and_field_types()) if not light else list(target.__slots__)
        if len(names) != len(args) or len(names) < 2:
            raise TypeError(f"{where}: {args!r} does not fit {field_type}")
        get = operator.attrgetter(*names)  # (a tuple of the fields' ints)
        if light:
            return (lambda v: target(*v)), (lambda v, w: get(v))
        return (lambda v: target(**dict(zip(names, v)))), (lambda v, w: tuple(map(int, get(v))))
    raise TypeError(f"{where}: unsupported tuple {args!r} for {field_type}")


def _enum(hint: type[enum.Enum]) -> tuple[ToRos, FromRos]:
    allowed = ", ".join(str(m.value) for m in hint)
    members = {m.value: m for m in hint}

    def from_enum(v: Any, w: str | None) -> Any:
        m = members.get(v)
        if m is None:
            raise MessageError(f"{w}: {_describe(v)} is not one of {allowed}")
        return m

    return (lambda v: v.value), from_enum


def _plan_to(target: type) -> ToRos:
    """A plan as ``ost_msgs/Plan``: its columns, no message object per step."""

    def to(plan: Sequence[PlanStep]) -> Any:
        p = PlanColumns.of(plan)
        return target(**{name: getattr(p, name) for name in PlanColumns.COLUMNS})

    return to


def _plan_from_ros(msg: Any, where: str | None) -> PlanColumns:
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
    light: bool
    from_ros: FromRos = dataclasses.field(init=False)  # (value, where) -> the dataclass

    def __post_init__(self) -> None:
        self.from_ros = _compiled_from(self.cls, self.fields)

    def to_ros(self, value: Any, **extra: Any) -> Any:
        if self.light:  # light classes take every field as a keyword
            kwargs = {name: to(getattr(value, name)) for name, to, _ in self.fields}
            return self.target(**kwargs, **extra)
        msg = self.target()
        for name, to, _ in self.fields:
            setattr(msg, name, to(getattr(value, name)))
        for name, v in extra.items():
            setattr(msg, name, v)
        return msg


def _compiled_from(cls: type, fields: list[tuple[str, ToRos, FromRos]]) -> FromRos:
    """``from_ros`` of one dataclass as generated source: each field read by name, converted only
    if it needs it (most ints and strings do not), the field path built only for an error. It
    runs for every message a node receives."""
    env: dict[str, Any] = {"cls": cls, "MessageError": MessageError}
    lines = ["def from_ros(msg, where):"]
    for k, (name, _, frm) in enumerate(fields):
        if frm is _as_it_is:
            lines.append(f"    a{k} = msg.{name}")
        else:
            env[f"f{k}"] = frm
            lines.append(f"    a{k} = f{k}(msg.{name}, where and where + {'.' + name!r})")
    kwargs = ", ".join(f"{name}=a{k}" for k, (name, _, _) in enumerate(fields))
    lines += [
        "    try:",
        f"        return cls({kwargs})",
        "    except (TypeError, ValueError) as exc:  # a class's own __post_init__ checks",
        '        raise MessageError(f"{where}: {exc}") from None',
    ]
    exec("\n".join(lines), env)  # our own generated source, nothing from outside
    return typing.cast(FromRos, env["from_ros"])


_CODECS: dict[tuple[type, bool], _Codec] = {}


def _codec(cls: type, light: bool = False) -> _Codec:
    known = _CODECS.get((cls, light))
    if known is not None:
        return known
    target: Any = _target(cls.__name__, light)
    types_ = ros_type(cls).get_fields_and_field_types()  # type: ignore[attr-defined]
    hints = _hints(cls)
    fields = []
    for f in dataclasses.fields(cls):
        if f.name in _NOT_ON_WIRE or any(issubclass(cls, c) and f.name == n for c, n in _WORLD_FIELDS):
            continue
        if f.name not in types_:
            raise TypeError(f"{cls.__name__}.{f.name}: no such field in {type_name(cls)}")
        to, frm = _converters(hints[f.name], types_[f.name], f"{cls.__name__}.{f.name}", light)
        fields.append((f.name, to, frm))
    _CODECS[(cls, light)] = c = _Codec(cls, target, fields, light)
    return c


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    """A dataclass's type hints (both targets' codecs read them)."""
    module = __import__(cls.__module__, fromlist=["_"])
    return typing.get_type_hints(cls, globalns=dict(vars(module)))


@dataclasses.dataclass(frozen=True)
class _Reader:
    """How a received message (generated or light) becomes its dataclass."""

    from_ros: FromRos
    where: str  # the message's name in errors: its TYPE (``acted``)
    sample: bool  # a protocol message: a Sample

    def read(self, msg: Any) -> Any:
        # no field path built; again with them if the message fails, so that the error names
        # its field (``acted.action.kind: ...``)
        try:
            value = self.from_ros(msg, None)
        except MessageError:
            value = self.from_ros(msg, self.where)
        if self.sample:
            return Sample(value, int(msg.step), int(msg.seq), msg.run, int(msg.watermark))
        return value


# ----------------------------------------------------------------------------- public


def to_ros(value: Any, run: str | None = None) -> Any:
    """The ``ost_msgs`` message of a dataclass, or of a :class:`Sample` (with ``run``/``seq``);
    ``run``: the run id of a realtime message."""
    return _to(value, run, light=False)


def _to(value: Any, run: str | None, light: bool) -> Any:
    if isinstance(value, Sample):
        return _codec(type(value.message), light).to_ros(
            value.message, run=value.run, step=value.step, seq=value.seq, watermark=value.watermark
        )
    if run is not None:
        return _codec(type(value), light).to_ros(value, run=run)
    return _codec(type(value), light).to_ros(value)


def from_ros(msg: Any) -> Any:
    """The dataclass of an ``ost_msgs`` message — generated or light (:func:`decode`) — (a
    :class:`Sample` for a protocol message)."""
    reader = _BY_ROS.get(type(msg))
    if reader is None:
        cls = _GENERATED.get(type(msg))
        if cls is None:
            raise MessageError(f"{type(msg).__name__}: not an ost_msgs message this runtime knows")
        reader = _BY_ROS[type(msg)] = _reader(cls, light=False)  # (the generated classes' codecs
        # are built when first used: the nodes' messages go through the light ones)
    return reader.read(msg)


def to_cdr(value: Any, run: str | None = None, counter: int = 0, signer: int = 0, tags: int = 0) -> bytearray:
    """A dataclass (or :class:`Sample`) as the CDR bytes of its interface, as DDS carries them,
    without a generated message object (:mod:`.cdr`). Its ``auth``: ``counter``, ``signer`` and
    ``tags`` zero bytes, which the sealer fills in place (:class:`ost_msgs_py.auth.Sealer`)."""
    msg = _to(value, run, light=True)
    msg.auth = _AUTH(counter=counter, signer=signer, tags=bytes(tags))
    return cdr.encode(msg)


def decoder(kind: type) -> Callable[[bytes | bytearray], tuple[Any, int]]:
    """:func:`decode` for one message dataclass's interface, its classes looked up once (what a
    subscription holds)."""
    return functools.partial(cdr.decode, ros_type(kind))


def decode(kind: type | str, data: bytes | bytearray) -> tuple[Any, int]:
    """The light message in CDR ``data`` of the interface of ``kind`` (a message dataclass or an
    interface name, ``ost_msgs/msg/Tick``) and where its bytes ended; :class:`MessageError` if
    they are not one."""
    if isinstance(kind, str):
        package, _, name = kind.partition("/msg/")
        generated = getattr(ros, name, None) if package == "ost_msgs" else None
        if generated is None or generated not in _GENERATED:
            raise MessageError(f"{kind}: not an ost_msgs message this runtime knows")
    else:
        generated = ros_type(kind)
    return cdr.decode(generated, data)


def from_cdr(kind: type | str, data: bytes | bytearray) -> Any:
    """The dataclass in CDR ``data`` (a :class:`Sample` for a protocol message): :func:`decode`,
    then :func:`from_ros`."""
    return from_ros(decode(kind, data)[0])


def to_ros_cell(cell: tuple[int, int]) -> Any:
    """A cell as ``ost_msgs/Cell``."""
    return ros.Cell(x=int(cell[0]), y=int(cell[1]))


def from_ros_value(cls: type, msg: Any, where: str) -> Any:
    """A nested message (an ``ost_msgs/ObjectInfo`` in a service's answer, say) as its dataclass."""
    return _codec(cls).from_ros(msg, where)


def round_trip(value: Any) -> Any:
    """A message as a receiver gets it: through the CDR bytes of its ``ost_msgs`` interface and
    back (the lockstep in one process, ``ost_ros.lockstep.inprocess``, with ``carry=round_trip``)."""
    kind = type(value.message) if isinstance(value, Sample) else type(value)
    return from_cdr(kind, to_cdr(value))


def sender_of(msg: Any) -> str:
    """Who a (possibly invalid) message claims to be from, for warnings."""
    try:
        who = auth.claimed_signer(msg)
    except AttributeError:
        who = None
    return "unknown" if not isinstance(who, int) else auth.signer_name(who)


def _reader(cls: type, light: bool) -> _Reader:
    return _Reader(_codec(cls, light).from_ros, getattr(cls, "TYPE", cls.__name__), cls in PROTOCOL_MESSAGES)


_AUTH = cdr.message_class(ros.Auth)
# Every dataclass's light codec is built now (a field missing from its interface fails at import).
_GENERATED: dict[type, type] = {}  # generated class -> dataclass
_BY_ROS: dict[type, _Reader] = {}  # light (and, once used, generated) class -> its reader
for _cls in (*PROTOCOL_MESSAGES, *RUNTIME_MESSAGES, *REALTIME_MESSAGES):
    _GENERATED[ros_type(_cls)] = _cls
    _BY_ROS[cdr.message_class(ros_type(_cls))] = _reader(_cls, light=True)
