"""A node's part in authenticated messages (docs/ros.md, "Authenticated messages"): it seals what
it publishes with the keys it shares with each member of the team and checks its own tag on what
it receives (:mod:`ost_msgs_py.auth`), or neither in an insecure run. Messages travel as the CDR
bytes of their interfaces (:func:`ost_msgs_py.wire.to_cdr`), published and taken raw: a message
is encoded once and sealed over exactly the bytes DDS carries."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from typing import Any

import rclpy
from rclpy._rclpy_pybind11 import RCLError

from ost_msgs_py import auth, wire
from ost_ros.node.params import ParameterError


class NodeAuth:
    """A node's sealer (tags for every member) and checker (its own tag, each signer's counters),
    or neither in an insecure run (``insecure:=true``: an empty tag vector, nothing checked);
    and what it dropped, by reason (:data:`ost_msgs_py.auth.REASONS`)."""

    def __init__(self, keys: auth.Keys | None = None, start: int | None = None):
        self.sealer = auth.Sealer(keys, start) if keys is not None else None
        self.checker = auth.Checker(keys) if keys is not None else None
        self.run = keys.run if keys is not None else None
        self.dropped: Counter[str] = Counter()
        self._topics: dict[Any, str] = {}  # publisher -> its full topic name (a call into rcl)

    @property
    def secure(self) -> bool:
        return self.checker is not None

    def topic(self, pub: Any) -> str:
        """A publisher's fully-qualified topic (what its messages are sealed for)."""
        topic = self._topics.get(pub)
        if topic is None:
            topic = self._topics[pub] = pub.topic_name
        return topic

    def encode(
        self, pub: Any, value: Any, run: str | None = None, receivers: Iterable[int] | None = None
    ) -> bytes:
        """``value`` (a message dataclass or a :class:`~ost_ros.lockstep.messages.Sample`) as the
        bytes ``pub`` will carry: encoded, and sealed with a fresh counter — for every member, or
        only for ``receivers`` (a topic one member reads). ``run``: a realtime message's run id."""
        s = self.sealer
        if s is None:
            return bytes(wire.to_cdr(value, run=run))
        data = wire.to_cdr(value, run=run, counter=s.next(), signer=s.signer, tags=s.size)
        s.seal(data, self.topic(pub), receivers)
        return bytes(data)

    def publish(
        self, pub: Any, value: Any, run: str | None = None, receivers: Iterable[int] | None = None
    ) -> bytes:
        """Encode, seal and publish ``value`` (:meth:`encode`); the bytes published."""
        data = self.encode(pub, value, run, receivers)
        _publish(pub, data)
        return data

    def relay(self, pub: Any, data: bytes) -> None:
        """Publish a message exactly as it was received (a peer's, sealed by the peer): every
        receiver's tag is still in it."""
        _publish(pub, data)

    def drop(self, reason: str) -> None:
        """Count a dropped message (its reason: the text before the first colon)."""
        self.dropped[reason.split(":", 1)[0]] += 1

    def counts(self) -> dict[str, int]:
        """Messages dropped by this node: unsigned, forged, replayed, malformed, stale."""
        return {r: self.dropped.get(r, 0) for r in auth.REASONS}


def _publish(pub: Any, data: bytes) -> None:
    """Publish ``data``; nothing once the process is shutting down (a signal ends the context
    from rclpy's own thread, and a callback under way would fail to publish: not a fault)."""
    try:
        pub.publish(data)
    except RCLError:
        if rclpy.ok():
            raise


def node_auth(keys: str, insecure: bool, signer: int) -> NodeAuth:
    """The node's keys from the run's key directory (``ost keys make``): ``team.yaml`` and its own
    private key, the only one it reads; every pairwise key derived now."""
    if insecure:
        if keys:
            raise ParameterError("keys: given with insecure:=true (choose one)")
        return NodeAuth()
    if not keys:
        raise ParameterError(
            "keys: a secure run needs its key directory (-p keys:=DIR, made by `ost keys make`), "
            "or -p insecure:=true"
        )
    try:
        team = auth.load_team(keys)
        if signer not in team.keys:
            raise auth.AuthError(f"{keys}/{auth.TEAM_FILE}: no key for {auth.signer_name(signer)}")
        return NodeAuth(auth.Keys(team, signer, auth.load_private(keys, signer)))
    except auth.AuthError as exc:
        raise ParameterError(f"keys: {exc}") from None
