"""Authenticated messages: who may speak for whom in a run (docs/ros.md, "Authenticated messages").

A secure run has key material made for it (:func:`make_keys`, ``ost keys make``): one Ed25519
signing key per robot and one for the world, each in a file of its own (``agent_<i>.key``,
``world.key``, mode 0600), and ``team.yaml`` — the run id and every public key — which every
process reads. Every message of the lockstep and of the protocols ends with an ``ost_msgs/Auth``
(signer, counter, signature). The signature covers the run id, the topic, the interface's name,
the signer, the counter and every other field (:func:`canonical`), so a message cannot be moved
to another topic, run or sender, nor altered.

A receiver (:class:`Verifier`) accepts a message only if

- it is signed (``unsigned`` otherwise),
- by the sender it claims — the world for ``Tick``/``RunEnd``/``RunInfo``, the agent named in it
  for everything else — with that signer's key from ``team.yaml`` (``forged`` otherwise),
- and its counter was not seen before from that signer (``replayed`` otherwise). Counters start
  at the signer's start time in ns and count up, so a restarted world continues above its old
  ones; the receiver remembers the last :data:`WINDOW` counters of each signer (a bitmap) and
  refuses anything older, so memory stays bounded however long the run.

Nothing here imports ROS: a message is anything with ``get_fields_and_field_types()`` (the
generated ``ost_msgs`` classes).
"""

from __future__ import annotations

import array
import functools
import os
import secrets
import stat
import struct
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey
from nacl.exceptions import BadSignatureError
from nacl.signing import SigningKey, VerifyKey

from ost_msgs_py.errors import InterfaceError
from ost_ros.yamlload import safe_load

WORLD = -1  # the world's signer id
TEAM_FILE = "team.yaml"
WINDOW = 1 << 16  # counters of each signer remembered by a receiver (a bitmap of this many bits)
# Interfaces only the world sends; every other one names its agent (see claimed_signer).
WORLD_TYPES = frozenset({"Tick", "RunEnd", "RunInfo", "Detection", "Lost"})  # (realtime: the last two)
DOMAIN = b"ost-auth-1\0"  # what the signed bytes start with: no other use of a key can collide

# Why a message was dropped: the three counts of a run's transport stats.
UNSIGNED, FORGED, REPLAYED = "unsigned", "forged", "replayed"
REASONS = (UNSIGNED, FORGED, REPLAYED)


class AuthError(InterfaceError):
    """Key material that cannot be used; the text names the file and the problem."""


def key_name(signer: int) -> str:
    """``world`` or ``agent_<i>``: the stem of the signer's key file."""
    return "world" if signer == WORLD else f"agent_{signer}"


def signer_name(signer: int) -> str:
    return "the world" if signer == WORLD else f"agent {signer}"


# ----------------------------------------------------------------------------- key material


@dataclass(frozen=True)
class Team:
    """The public half of a run's key material: its run id and every signer's public key."""

    run: str
    keys: dict[int, Ed25519PublicKey]


def _public_hex(key: Ed25519PublicKey) -> str:
    raw = key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return raw.hex()


def make_keys(directory: str | Path, ids: Iterable[int], run: str | None = None) -> Team:
    """Fresh keys for the world and agents ``ids`` in ``directory`` (created 0700; private keys
    0600, PEM/PKCS#8, readable with ``openssl pkey``), and ``team.yaml``. Returns the team."""
    d = Path(directory)
    d.mkdir(mode=0o700, parents=True, exist_ok=True)
    run = run or secrets.token_hex(6)
    public: dict[int, Ed25519PublicKey] = {}
    for signer in (WORLD, *sorted(set(ids))):
        key = Ed25519PrivateKey.generate()
        pem = key.private_bytes(
            serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
        )
        path = d / f"{key_name(signer)}.key"
        path.unlink(missing_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as f:
            f.write(pem)
        public[signer] = key.public_key()
    doc = {
        "run": run,
        "world": _public_hex(public[WORLD]),
        "agents": {i: _public_hex(k) for i, k in public.items() if i != WORLD},
    }
    text = "# The run's public keys (Ed25519, raw hex) and its id: every process of the run reads this.\n"
    (d / TEAM_FILE).write_text(text + yaml.safe_dump(doc, sort_keys=False))
    return Team(run, public)


def _public_key(text: Any, where: str) -> Ed25519PublicKey:
    try:
        return Ed25519PublicKey.from_public_bytes(bytes.fromhex(str(text)))
    except ValueError:
        raise AuthError(f"{where}: not an Ed25519 public key (64 hex digits)") from None


def load_team(directory: str | Path) -> Team:
    """The run id and public keys from ``directory/team.yaml``."""
    path = Path(directory) / TEAM_FILE
    try:
        doc = safe_load(path.read_text())
    except OSError as exc:
        raise AuthError(f"{path}: cannot read ({exc.strerror})") from None
    except yaml.YAMLError:
        raise AuthError(f"{path}: not YAML") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("agents"), dict) or not doc.get("run"):
        raise AuthError(f"{path}: expected run, world and agents (ost keys make)")
    keys = {WORLD: _public_key(doc.get("world"), f"{path}: world")}
    for i, text in doc["agents"].items():
        if not isinstance(i, int) or i < 0:
            raise AuthError(f"{path}: agents: {i!r} is not an agent id")
        keys[i] = _public_key(text, f"{path}: agent {i}")
    return Team(str(doc["run"]), keys)


def load_private(directory: str | Path, signer: int) -> Ed25519PrivateKey:
    """The signer's own private key (its file must not be readable by group or others)."""
    path = Path(directory) / f"{key_name(signer)}.key"
    try:
        mode = path.stat().st_mode
        data = path.read_bytes()
    except OSError as exc:
        raise AuthError(f"{path}: cannot read ({exc.strerror})") from None
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise AuthError(f"{path}: readable by others (mode {stat.S_IMODE(mode):o}; chmod 600 it)")
    try:
        key = serialization.load_pem_private_key(data, password=None)
    except (ValueError, TypeError):
        raise AuthError(f"{path}: not a PEM private key") from None
    if not isinstance(key, Ed25519PrivateKey):
        raise AuthError(f"{path}: not an Ed25519 key")
    return key


# ----------------------------------------------------------------------------- signed bytes

_SCALARS = {
    "boolean": "?", "octet": "B", "char": "B", "byte": "B", "uint8": "B", "int8": "b",
    "uint16": "H", "int16": "h", "uint32": "I", "int32": "i", "uint64": "Q", "int64": "q",
    "float": "f", "double": "d", "float32": "f", "float64": "d",
}  # fmt: skip
# array.array codes of the same sizes (booleans as bytes); little-endian like struct's "<"
_ARRAYS = {**_SCALARS, "boolean": "B"}
_BIG = sys.byteorder == "big"  # arrays are signed little-endian on every machine
_LEN = struct.Struct("<I")
_HEAD = struct.Struct("<iQ")

Encode = Callable[[Any, bytearray], None]
_ENCODERS: dict[type, list[tuple[str, Encode]]] = {}


def _text(value: str, out: bytearray) -> None:
    data = value.encode("utf-8", "surrogatepass")
    out += _LEN.pack(len(data))
    out += data


@functools.lru_cache(maxsize=4096)
def _text_bytes(value: str) -> bytes:
    data = value.encode("utf-8", "surrogatepass")
    return _LEN.pack(len(data)) + data


def _texts(v: Any, out: bytearray) -> None:
    # A plan's states repeat (a few distinct strings in 1 024 steps): each encoded once.
    out += _LEN.pack(len(v))
    out += b"".join(map(_text_bytes, v))


def _field(field_type: str) -> Encode:
    """How one field of the given ROS type goes into the signed bytes."""
    if field_type == "sequence<string>":
        return _texts
    if field_type in _SCALARS:
        s = struct.Struct("<" + _SCALARS[field_type])
        return lambda v, out: out.extend(s.pack(v))
    if field_type == "string":
        return _text
    if field_type.startswith("sequence<") and field_type.endswith(">"):
        inner = field_type[len("sequence<") : -1]
        if inner in _ARRAYS:
            code = _ARRAYS[inner]

            def prims(v: Any, out: bytearray) -> None:
                a = v if isinstance(v, array.array) and v.typecode == code else array.array(code, v)
                if _BIG and a.itemsize > 1:
                    a = array.array(code, a)
                    a.byteswap()
                out += _LEN.pack(len(a))
                out += a.tobytes()

            return prims
        elem = _field(inner)

        def seq(v: Any, out: bytearray) -> None:
            out += _LEN.pack(len(v))
            for x in v:
                elem(x, out)

        return seq
    if "/" in field_type:  # a nested message
        return lambda v, out: _message(v, out)
    raise TypeError(f"no signed encoding for the ROS field type {field_type!r}")


def _encoders(cls: type) -> list[tuple[str, Encode]]:
    known = _ENCODERS.get(cls)
    if known is None:
        fields = cls.get_fields_and_field_types()  # type: ignore[attr-defined]
        known = _ENCODERS[cls] = [(name, _field(t)) for name, t in fields.items() if name != "auth"]
    return known


def _message(msg: Any, out: bytearray) -> None:
    for name, encode in _encoders(type(msg)):
        encode(getattr(msg, name), out)


def canonical(msg: Any) -> bytes:
    """Every field of a message but ``auth``, in declaration order: integers and floats
    little-endian, strings UTF-8 and sequences each after a uint32 length, nested messages
    inline. The same message gives the same bytes in every process (unlike CDR, whose padding
    bytes are not specified)."""
    out = bytearray()
    _message(msg, out)
    return bytes(out)


def signed_bytes(run: str, topic: str, msg: Any, signer: int, counter: int) -> bytes:
    head = DOMAIN + f"{run}\0{topic}\0{type(msg).__name__}\0".encode()
    return head + _HEAD.pack(signer, counter) + canonical(msg)


def claimed_signer(msg: Any) -> int | None:
    """Who a message says it is from: the world for its own interfaces, else the agent it
    names (``sender``, ``agent`` or ``action.agent``); None if it names nobody."""
    name = type(msg).__name__
    if name in WORLD_TYPES:
        return WORLD
    for field in ("sender", "agent"):
        v = getattr(msg, field, None)
        if isinstance(v, int):
            return v
    action = getattr(msg, "action", None)
    return action.agent if action is not None else None


# ----------------------------------------------------------------------------- sign, verify


class Signer:
    """Seals the messages of one signer: its id, a fresh counter and the signature in ``auth``."""

    def __init__(self, team: Team, signer: int, key: Ed25519PrivateKey, start: int | None = None):
        self.run = team.run
        self.signer = signer
        self.key = key
        # Signed with libsodium (PyNaCl), as checked: the same deterministic Ed25519 signature,
        # faster than through cryptography (Verifier).
        self._sodium = SigningKey(
            key.private_bytes(
                serialization.Encoding.Raw, serialization.PrivateFormat.Raw, serialization.NoEncryption()
            )
        )
        # From the start time: a restarted process (a resumed world) counts on above its old
        # counters, which its peers have seen.
        self.counter = time.time_ns() if start is None else start

    def seal(self, msg: Any, topic: str) -> Any:
        """Sign ``msg`` for ``topic`` in place (every publish gets a new counter); returns it."""
        self.counter += 1
        auth = msg.auth
        auth.signer = self.signer
        auth.counter = self.counter
        data = signed_bytes(self.run, topic, msg, self.signer, self.counter)
        auth.signature = array.array("B", self._sodium.sign(data).signature)
        return msg


class _Window:
    """The counters seen of one signer: the highest and a bitmap of the :data:`WINDOW` below."""

    __slots__ = ("high", "mask")

    def __init__(self) -> None:
        self.high = -1
        self.mask = 0

    def fresh(self, c: int) -> bool:
        """``c`` not seen before (and not older than the window): now it is."""
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


class Verifier:
    """Checks received messages against the team's keys; counts what it drops, by reason."""

    def __init__(self, team: Team):
        self.run = team.run
        self.keys = team.keys
        # Checked with libsodium (PyNaCl): the same Ed25519, about half the time of OpenSSL's
        # through cryptography here (benchmarks/bench_auth.py) — every node checks every message
        # it receives.
        self.verify_keys = {
            i: VerifyKey(k.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw))
            for i, k in team.keys.items()
        }
        self.windows: dict[int, _Window] = {}
        self.dropped: Counter[str] = Counter()

    def check(self, msg: Any, topic: str) -> str | None:
        """None if ``msg`` is genuine and new on ``topic``; else why not (counted), starting
        with the reason (unsigned, forged, replayed)."""
        why = self._why(msg, topic)
        if why is not None:
            self.dropped[why.split(":", 1)[0]] += 1
        return why

    def _why(self, msg: Any, topic: str) -> str | None:
        auth = getattr(msg, "auth", None)
        if auth is None or len(auth.signature) == 0:
            return f"{UNSIGNED}: this run accepts signed messages only"
        claimed = claimed_signer(msg)
        if claimed is None:
            return f"{FORGED}: names no sender"
        if auth.signer != claimed:
            return f"{FORGED}: signed by {signer_name(auth.signer)}, sent as {signer_name(claimed)}"
        key = self.verify_keys.get(auth.signer)
        if key is None:
            return f"{FORGED}: {signer_name(auth.signer)} has no key in this run"
        try:
            data = signed_bytes(self.run, topic, msg, auth.signer, auth.counter)
            key.verify(data, bytes(auth.signature))
        except BadSignatureError:
            return f"{FORGED}: the signature does not match (another key, run, topic or content)"
        except (TypeError, ValueError, OverflowError, struct.error) as exc:
            return f"{FORGED}: cannot be checked ({exc})"
        window = self.windows.setdefault(auth.signer, _Window())
        if not window.fresh(auth.counter):
            return f"{REPLAYED}: counter {auth.counter} of {signer_name(auth.signer)} seen before"
        return None

    def counts(self) -> dict[str, int]:
        return {r: self.dropped.get(r, 0) for r in REASONS}
