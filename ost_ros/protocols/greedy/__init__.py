"""Greedy dispatch, the usual baseline of multi-robot task allocation: each found object goes at
once to its n_i nearest free robots — no coordination point, no schedule ahead, no message of its
own. Not in the papers (docs/interpretation.md, "Greedy dispatch")."""

from __future__ import annotations

from typing import Any

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import ObjectFound, SearchDone, Status
from ost_ros.protocols.base import Capabilities, ProtocolSpec
from ost_ros.protocols.greedy.comm import GreedyComm
from ost_ros.protocols.shared.agent import STATES, ScheduleAgent
from ost_ros.team import TeamInfo


def make_agent(
    agent_id: int, team: TeamInfo, policy: CoordinationPolicy, settings: Any = None
) -> ScheduleAgent:
    return ScheduleAgent(agent_id, team, GreedyComm(agent_id, team, policy), "greedy")


def team_comm(team: TeamInfo, policy: CoordinationPolicy, settings: Any = None) -> GreedyComm:
    """The dispatch is computed from public knowledge alone: one comm module speaking for the
    whole team computes the same one (the analytic engine)."""
    return GreedyComm(team.agent_ids[0], team, policy, voices=team.agent_ids)


SPEC = ProtocolSpec(
    name="greedy",
    label="greedy dispatch",
    title="greedy: each found object goes at once to its n_i nearest free robots (the MRTA baseline)",
    make_agent=make_agent,
    messages=(ObjectFound, SearchDone, Status),
    states=STATES,
    capabilities=Capabilities(
        recovers_failures=True, own_sweeps=True, heterogeneous=True, team_knowledge=True
    ),
    team_comm=team_comm,
    note="Not in the paper: the usual baseline of multi-robot task allocation — each found "
    "object goes at once to its n_i nearest robots that are free (searched, nothing to carry), "
    "first found first served (docs/interpretation.md, Greedy dispatch).",
)
