"""The one error base of the messages layer: bad data on the ROS side of the system."""

from __future__ import annotations

from ost_ros.errors import OstError


class InterfaceError(OstError):
    """A message, key material or a recording that cannot be used (``MessageError``,
    ``AuthError``, ``BagError``); the text names the problem in one line."""


class MessageError(InterfaceError):
    """A message that does not fit its interface or dataclass; the text names the offending field
    (or what is wrong with its bytes)."""
