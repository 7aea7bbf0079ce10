"""What a receiver did before receiver-specific MACs, kept for the benchmarks only (not a test,
not the product): every message Ed25519-signed (libsodium, through PyNaCl) over a canonical
re-encoding of every field, and a replay window of 65 536 bits held in one Python integer — the
code of ``ost_msgs_py/auth.py`` up to commit 2e05850, trimmed to the receive path.

benchmarks/bench_auth.py sets a check against Ed25519's; benchmarks/bench_receive.py runs this
path in a subscriber process of its own, beside the new one and a plain typed subscriber.
"""

from __future__ import annotations

import array
import functools
import struct
from collections.abc import Callable
from typing import Any

from nacl.signing import SigningKey

DOMAIN = b"ost-auth-1\0"
WINDOW = 1 << 16
_SCALARS = {
    "boolean": "?", "uint8": "B", "int8": "b", "uint16": "H", "int16": "h", "uint32": "I",
    "int32": "i", "uint64": "Q", "int64": "q", "float": "f", "double": "d",
}  # fmt: skip
_ARRAYS = {**_SCALARS, "boolean": "B"}
_LEN = struct.Struct("<I")
_HEAD = struct.Struct("<iQ")
Encode = Callable[[Any, bytearray], None]
_ENCODERS: dict[type, list[tuple[str, Encode]]] = {}


@functools.lru_cache(maxsize=4096)
def _text_bytes(value: str) -> bytes:
    data = value.encode("utf-8", "surrogatepass")
    return _LEN.pack(len(data)) + data


def _field(field_type: str) -> Encode:
    if field_type == "sequence<string>":
        return lambda v, out: out.extend(_LEN.pack(len(v)) + b"".join(map(_text_bytes, v)))
    if field_type in _SCALARS:
        s = struct.Struct("<" + _SCALARS[field_type])
        return lambda v, out: out.extend(s.pack(v))
    if field_type == "string":
        return lambda v, out: out.extend(_text_bytes(v))
    if field_type.startswith("sequence<"):
        inner = field_type[len("sequence<") : -1]
        if inner in _ARRAYS:
            code = _ARRAYS[inner]

            def prims(v: Any, out: bytearray) -> None:
                a = v if isinstance(v, array.array) and v.typecode == code else array.array(code, v)
                out += _LEN.pack(len(a))
                out += a.tobytes()

            return prims
        elem = _field(inner)

        def seq(v: Any, out: bytearray) -> None:
            out += _LEN.pack(len(v))
            for x in v:
                elem(x, out)

        return seq
    return lambda v, out: _message(v, out)  # a nested message


def _message(msg: Any, out: bytearray) -> None:
    known = _ENCODERS.get(type(msg))
    if known is None:
        fields = type(msg).get_fields_and_field_types()
        known = _ENCODERS[type(msg)] = [(n, _field(t)) for n, t in fields.items() if n != "auth"]
    for name, encode in known:
        encode(getattr(msg, name), out)


def signed_bytes(run: str, topic: str, msg: Any, signer: int, counter: int) -> bytes:
    """What was signed: the domain, run, topic, type, signer, counter, every other field."""
    out = bytearray(DOMAIN + f"{run}\0{topic}\0{type(msg).__name__}\0".encode())
    out += _HEAD.pack(signer, counter)
    _message(msg, out)
    return bytes(out)


class BigWindow:
    """The old replay window: the highest counter and a bitmap of the WINDOW below, one int."""

    __slots__ = ("high", "mask")

    def __init__(self) -> None:
        self.high, self.mask = -1, 0

    def fresh(self, c: int) -> bool:
        if c > self.high:
            shift = c - self.high
            self.mask = ((self.mask << shift) | 1) & ((1 << WINDOW) - 1) if shift < WINDOW else 1
            self.high = c
            return True
        bit = 1 << (self.high - c) if self.high - c < WINDOW else 0
        if not bit or self.mask & bit:
            return False
        self.mask |= bit
        return True


def signing_key(seed: bytes = b"\1" * 32) -> SigningKey:
    return SigningKey(seed)
