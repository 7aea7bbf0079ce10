"""The core's one error base, and the CLI's usage error.

Every error the system raises for bad input derives from :class:`OstError` — one base per layer
under it: the core's own classes (``ScenarioError``/``FieldError``, ``ProtocolError``,
``NegotiationError``, ``AnimationError``, ``ProtocolViolation``, ``FollowError``,
:class:`UsageError`), the messages layer's ``ost_msgs_py.errors.InterfaceError`` and the node
layer's ``ost_ros.node.params.NodeError``. Each is one line naming the problem. They are
``ValueError`` s, as the callers that catch ``ValueError`` expect.
"""

from __future__ import annotations


class OstError(ValueError):
    """Bad input to the system (a file, a value, a message, a parameter), said in one line."""


class UsageError(OstError):
    """Bad input from the user (file, flag, value). Printed as one line; exit code 2."""
