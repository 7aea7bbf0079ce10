"""Strict JSON codec for the message dataclasses (carried in ``std_msgs/msg/String`` on the wire).

Generic over every registered dataclass: the wire form of a message is a JSON object with its
``type`` tag and exactly its dataclass fields, each checked against the field's type hint. So a
new message class (HCP, faults, ...) needs no codec code — only :func:`register` (the classes of
:data:`ost_msgs_py.messages.ALL_MESSAGES` and :mod:`ost_msgs_py.runtime` are registered here).

Supported field types: ``int``, ``float``, ``str``, ``bool``, ``str`` enums, nested frozen
dataclasses, ``tuple[T, ...]``, fixed ``tuple[A, B]``, ``X | None``, and :data:`AnyMessage`
(any registered message, tagged with its ``type``). Anything invalid raises :class:`MessageError`
naming the field path, e.g. ``observation.sensed[2].location[0]: expected an integer, got 'a'``.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import types
import typing
from typing import Any

from ost_msgs_py import messages as _messages
from ost_msgs_py import runtime as _runtime
from ost_msgs_py.runtime import AnyMessage

# Large enough for a final report of a 200-object run, small enough that a hostile 1 GB string
# is refused before json.loads touches it.
MAX_BYTES = 1 << 20


class MessageError(ValueError):
    """An invalid message; the text names the offending field."""


REGISTRY: dict[str, type] = {}
_HINTS: dict[type, dict[str, Any]] = {}


def register(cls: type) -> type:
    """Make a message dataclass (with ``TYPE`` and a ``version`` field) known to the codec."""
    if not dataclasses.is_dataclass(cls) or not hasattr(cls, "TYPE"):
        raise TypeError(f"{cls!r} is not a message dataclass with a TYPE tag")
    known = REGISTRY.get(cls.TYPE)
    if known is not None and known is not cls:
        raise TypeError(f"message type {cls.TYPE!r} registered twice ({known.__name__}, {cls.__name__})")
    REGISTRY[cls.TYPE] = cls
    return cls


def _hints(cls: type) -> dict[str, Any]:
    hints = _HINTS.get(cls)
    if hints is None:
        module = __import__(cls.__module__, fromlist=["_"])
        ns = dict(vars(module))
        ns["AnyMessage"] = AnyMessage
        hints = typing.get_type_hints(cls, globalns=ns)
        _HINTS[cls] = hints
    return hints


def _version_of(cls: type) -> int | None:
    for f in dataclasses.fields(cls):
        if f.name == "version" and isinstance(f.default, int):
            return f.default
    return None


# ----------------------------------------------------------------------------- encoding


def _to_json(value: Any) -> Any:
    if isinstance(value, enum.Enum):
        return value.value
    if dataclasses.is_dataclass(value):
        out = {"type": value.TYPE} if hasattr(value, "TYPE") else {}
        for f in dataclasses.fields(value):
            out[f.name] = _to_json(getattr(value, f.name))
        return out
    if isinstance(value, (tuple, list)):
        return [_to_json(v) for v in value]
    return value


def to_dict(msg: Any) -> dict[str, Any]:
    """The JSON-ready dict of a registered message (``type`` first, then its fields)."""
    if type(msg).__dict__.get("TYPE") is None or REGISTRY.get(msg.TYPE) is not type(msg):
        raise MessageError(f"{type(msg).__name__} is not a registered message")
    return _to_json(msg)


def encode(msg: Any) -> str:
    """Compact JSON text of a registered message."""
    text = json.dumps(to_dict(msg), separators=(",", ":"))
    if len(text.encode()) > MAX_BYTES:
        raise MessageError(f"{msg.TYPE}: encoded size {len(text.encode())} exceeds {MAX_BYTES} bytes")
    return text


# ----------------------------------------------------------------------------- decoding


def _describe(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# Scalar field types: (accepts the JSON value, what was expected, the Python value).
_SCALARS: dict[type, tuple[Any, str, Any]] = {
    bool: (lambda v: isinstance(v, bool), "true/false", lambda v: v),
    int: (lambda v: isinstance(v, int) and not isinstance(v, bool), "an integer", lambda v: v),
    float: (lambda v: isinstance(v, (int, float)) and not isinstance(v, bool), "a number", float),
    str: (lambda v: isinstance(v, str), "a string", lambda v: v),
}


def _from_json(value: Any, hint: Any, where: str) -> Any:
    if hint is AnyMessage:
        return _message(value, None, where)
    if hint is Any:
        return value
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return _union(value, typing.get_args(hint), where)
    if origin is tuple:
        return _tuple(value, typing.get_args(hint), where)
    if hint in _SCALARS:
        accepts, expected, convert = _SCALARS[hint]
        if not accepts(value):
            raise MessageError(f"{where}: expected {expected}, got {_describe(value)}")
        return convert(value)
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        try:
            return hint(value)
        except ValueError:
            allowed = ", ".join(str(m.value) for m in hint)
            raise MessageError(f"{where}: {_describe(value)} is not one of {allowed}") from None
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        if hasattr(hint, "TYPE"):  # a nested message keeps its type tag and version
            return _message(value, (hint,), where)
        return _fields(value, hint, where)
    raise MessageError(f"{where}: unsupported field type {hint!r}")


def _union(value: Any, options: tuple[Any, ...], where: str) -> Any:
    if value is None and type(None) in options:
        return None
    errors = []
    for opt in options:
        if opt is type(None):
            continue
        try:
            return _from_json(value, opt, where)
        except MessageError as exc:
            errors.append(str(exc))
    raise MessageError(
        errors[0]
        if len(errors) == 1
        else f"{where}: {_describe(value)} fits none of "
        f"{', '.join(getattr(o, '__name__', str(o)) for o in options)}"
    )


def _tuple(value: Any, args: tuple[Any, ...], where: str) -> tuple[Any, ...]:
    if not isinstance(value, list):
        raise MessageError(f"{where}: expected a list, got {_describe(value)}")
    if len(args) == 2 and args[1] is Ellipsis:
        return tuple(_from_json(v, args[0], f"{where}[{k}]") for k, v in enumerate(value))
    if len(value) != len(args):
        raise MessageError(f"{where}: expected {len(args)} items, got {len(value)}")
    return tuple(_from_json(v, a, f"{where}[{k}]") for k, (v, a) in enumerate(zip(value, args)))


def _fields(value: Any, cls: type, where: str, skip: tuple[str, ...] = ()) -> Any:
    if not isinstance(value, dict):
        raise MessageError(f"{where}: expected an object, got {_describe(value)}")
    hints = _hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key in value:
        if key not in fields and key not in skip:
            raise MessageError(f"{where}.{key}: unknown field (allowed: {', '.join(fields)})")
    kwargs = {}
    for name, f in fields.items():
        if name not in value:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise MessageError(f"{where}.{name}: missing")
            continue
        kwargs[name] = _from_json(value[name], hints[name], f"{where}.{name}")
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:  # a class's own __post_init__ checks
        raise MessageError(f"{where}: {exc}") from None


def _message(data: Any, expected: tuple[type[Any], ...] | None, where: str) -> Any:
    if not isinstance(data, dict):
        raise MessageError(f"{where}: expected a JSON object, got {_describe(data)}")
    tag = data.get("type")
    cls = REGISTRY.get(tag) if isinstance(tag, str) else None
    if cls is None:
        raise MessageError(f"{where}.type: unknown message type {_describe(tag)}")
    if expected is not None and cls not in expected:
        names = ", ".join(c.TYPE for c in expected)
        raise MessageError(f"{where}.type: {tag!r} not accepted here (expected {names})")
    where = str(tag) if where == "message" else where
    want = _version_of(cls)
    if want is not None:
        if "version" not in data:
            raise MessageError(f"{where}.version: missing")
        if data["version"] != want or isinstance(data["version"], bool):
            raise MessageError(
                f"{where}.version: unsupported version {_describe(data['version'])} "
                f"of {tag} (expected {want})"
            )
    return _fields(data, cls, where, skip=("type",))


def decode(text: str | bytes, expected: type[Any] | tuple[type[Any], ...] | None = None) -> Any:
    """Parse and validate one message; ``expected`` restricts the accepted classes."""
    if isinstance(text, str):
        size = len(text.encode("utf-8", "surrogatepass"))
    else:
        size = len(text)
    if size > MAX_BYTES:
        raise MessageError(f"message: size {size} exceeds {MAX_BYTES} bytes")
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise MessageError(f"message: invalid JSON ({exc})") from None
    except RecursionError:
        raise MessageError("message: JSON nested too deeply") from None
    if isinstance(expected, type):
        expected = (expected,)
    return _message(data, expected, "message")


def sender_of(text: str) -> str:
    """Best-effort ``sender``/``agent`` of a (possibly invalid) message, for warnings."""
    try:
        data = json.loads(text) if len(text) <= MAX_BYTES else None
    except (ValueError, RecursionError):
        return "unknown"
    if isinstance(data, dict):
        for key in ("sender", "agent"):
            v = data.get(key)
            if isinstance(v, int) and not isinstance(v, bool):
                return f"agent {v}"
    return "unknown"


for _cls in (*_messages.ALL_MESSAGES.values(), *_runtime.RUNTIME_MESSAGES):
    register(_cls)
