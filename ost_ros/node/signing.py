"""A node's part in authenticated messages (docs/ros.md, "Authenticated messages"): it seals what
it publishes with its own key and checks what it receives against the team's public keys
(:mod:`ost_msgs_py.auth`), or neither in an insecure run."""

from __future__ import annotations

from typing import Any

from ost_msgs_py import auth
from ost_ros.node.params import ParameterError


class NodeAuth:
    """A node's part in authenticated messages: its signer (its own key) and a verifier (the
    team's public keys), or neither in an insecure run (``insecure:=true``)."""

    def __init__(self, signer: auth.Signer | None = None, verifier: auth.Verifier | None = None):
        self.signer = signer
        self.verifier = verifier
        self._topics: dict[Any, str] = {}  # publisher -> its full topic name (a call into rcl)

    @property
    def secure(self) -> bool:
        return self.verifier is not None

    def publish(self, pub: Any, msg: Any) -> None:
        """Seal (sign, with a fresh counter) and publish."""
        if self.signer is not None:
            topic = self._topics.get(pub)
            if topic is None:
                topic = self._topics[pub] = pub.topic_name
            self.signer.seal(msg, topic)
        pub.publish(msg)

    def check(self, msg: Any, topic: str) -> str | None:
        """None for a genuine message (or any, insecure); else why it is dropped."""
        return None if self.verifier is None else self.verifier.check(msg, topic)

    def counts(self) -> dict[str, int]:
        """Messages dropped by this node: unsigned, forged, replayed."""
        return self.verifier.counts() if self.verifier is not None else dict.fromkeys(auth.REASONS, 0)


def node_auth(keys: str, insecure: bool, signer: int) -> NodeAuth:
    """The node's keys from the run's key directory (``ost keys make``); the signer's own
    private key is the only one it reads."""
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
        return NodeAuth(auth.Signer(team, signer, auth.load_private(keys, signer)), auth.Verifier(team))
    except auth.AuthError as exc:
        raise ParameterError(f"keys: {exc}") from None
