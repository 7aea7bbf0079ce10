"""Authenticated messages: who may speak for whom in a run (docs/ros.md, "Authenticated messages").

A secure run has key material made for it (:func:`make_keys`, ``ost keys make``): one X25519 key
per robot and one for the world, each in a file of its own (``agent_<i>.key``, ``world.key``,
mode 0600), and ``team.yaml`` — the run id and every public key — which every process reads.
Any two members s and r share a secret nobody else can compute, X25519 of s's private key and
r's public key (the same as r's private and s's public); through a KDF bound to the run and to
the ordered pair it is the key K(s→r) with which s authenticates what it says to r
(:func:`pair_key`). No handshake: each node derives its keys once, at start (:class:`Keys`).

Every message of the lockstep and of the protocols ends with an ``ost_msgs/Auth`` — counter,
signer, a vector of 16-byte tags, one slot per team member (the world first, then the agents by
id) — so its serialized bytes end with counter (8 bytes), signer (4), the vector's length (4) and
the tags, with no padding between them. The sender (:class:`Sealer`) computes one digest of the
message, D = BLAKE2b-256 over :data:`DOMAIN`, the fully-qualified topic and every byte before the
tags (padding included: everyone receives the same bytes), and the tag of receiver r = keyed
BLAKE2b-128 of D under K(sender→r) — the receiver-specific MACs of the OMG DDS Security
specification. The counter is covered, so a message cannot be replayed under a fresh counter,
and so is the topic: a message cannot be moved to another topic, run or sender, nor altered.

A receiver (:class:`Checker`) accepts a message only if

- it carries a tag vector of the team's size (``unsigned`` if it has none),
- its own slot holds the tag of D under the key it shares with the signer (``forged`` otherwise),
- its counter was not seen before from that signer (``replayed`` otherwise). Counters start at
  the signer's start time in ns and count up, so a restarted world continues above its old
  ones; the receiver remembers the last :data:`WINDOW` counters of each signer and refuses
  anything older, so memory stays bounded however long the run;

and the node then checks that the signer is the sender the message claims (:func:`claimed_signer`):
the world for ``Tick``/``RunEnd``/``RunInfo`` (and a realtime run's ``BaseEvent``, ``BaseClock``,
``BaseStopped``); the membership monitor for a realtime run's ``Lost`` and ``StopBase`` — the notice
is stamped by the membership monitor (or, in process without a monitor, by the run on the world's
behalf); the agent named in it for everything else.

What MACs give up against signatures: whoever holds robot A's key can make A accept a message in
any member's name (A's keys with everyone are its own) — never another robot; a message no
longer proves to a third party what its sender said, and a recording cannot be checked offline.
A message relayed byte for byte (a dead robot's, by the world) still carries every receiver's tag.

Nothing here imports ROS: the tags are over bytes.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
import stat
import struct
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey, X25519PublicKey

from ost_msgs_py.errors import InterfaceError
from ost_ros.yamlload import safe_load

WORLD = -1  # the world's signer id
MEMBERSHIP = -2  # the membership monitor's (realtime runs: its notices and watermarks)
TEAM_FILE = "team.yaml"
WINDOW = 1 << 16  # counters of each signer remembered by a receiver
TAG = 16  # bytes of one receiver's tag
# Interfaces only the world sends; every other one names its agent (see claimed_signer).
WORLD_TYPES = frozenset(
    {"Tick", "RunEnd", "RunInfo", "BaseEvent", "BaseClock", "BaseStopped"}
)  # (realtime: the last three)
MEMBERSHIP_TYPES = frozenset({"Lost", "StopBase"})  # the membership monitor's own interfaces
DOMAIN = b"ost-mac-1\0"  # what the digest of a message starts with: no other use of it can collide
_KDF_PERSON = b"ost-pair-key-1"  # BLAKE2b personalisation of the pairwise key derivation
_PAIR = struct.Struct("<ii")
_U32 = struct.Struct("<I")
_I32 = struct.Struct("<i")
_TRAILER = 16  # counter, signer, the tag vector's length: the bytes before the tags
_NO_TAG = bytes(TAG)

# Why a message was dropped: the counts of a run's transport stats (AgentReport.dropped, in order).
# (stale: a membership message that does not fit the team — ost_ros.realtime.membership.misfit)
UNSIGNED, FORGED, REPLAYED, MALFORMED, STALE = "unsigned", "forged", "replayed", "malformed", "stale"
REASONS = (UNSIGNED, FORGED, REPLAYED, MALFORMED, STALE)


class AuthError(InterfaceError):
    """Key material that cannot be used; the text names the file and the problem."""


def key_name(signer: int) -> str:
    """``world``, ``membership`` or ``agent_<i>``: the stem of the signer's key file."""
    return {WORLD: "world", MEMBERSHIP: "membership"}.get(signer, f"agent_{signer}")


def signer_name(signer: int) -> str:
    return {WORLD: "the world", MEMBERSHIP: "the membership monitor"}.get(signer, f"agent {signer}")


# ----------------------------------------------------------------------------- key material


@dataclass(frozen=True)
class Team:
    """The public half of a run's key material: its run id and every member's public key."""

    run: str
    keys: dict[int, X25519PublicKey]

    @property
    def members(self) -> tuple[int, ...]:
        """The tag vector's slots in order: the world, then the agents by id."""
        return (WORLD, *sorted(i for i in self.keys if i != WORLD))


def _public_hex(key: X25519PublicKey) -> str:
    return key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw).hex()


def make_keys(directory: str | Path, ids: Iterable[int], run: str | None = None) -> Team:
    """Fresh keys for the world, the membership monitor and agents ``ids`` in ``directory``
    (created 0700; private keys 0600, PEM/PKCS#8, readable with ``openssl pkey``), and
    ``team.yaml``. Returns the team."""
    d = Path(directory)
    d.mkdir(mode=0o700, parents=True, exist_ok=True)
    run = run or secrets.token_hex(6)
    public: dict[int, X25519PublicKey] = {}
    for signer in (WORLD, MEMBERSHIP, *sorted(set(ids))):
        key = X25519PrivateKey.generate()
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
        "membership": _public_hex(public[MEMBERSHIP]),
        "agents": {i: _public_hex(k) for i, k in public.items() if i >= 0},
    }
    text = "# The run's public keys (X25519, raw hex) and its id: every process of the run reads this.\n"
    (d / TEAM_FILE).write_text(text + yaml.safe_dump(doc, sort_keys=False))
    return Team(run, public)


def _public_key(text: Any, where: str) -> X25519PublicKey:
    try:
        return X25519PublicKey.from_public_bytes(bytes.fromhex(str(text)))
    except ValueError:
        raise AuthError(f"{where}: not an X25519 public key (64 hex digits)") from None


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
    if doc.get("membership") is not None:  # (keys made before the membership monitor have none)
        keys[MEMBERSHIP] = _public_key(doc["membership"], f"{path}: membership")
    for i, text in doc["agents"].items():
        if not isinstance(i, int) or i < 0:
            raise AuthError(f"{path}: agents: {i!r} is not an agent id")
        keys[i] = _public_key(text, f"{path}: agent {i}")
    return Team(str(doc["run"]), keys)


def load_private(directory: str | Path, signer: int) -> X25519PrivateKey:
    """The member's own private key (its file must not be readable by group or others)."""
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
    if not isinstance(key, X25519PrivateKey):
        raise AuthError(f"{path}: not an X25519 key (made by an older `ost keys make`? make new keys)")
    return key


def pair_key(shared: bytes, run: str, sender: int, receiver: int) -> bytes:
    """K(sender→receiver): the X25519 secret the two share, bound to the run and to the ordered
    pair (what s says to r and what r says to s are told apart)."""
    data = _PAIR.pack(sender, receiver) + run.encode()
    return hashlib.blake2b(data, key=shared, digest_size=32, person=_KDF_PERSON).digest()


class Keys:
    """One member's pairwise keys with every member of the team (itself included), derived once:
    K(me→r) to seal, K(s→me) to check; each kept as a keyed BLAKE2b state that every message
    copies (cheaper than keying a new one)."""

    def __init__(self, team: Team, me: int, key: X25519PrivateKey):
        if me not in team.keys:
            raise AuthError(f"{TEAM_FILE}: no key for {signer_name(me)}")
        self.run, self.me, self.members = team.run, me, team.members
        self.send: dict[int, Any] = {}
        self.receive: dict[int, Any] = {}
        for other in self.members:
            try:
                shared = key.exchange(team.keys[other])
            except ValueError:  # a low-order point: no secret (cryptography refuses the all-zero one)
                raise AuthError(
                    f"{TEAM_FILE}: {signer_name(other)}: not a usable X25519 public key"
                ) from None
            self.send[other] = _mac(pair_key(shared, team.run, me, other))
            self.receive[other] = _mac(pair_key(shared, team.run, other, me))


def digest(topic: str, body: bytes | bytearray | memoryview) -> bytes:
    """D, what every tag of a message is computed over: BLAKE2b-256 of :data:`DOMAIN`, the topic
    and ``body`` (the message's bytes before its tags). :class:`Sealer` and :class:`Checker`
    compute the same from a state kept per topic."""
    h = _digest_start(topic)
    h.update(body)
    return h.digest()


def tag(key: bytes, d: bytes) -> bytes:
    """The tag of digest ``d`` under a pairwise key: keyed BLAKE2b, :data:`TAG` bytes."""
    return hashlib.blake2b(d, key=key, digest_size=TAG).digest()


def _mac(key: bytes) -> Any:
    return hashlib.blake2b(key=key, digest_size=TAG)


def _digest_start(topic: str) -> Any:
    """The digest's state after :data:`DOMAIN` and the topic (copied per message)."""
    return hashlib.blake2b(DOMAIN + topic.encode() + b"\0", digest_size=32)


# ----------------------------------------------------------------------------- seal, check


class Sealer:
    """Seals the messages of one member: its id, a fresh counter, and the tag vector."""

    def __init__(self, keys: Keys, start: int | None = None):
        self.run = keys.run
        self.signer = keys.me
        self.size = TAG * len(keys.members)  # bytes of the tag vector
        self._macs = [keys.send[m] for m in keys.members]
        self._slot = {m: k for k, m in enumerate(keys.members)}
        self._topics: dict[str, Any] = {}
        # From the start time: a restarted process (a resumed world) counts on above its old
        # counters, which its peers have seen.
        self.counter = time.time_ns() if start is None else start

    def next(self) -> int:
        """The counter of the next message (every publish has its own)."""
        self.counter += 1
        return self.counter

    def seal(self, data: bytearray, topic: str, receivers: Iterable[int] | None = None) -> None:
        """Fill in the tag vector that ends ``data`` (:attr:`size` bytes, zeros): for every
        member, or only for ``receivers`` (a topic one member reads; zeros elsewhere)."""
        start = len(data) - self.size
        h = self._topics.get(topic)
        if h is None:
            h = self._topics[topic] = _digest_start(topic)
        h = h.copy()
        h.update(memoryview(data)[:start])
        d = h.digest()
        if receivers is None:
            tags = []
            for mac in self._macs:
                t = mac.copy()
                t.update(d)
                tags.append(t.digest())
            data[start:] = b"".join(tags)
            return
        for r in receivers:
            k = start + TAG * self._slot[r]
            t = self._macs[self._slot[r]].copy()
            t.update(d)
            data[k : k + TAG] = t.digest()


class Window:
    """The counters seen of one signer: the highest, and every one seen above highest − WINDOW
    (older ones are refused). A set pruned in batches: O(1) per message, at most 5/4 WINDOW
    entries."""

    __slots__ = ("high", "seen")
    PRUNE_AT = WINDOW + WINDOW // 4

    def __init__(self) -> None:
        self.high = -1
        self.seen: set[int] = set()

    def fresh(self, c: int) -> bool:
        """``c`` not seen before (and not older than the window): now it is."""
        if c <= self.high - WINDOW or c in self.seen:
            return False
        self.seen.add(c)
        if c > self.high:
            self.high = c
            if len(self.seen) >= self.PRUNE_AT:  # every WINDOW/4 new counters at the most
                low = c - WINDOW
                self.seen = {x for x in self.seen if x > low}
        return True


class Checker:
    """Checks one member's tag on received messages, and each signer's counters."""

    def __init__(self, keys: Keys):
        self.me = keys.me
        self.size = TAG * len(keys.members)
        self._offset = TAG * keys.members.index(keys.me)  # its own slot in the vector
        self._macs = keys.receive
        self._topics: dict[str, Any] = {}
        self.windows: dict[int, Window] = {}

    def check(self, data: bytes, topic: str) -> str | None:
        """None if ``data`` carries a good tag for this member on ``topic`` from the signer it
        names; else why not, starting with the reason (unsigned, forged)."""
        start = len(data) - self.size
        if start < 4 + _TRAILER or _U32.unpack_from(data, start - 4)[0] != self.size:
            if len(data) >= 8 and data[-4:] == b"\0\0\0\0":  # a tag vector of length 0
                return f"{UNSIGNED}: this run accepts sealed messages only"
            return f"{FORGED}: no tag vector of this team's size ({self.size // TAG} members)"
        signer = _I32.unpack_from(data, start - 4 - 4)[0]
        mac = self._macs.get(signer)
        if mac is None:
            return f"{FORGED}: {signer_name(signer)} has no key in this run"
        h = self._topics.get(topic)
        if h is None:
            h = self._topics[topic] = _digest_start(topic)
        h = h.copy()
        h.update(memoryview(data)[:start])
        t = mac.copy()
        t.update(h.digest())
        k = start + self._offset
        if hmac.compare_digest(t.digest(), data[k : k + TAG]):
            return None
        if data[k : k + TAG] == _NO_TAG:
            return f"{FORGED}: no tag for {signer_name(self.me)} (sealed for other receivers)"
        return f"{FORGED}: the tag does not match (another key, run, topic or content)"

    def fresh(self, signer: int, counter: int) -> str | None:
        """None if ``counter`` is new from ``signer`` (now it is seen); else why not."""
        window = self.windows.get(signer)
        if window is None:
            window = self.windows[signer] = Window()
        if window.fresh(counter):
            return None
        return f"{REPLAYED}: counter {counter} of {signer_name(signer)} seen before"


def trailer(data: bytes, size: int) -> tuple[int, int]:
    """(counter, signer) of a message whose tag vector has ``size`` bytes, read from its end."""
    start = len(data) - size - _TRAILER
    counter, signer = struct.unpack_from("<Qi", data, start)
    return int(counter), int(signer)


def claimed_signer(msg: Any) -> int | None:
    """Who a message says it is from: the world for its own interfaces, else the agent it
    names (``sender``, ``agent`` or ``action.agent``); None if it names nobody."""
    name = type(msg).__name__
    if name in WORLD_TYPES:
        return WORLD
    if name in MEMBERSHIP_TYPES:
        return MEMBERSHIP
    for field in ("sender", "agent"):
        v = getattr(msg, field, None)
        if isinstance(v, int):
            return v
    action = getattr(msg, "action", None)
    return action.agent if action is not None else None
