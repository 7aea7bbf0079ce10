"""Negotiation-based task subdivision and allocation (Rossi, Aldama, Barrientos 2015).

ROS-free: tasks (areas, target points), private rewards, Rubinstein's alternating offers,
proposal search, multi-party strategies, an exact solver for the target-point tables, the slot
negotiation (targets that need several robots; NCP allocates OST objects with it), and
negotiated search subareas for OST teams of different speeds (``partition``).
Offers travel as plain data (``messages``) so a transport can carry them unchanged.

Names are imported lazily so that ``ost --help`` does not pay for shapely and numpy.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "NegotiationError": "errors",
    "AreaTask": "tasks",
    "TargetTask": "tasks",
    "make_task_polygon": "tasks",
    "AreaReward": "rewards",
    "TargetReward": "rewards",
    "global_coverage": "rewards",
    "rubinstein_share": "protocol",
    "predicted_share": "protocol",
    "estimate_discount": "protocol",
    "claim_size": "protocol",
    "AgentSpec": "agents",
    "NegotiationResult": "multiparty",
    "negotiate": "multiparty",
    "Offer": "messages",
    "AreaSearch": "proposals",
    "optimal_allocation": "optimal",
    "SearchRobot": "partition",
    "SearchTeam": "partition",
    "negotiate_partition": "partition",
    "negotiated_scenario": "partition",
    "SlotNegotiation": "slots",
    "NegotiationSettings": "slots",
    "negotiate_slots": "slots",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
