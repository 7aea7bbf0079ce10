"""HCP, the help-based cooperation protocol (Lin & Hsu §2.3, the paper's baseline): each robot owns
the objects of its subarea and asks for help with those that need more than one robot."""

from __future__ import annotations

from typing import Any

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import SearchDone
from ost_ros.protocols.base import Capabilities, ProtocolSpec
from ost_ros.protocols.hcp.agent import HcpAgent, HcpState
from ost_ros.protocols.hcp.messages import HelpAccept, HelpOffer, HelpRelease, HelpRequest
from ost_ros.team import TeamInfo


def make_agent(agent_id: int, team: TeamInfo, policy: CoordinationPolicy, settings: Any = None) -> HcpAgent:
    return HcpAgent(agent_id, team)


SPEC = ProtocolSpec(
    name="hcp",
    label="help-based",
    title="help-based: owners ask for help, priority by object id (the paper's baseline)",
    make_agent=make_agent,
    messages=(SearchDone, HelpRequest, HelpOffer, HelpAccept, HelpRelease),
    states=tuple(s.value for s in HcpState),
    capabilities=Capabilities(recovers_failures=True),
)
