"""NCP, negotiated allocation: found objects are allocated by the negotiation library's slot
negotiation (Rossi et al.'s target-points protocol, n_i slots per object) and the agreed groups
are executed like a CCP schedule. Not in either paper: the two papers combined."""

from __future__ import annotations

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import ObjectFound, SearchDone, Status
from ost_ros.negotiation.messages import NegotiationOffer
from ost_ros.negotiation.slots import NegotiationSettings
from ost_ros.protocols.base import Capabilities, Option, ProtocolSpec
from ost_ros.protocols.ncp.comm import NcpComm
from ost_ros.protocols.shared.agent import STATES, ScheduleAgent
from ost_ros.team import TeamInfo


def make_agent(
    agent_id: int, team: TeamInfo, policy: CoordinationPolicy, settings: NegotiationSettings | None = None
) -> ScheduleAgent:
    comm = NcpComm(agent_id, team, policy, settings=settings or NegotiationSettings())
    return ScheduleAgent(agent_id, team, comm, "ncp")


def team_comm(
    team: TeamInfo, policy: CoordinationPolicy, settings: NegotiationSettings | None = None
) -> NcpComm:
    return NcpComm(
        team.agent_ids[0], team, policy, settings=settings or NegotiationSettings(), voices=team.agent_ids
    )


def silence(agent: ScheduleAgent, step: int) -> None:
    """Fault injection: from ``step`` on this negotiator sends no moves (the others time it out)."""
    assert isinstance(agent.comm, NcpComm)
    agent.comm.mute_from = step


SPEC = ProtocolSpec(
    name="ncp",
    label="negotiated allocation",
    title="negotiated: objects allocated by a slot negotiation (Rossi et al.), executed like CCP",
    make_agent=make_agent,
    messages=(ObjectFound, SearchDone, NegotiationOffer, Status),
    states=STATES,
    capabilities=Capabilities(
        recovers_failures=True, own_sweeps=True, heterogeneous=True, triggers=True, team_knowledge=True
    ),
    settings=NegotiationSettings,
    options=(
        Option("ncp_delta", "delta", "claim discount per negotiation round, in (0, 1)"),
        Option("ncp_timeout", "timeout_rounds", "rounds without an answer before a negotiator is left out"),
    ),
    team_comm=team_comm,
    silence=silence,
    note="Not in the paper: at each coordination point the found objects are allocated by the "
    "target-points negotiation (docs/interpretation.md, NCP) and the agreed groups are "
    "executed like a CCP schedule.",
)
