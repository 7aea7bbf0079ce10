"""The ``ost_msgs`` interfaces as bytes without rclpy: a direct CDR codec, compiled per interface.

A receiver that lets rclpy deserialise a sample pays for the generated message classes — ~30 µs
for a small message with a nested ``Auth``, ~7 µs to build one to send — more than everything
else it does with the sample. The interfaces are ours and few, so each is compiled once, from its
generated class's ``get_fields_and_field_types()`` and those of its nested types, into a Python
encoder and decoder over :mod:`struct` (generated source, so a run of fixed-size fields is one
``struct`` call). The bytes are those rclpy and Fast CDR make and read (XCDR1, plain CDR,
little-endian); ``tests/ost_msgs_py/test_cdr.py`` checks both directions against rclpy's
``serialize_message``/``deserialize_message`` for every interface the wire knows:

- a 4-byte encapsulation header ``00 01 00 00``, then the fields in declaration order;
- each primitive aligned to its size (at most 8) counted from the first byte after the header;
  padding is written as zeros and never read (Fast CDR leaves whatever was in its buffer there);
- a string: uint32 length including the NUL, the UTF-8 bytes, the NUL (rclpy's C strings end at
  a NUL inside the text; this codec keeps the text whole);
- a sequence: uint32 count, then its elements; a sequence of primitives is aligned to the
  element size once, and only when it has elements (as Fast CDR does);
- a nested message inline, aligned by its own fields.

Decoded messages are light objects (:func:`message_class`: per interface one slotted class with
the generated class's name and fields), numeric sequences as :class:`array.array` of the same
type codes rclpy uses, boolean sequences as lists, string sequences as lists. Bytes past the
last field are not read (:func:`decode` says where the message ended).
"""

from __future__ import annotations

import array
import importlib
import struct
import sys
import typing
from collections.abc import Callable
from typing import Any

from ost_msgs_py.errors import MessageError

HEADER = b"\x00\x01\x00\x00"  # CDR, little-endian; no options
# ROS type -> (struct code, size); array.array uses the same codes (booleans as bytes)
_PRIMITIVES = {
    "boolean": ("?", 1), "uint8": ("B", 1), "int8": ("b", 1), "uint16": ("H", 2), "int16": ("h", 2),
    "uint32": ("I", 4), "int32": ("i", 4), "uint64": ("Q", 8), "int64": ("q", 8),
    "float": ("f", 4), "double": ("d", 8),
}  # fmt: skip
for _code, _size in _PRIMITIVES.values():
    if _code != "?" and array.array(_code).itemsize != _size:  # (every platform ROS 2 runs on)
        raise ImportError(f"array type code {_code!r} is not {_size} bytes here")
_SWAP = sys.byteorder == "big"  # arrays are little-endian on the wire
_DEFAULTS = {"boolean": "False", "float": "0.0", "double": "0.0", "string": "''"}

Decoder = Callable[[bytes | bytearray, int, int], tuple[Any, int]]
Encoder = Callable[[Any, bytearray], None]


class Light:
    """Base of the light message classes: slots, equality by fields, a readable repr."""

    __slots__ = ()

    def __eq__(self, other: object) -> bool:
        names: tuple[str, ...] = self.__slots__
        return type(other) is type(self) and all(getattr(self, f) == getattr(other, f) for f in names)

    def __repr__(self) -> str:
        names: tuple[str, ...] = self.__slots__
        inner = ", ".join(f"{f}={getattr(self, f)!r}" for f in names)
        return f"{type(self).__name__}({inner})"

    __hash__ = None  # type: ignore[assignment]  # mutable, as the generated classes


_LIGHT: dict[type, type] = {}  # generated class -> light class
_ROS: dict[type, type] = {}  # light class -> generated class
_DECODERS: dict[type, Decoder] = {}  # light class -> decoder
_ENCODERS: dict[type, Encoder] = {}  # light class -> encoder
_PENDING: set[type] = set()  # being compiled (a type nesting itself is not an interface)


def _nested(field_type: str) -> type:
    """``pkg/Name`` -> the generated class."""
    package, _, name = field_type.partition("/")
    return typing.cast(type, getattr(importlib.import_module(f"{package}.msg"), name))


def _kind(field_type: str) -> tuple[str, str]:
    """('prim'|'string'|'message', inner) and ('seq-…', inner) for a sequence; TypeError for
    what no interface of ours uses (bounded, fixed-size, wide, char and byte types)."""
    if field_type.startswith("sequence<") and field_type.endswith(">"):
        inner = field_type[len("sequence<") : -1]
        kind, _ = _kind(inner)
        return f"seq-{kind}", inner
    if field_type in _PRIMITIVES:
        return "prim", field_type
    if field_type == "string":
        return "string", field_type
    if "/" in field_type and "<" not in field_type and "[" not in field_type:
        return "message", field_type
    raise TypeError(f"no CDR codec for the field type {field_type!r}")


def message_class(cls: type) -> type:
    """The light class of a generated message class (built once); a light class is its own."""
    light = _LIGHT.get(cls)
    if light is None:
        light = _compile(cls)
    return light


def ros_class(light: type) -> type:
    """The generated class a light class stands for."""
    return _ROS[light]


def encode(msg: Any) -> bytearray:
    """A light message as CDR bytes, header included."""
    out = bytearray(HEADER)
    try:
        _ENCODERS[type(msg)](msg, out)
    except KeyError:
        raise MessageError(f"{type(msg).__name__}: not a light ost_msgs message") from None
    except (struct.error, OverflowError, TypeError, ValueError, AttributeError) as exc:
        raise MessageError(f"{type(msg).__name__}: cannot be encoded ({exc})") from None
    return out


def decode(cls: type, data: bytes | bytearray) -> tuple[Any, int]:
    """The light message of class ``cls`` (light or generated) in ``data`` and where it ended.
    :class:`MessageError` for bytes that are not such a message (truncated, another encoding)."""
    decoder = _DECODERS[message_class(cls)]
    if data[:2] != HEADER[:2]:
        raise MessageError(f"{cls.__name__}: not little-endian plain CDR (header {bytes(data[:4]).hex()})")
    try:
        return decoder(data, 4, len(data))
    except (struct.error, IndexError, _Short):
        raise MessageError(f"{cls.__name__}: truncated ({len(data)} bytes)") from None
    except UnicodeDecodeError:
        raise MessageError(f"{cls.__name__}: a string that is not UTF-8") from None


class _Short(Exception):
    """A length or count that runs past the end of the bytes."""


# ----------------------------------------------------------------------------- compilation


class _Source:
    """Generated source: lines, constants it refers to, fresh variable names."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.env: dict[str, Any] = {"_Short": _Short, "array": array.array, "U32": struct.Struct("<I")}
        self.count = 0

    def var(self, stem: str = "v") -> str:
        self.count += 1
        return f"{stem}{self.count}"

    def const(self, value: Any, stem: str) -> str:
        for name, known in self.env.items():
            if known is value or (
                isinstance(value, struct.Struct) and getattr(known, "format", None) == value.format
            ):
                return name
        name = self.var(stem)
        self.env[name] = value
        return name

    def emit(self, indent: int, line: str) -> None:
        self.lines.append("    " * indent + line)

    def function(self, name: str) -> Callable[..., Any]:
        exec("\n".join(self.lines), self.env)  # our own generated source, nothing from outside
        return typing.cast(Callable[..., Any], self.env[name])


class _Align:
    """What is known of the position: (position - 4) ≡ rest (mod modulus)."""

    def __init__(self, modulus: int = 1, rest: int = 0):
        self.modulus, self.rest = modulus, rest

    def pad(self, size: int) -> int | None:
        """Padding before a primitive of ``size`` bytes, if known here."""
        if self.modulus >= size:
            return (-self.rest) % size
        return None

    def advance(self, n: int) -> None:
        self.rest = (self.rest + n) % self.modulus

    def set(self, modulus: int) -> None:
        self.modulus, self.rest = modulus, 0


def _runtime_align(size: int, pos: str) -> str:
    """Source aligning ``pos`` (absolute, after the 4-byte header) to ``size``."""
    # (pos - 4) aligned to size: 4 and 2 divide the header, 8 does not
    return {8: f"{pos} += (4 - {pos}) & 7", 4: f"{pos} += -{pos} & 3", 2: f"{pos} += {pos} & 1"}[size]


def _runtime_pad(size: int) -> str:
    """Source padding ``out`` (the header included) with zeros to ``size``."""
    return {
        8: "out += PAD[(4 - len(out)) & 7]",
        4: "out += PAD[-len(out) & 3]",
        2: "out += PAD[len(out) & 1]",
    }[size]


class _DecoderSource(_Source):
    """A decoder ``def name(data, p, end) -> (message, p)``; runs of fixed-size fields read by one
    ``struct`` call."""

    def __init__(self) -> None:
        super().__init__()
        self.group: list[str] = []  # struct codes, pads as 'x'
        self.names: list[str] = []  # the variables they go to

    def primitive(self, code: str, size: int, align: _Align, indent: int) -> str:
        pad = align.pad(size)
        if pad is None:
            self.flush(indent)
            self.emit(indent, _runtime_align(size, "p"))
            align.set(min(size, 8))
            pad = 0
        self.group.append("x" * pad + code)
        name = self.var()
        self.names.append(name)
        align.advance(pad + size)
        return name

    def flush(self, indent: int) -> None:
        if not self.group:
            return
        s = struct.Struct("<" + "".join(self.group))
        self.emit(indent, f"{', '.join(self.names)}, = {self.const(s, 'S')}.unpack_from(data, p)")
        self.emit(indent, f"p += {s.size}")
        self.group, self.names = [], []

    def fields(self, ros: type, align: _Align, indent: int) -> str:
        """Source reading every field of ``ros`` into variables; the constructor expression."""
        light = message_class(ros)
        args = []
        for field_type in ros.get_fields_and_field_types().values():  # type: ignore[attr-defined]
            args.append(self.field(field_type, align, indent))
        return f"{self.const(light, 'C')}({', '.join(args)})"

    def field(self, field_type: str, align: _Align, indent: int) -> str:
        kind, inner = _kind(field_type)
        if kind == "prim":
            return self.primitive(*_PRIMITIVES[inner], align, indent)
        if kind == "message":
            return self.fields(_nested(inner), align, indent)
        n = self.primitive("I", 4, align, indent)  # a string's length, a sequence's count
        self.flush(indent)
        v = self.var()
        if kind == "string":
            self.emit(indent, f"if {n} > end - p: raise _Short")
            self.emit(indent, f"{v} = data[p:p + {n} - 1].decode() if {n} else ''")
            self.emit(indent, f"p += {n}")
            align.set(1)
        elif kind == "seq-prim":
            code, size = _PRIMITIVES[inner]
            if size == 8:
                self.emit(indent, f"if {n}: {_runtime_align(8, 'p')}")
            self.emit(indent, f"b = p + {n} * {size}")
            self.emit(indent, "if b > end: raise _Short")
            if code == "?":
                self.emit(indent, f"{v} = [x != 0 for x in data[p:b]]")
            else:
                self.emit(indent, f"{v} = array({code!r}, data[p:b])")
                if _SWAP and size > 1:
                    self.emit(indent, f"{v}.byteswap()")
            self.emit(indent, "p = b")
            align.set(min(size, 4))  # after the count: 4-aligned, then n elements
        elif kind == "seq-string":
            self.emit(indent, f"{v} = []")
            self.emit(indent, f"for _ in range({n}):")
            self.emit(indent + 1, _runtime_align(4, "p"))
            self.emit(indent + 1, "m, = U32.unpack_from(data, p)")
            self.emit(indent + 1, "p += 4")
            self.emit(indent + 1, "if m > end - p: raise _Short")
            self.emit(indent + 1, f"{v}.append(data[p:p + m - 1].decode() if m else '')")
            self.emit(indent + 1, "p += m")
            align.set(1)
        else:  # a sequence of messages: each element by its own decoder
            nested = self.const(_decoder(_nested(inner)), "D")
            self.emit(indent, f"{v} = []")
            self.emit(indent, f"for _ in range({n}):")
            self.emit(indent + 1, f"x, p = {nested}(data, p, end)")
            self.emit(indent + 1, f"{v}.append(x)")
            align.set(1)
        return v


class _EncoderSource(_Source):
    """An encoder ``def name(m, out)`` appending the message to ``out``; runs of fixed-size fields
    written by one ``struct`` call."""

    def __init__(self) -> None:
        super().__init__()
        self.group: list[str] = []
        self.values: list[str] = []
        self.env["PAD"] = tuple(bytes(k) for k in range(8))
        self.env["seq"] = _sequence_bytes

    def primitive(self, code: str, size: int, value: str, align: _Align, indent: int) -> None:
        pad = align.pad(size)
        if pad is None:
            self.flush(indent)
            self.emit(indent, _runtime_pad(size))
            align.set(size)
            pad = 0
        self.group.append("x" * pad + code)
        self.values.append(value)
        align.advance(pad + size)

    def flush(self, indent: int) -> None:
        if not self.group:
            return
        s = struct.Struct("<" + "".join(self.group))
        self.emit(indent, f"out += {self.const(s, 'S')}.pack({', '.join(self.values)})")
        self.group, self.values = [], []

    def fields(self, ros: type, value: str, align: _Align, indent: int) -> None:
        for name, field_type in ros.get_fields_and_field_types().items():  # type: ignore[attr-defined]
            self.field(field_type, f"{value}.{name}", align, indent)

    def field(self, field_type: str, value: str, align: _Align, indent: int) -> None:
        kind, inner = _kind(field_type)
        if kind == "prim":
            self.primitive(*_PRIMITIVES[inner], value, align, indent)
            return
        if kind == "message":
            v = self.var("m")
            self.emit(indent, f"{v} = {value}")
            self.fields(_nested(inner), v, align, indent)
            return
        v = self.var()
        if kind == "string":
            self.emit(indent, f"{v} = {value}.encode()")
            self.primitive("I", 4, f"len({v}) + 1", align, indent)
            self.flush(indent)
            self.emit(indent, f"out += {v}")
            self.emit(indent, "out.append(0)")
            align.set(1)
            return
        self.emit(indent, f"{v} = {value}")
        self.primitive("I", 4, f"len({v})", align, indent)
        self.flush(indent)
        if kind == "seq-prim":
            code, size = _PRIMITIVES[inner]
            if size == 8:
                self.emit(indent, f"if {v}: {_runtime_pad(8)}")
            self.emit(indent, f"seq(out, {v}, {code!r})")
            align.set(min(size, 4))
        elif kind == "seq-string":
            self.emit(indent, f"for x in {v}:")
            self.emit(indent + 1, _runtime_pad(4))
            self.emit(indent + 1, "b = x.encode()")
            self.emit(indent + 1, "out += U32.pack(len(b) + 1)")
            self.emit(indent + 1, "out += b")
            self.emit(indent + 1, "out.append(0)")
            align.set(1)
        else:
            nested = self.const(_encoder(_nested(inner)), "E")
            self.emit(indent, f"for x in {v}:")
            self.emit(indent + 1, f"{nested}(x, out)")
            align.set(1)


def _sequence_bytes(out: bytearray, values: Any, code: str) -> None:
    """A sequence of primitives' elements, little-endian (an array of the right code as it is)."""
    if code == "?":
        out += bytes(map(bool, values))
        return
    if not (isinstance(values, array.array) and values.typecode == code) or _SWAP:
        values = array.array(code, values)  # (a copy to swap on a big-endian machine)
    if _SWAP and values.itemsize > 1:
        values.byteswap()
    out += values


def _decoder(ros: type) -> Decoder:
    light = message_class(ros)
    known = _DECODERS.get(light)
    if known is None:
        src = _DecoderSource()
        src.emit(0, "def decode(data, p, end):")
        made = src.fields(ros, _Align(), 1)
        src.flush(1)
        src.emit(1, f"return {made}, p")
        known = _DECODERS[light] = src.function("decode")
    return known


def _encoder(ros: type) -> Encoder:
    light = message_class(ros)
    known = _ENCODERS.get(light)
    if known is None:
        src = _EncoderSource()
        src.emit(0, "def encode(m, out):")
        src.fields(ros, "m", _Align(), 1)
        src.flush(1)
        src.emit(1, "return None")
        known = _ENCODERS[light] = src.function("encode")
    return known


def _compile(ros: type) -> type:
    """The light class of ``ros``, its decoder and its encoder."""
    if ros in _PENDING:
        raise TypeError(f"{ros.__name__}: a message that contains itself")
    _PENDING.add(ros)
    try:
        fields = ros.get_fields_and_field_types()  # type: ignore[attr-defined]
        kinds = {name: _kind(t) for name, t in fields.items()}
        # Defaults as the generated classes have them: zeros, empty, nested defaults.
        src = _Source()
        params, body = [], []
        for name, (kind, inner) in kinds.items():
            if kind == "message":
                params.append(f"{name}=None")
                nested = src.const(message_class(_nested(inner)), "C")
                body.append(f"self.{name} = {nested}() if {name} is None else {name}")
            elif kind.startswith("seq"):
                params.append(f"{name}=()")
                body.append(f"self.{name} = {name}")
            else:
                params.append(f"{name}={_DEFAULTS.get(inner, '0')}")
                body.append(f"self.{name} = {name}")
        src.emit(0, f"def __init__(self, {', '.join(params)}):")
        for line in body or ["pass"]:
            src.emit(1, line)
        init = src.function("__init__")
        light = type(ros.__name__, (Light,), {"__slots__": tuple(fields), "__init__": init})
        light.__module__ = __name__
        light.__qualname__ = ros.__name__
        _LIGHT[ros], _ROS[light] = light, ros
        _LIGHT[light] = light  # (a light class is its own)
    finally:
        _PENDING.discard(ros)
    _decoder(ros)
    _encoder(ros)
    return light
