"""CCP, the cost-balanced cooperation protocol (Lin & Hsu, §3–4): every agent runs Algorithm
Coordination on the same shared knowledge and so holds the same global schedule."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ost_ros.coordination import ORGANISATIONS, CoordinationPolicy
from ost_ros.messages import ObjectFound, SearchDone, Status
from ost_ros.planner import PLANNERS, check_planner
from ost_ros.protocols.base import Capabilities, Option, ProtocolSpec
from ost_ros.protocols.ccp.comm import CcpComm
from ost_ros.protocols.ccp.messages import ScheduleUpdate, Selection
from ost_ros.protocols.shared.agent import STATES, ScheduleAgent
from ost_ros.team import TeamInfo


@dataclass(frozen=True)
class CcpSettings:
    """CCP parameters, the same for every agent (every agent must compute the same schedule)."""

    planner: str = "paper"  # Algorithm Coordination as published, or ost_ros.planner's improvement

    def __post_init__(self) -> None:
        check_planner(self.planner)


def make_agent(
    agent_id: int, team: TeamInfo, policy: CoordinationPolicy, settings: Any = None
) -> ScheduleAgent:
    planner = (settings or CcpSettings()).planner
    return ScheduleAgent(agent_id, team, CcpComm(agent_id, team, policy, planner=planner), "ccp")


def team_comm(team: TeamInfo, policy: CoordinationPolicy, settings: Any = None) -> CcpComm:
    planner = (settings or CcpSettings()).planner
    return CcpComm(team.agent_ids[0], team, policy, voices=team.agent_ids, planner=planner)


SPEC = ProtocolSpec(
    name="ccp",
    label="cost-balanced",
    title="cost-balanced: every robot runs Algorithm Coordination on shared knowledge (the paper's)",
    make_agent=make_agent,
    messages=(ObjectFound, SearchDone, Selection, Status, ScheduleUpdate),
    states=STATES,
    capabilities=Capabilities(
        recovers_failures=True,
        organisations=ORGANISATIONS,
        own_sweeps=True,
        heterogeneous=True,
        triggers=True,
        team_knowledge=True,
    ),
    settings=CcpSettings,
    options=(
        Option(
            "planner",
            "planner",
            f"who plans at a coordination point: {' or '.join(PLANNERS)} (paper: Algorithm "
            "Coordination; improved: re-plans what has not started, then a bounded local search)",
        ),
    ),
    team_comm=team_comm,
)
