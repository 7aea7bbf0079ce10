"""The CCP comm module never obeys a peer's selection: it recomputes it, and a selection that
contradicts the algorithm (a faulty or false peer) is logged and ignored."""

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import ObjectFound
from ost_ros.model import Grid, ObjectSpec
from ost_ros.protocols.ccp.comm import CcpComm
from ost_ros.protocols.ccp.messages import Selection
from ost_ros.scenario import build_scenario
from ost_ros.team import TeamInfo


def test_false_selection_is_detected_and_ignored():
    team = TeamInfo.from_scenario(build_scenario(Grid(20, 6), [], n_agents=2))
    comms = [CcpComm(i, team, CoordinationPolicy(ci=1)) for i in (0, 1)]
    obj = ObjectSpec(0, (3, 2), (8, 2), 1)
    for c in comms:
        c.receive(0, [ObjectFound(0, 0, obj)])
    honest = [m for c in comms for m in c.drain()]
    schedule = list(comms[0].knowledge.schedule)
    lie = Selection(1, 0, 1, (7,))  # agent 1 "selected" an object that does not exist
    for c in comms:
        c.receive(1, honest + [lie])
    assert comms[0].knowledge.schedule == schedule == comms[1].knowledge.schedule  # nothing obeyed
    assert any(
        "agent 1: selection [7] in coordination 1 contradicts the algorithm" in w
        for w in comms[0].knowledge.warnings
    )
    assert not any("contradicts" in w for w in comms[1].knowledge.warnings)  # its own is not checked
