"""The library's one error type: bad input, with a one-line message naming the problem."""

from __future__ import annotations

from ost_ros.errors import OstError


class NegotiationError(OstError):
    """Invalid negotiation input (task, discount factor, team, file). Message is one line."""
