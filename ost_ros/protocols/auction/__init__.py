"""The auction protocol (market-based allocation, as fleet dispatchers do): each found object is
auctioned by its finder, every agent bids when it could be there, the n_i lowest bids win and
the award is broadcast; winners execute their objects in award order. A peer for CCP, not in
the paper (docs/interpretation.md, "The auction")."""

from __future__ import annotations

from typing import Any

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import ObjectFound, SearchDone, Status
from ost_ros.protocols.auction.comm import AuctionComm
from ost_ros.protocols.auction.messages import Award, Bid
from ost_ros.protocols.base import Capabilities, ProtocolSpec
from ost_ros.protocols.shared.agent import STATES, ScheduleAgent
from ost_ros.team import TeamInfo


def make_agent(
    agent_id: int, team: TeamInfo, policy: CoordinationPolicy, settings: Any = None
) -> ScheduleAgent:
    return ScheduleAgent(agent_id, team, AuctionComm(agent_id, team, policy), "auction")


def team_comm(team: TeamInfo, policy: CoordinationPolicy, settings: Any = None) -> AuctionComm:
    """Every bid and award is public: one comm module speaking for the whole team computes the
    same auctions (the analytic engine)."""
    return AuctionComm(team.agent_ids[0], team, policy, voices=team.agent_ids)


SPEC = ProtocolSpec(
    name="auction",
    label="auction",
    title="auction: each found object goes to its n_i lowest bidders (market-based; not in the paper)",
    make_agent=make_agent,
    messages=(ObjectFound, SearchDone, Bid, Award, Status),
    states=STATES,
    capabilities=Capabilities(
        recovers_failures=True, own_sweeps=True, heterogeneous=True, team_knowledge=True
    ),
    team_comm=team_comm,
    note="Not in the paper: market-based allocation as fleet dispatchers use it — the finder "
    "auctions each object, every robot bids when it could be there, the n_i lowest bids win "
    "(docs/interpretation.md, The auction).",
)
