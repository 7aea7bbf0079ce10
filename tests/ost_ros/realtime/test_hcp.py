"""HCP without a barrier: a decision taken on a stale view counts only if it is still sound where
its stamp puts it (docs/realtime.md, "HCP without a barrier") — the comm's rules one by one, and
the runs that hung before each was in place. The promises over random runs are the property tests
of test_run.py (HCP is one of their protocols)."""

import pytest

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import SearchDone
from ost_ros.model import Grid, ObjectSpec
from ost_ros.protocols.hcp.messages import HelpOffer, HelpRelease, HelpRequest
from ost_ros.realtime.hcp import RtHcpComm
from ost_ros.realtime.messages import Lost, ObjectInfo
from ost_ros.realtime.net import Latency
from ost_ros.realtime.run import run_realtime
from ost_ros.scenario import AgentSpec, build_scenario, generate_objects, generate_scenario
from ost_ros.team import TeamInfo

X = ObjectInfo(5, (3, 1), (0, 1), 2)
Y = ObjectInfo(2, (6, 1), (0, 1), 2)


def _comm(n=4):
    s = build_scenario(Grid(20, 3), [], n_agents=n)
    return RtHcpComm(0, TeamInfo.from_scenario(s))


def test_a_withdrawal_of_a_request_staffed_meanwhile_counts_for_nobody():
    """The hole that kept HCP from running without a barrier: requester 1 withdraws X for a
    request of higher priority, having not read the batch that staffed X — X is carried all the
    same, and its offer elsewhere lapses (it is busy at X)."""
    c = _comm()
    c.receive(1, [HelpRequest(1, 1, X)])
    (group,) = c.receive(2, [HelpOffer(2, 2, X.id, 1, 9, view=1)])
    assert group.agents == (1, 2)
    c.receive(3, [HelpRequest(3, 3, Y)])
    c.receive(4, [HelpRelease(1, 4, X.id, view=2), HelpOffer(1, 4, Y.id, 3, 9, view=1)])
    assert c.groups == [group] and c.offers[Y.id] == {}  # X still staffed; 1's offer void
    c.receive(5, [HelpOffer(1, 5, Y.id, 3, 9, view=4)])  # once it has read it: free again
    assert [g.agents for g in c.groups] == [(1, 2), (1, 3)]


def test_a_withdrawal_of_an_open_request_closes_it_and_its_offers_lapse():
    c = _comm()
    c.receive(1, [HelpRequest(1, 1, ObjectInfo(5, (3, 1), (0, 1), 3))])
    c.receive(2, [HelpOffer(2, 2, 5, 1, 9, view=0)])
    c.receive(3, [HelpRelease(1, 3, 5, view=0)])
    assert c.open == {} and c.offered_to == {}


def test_a_request_withdrawn_in_the_batch_it_was_made_in_is_never_open():
    c = _comm()
    c.receive(1, [HelpRequest(1, 1, X), HelpRelease(1, 1, X.id, view=0)])
    assert c.open == {} and 1 not in c.offered_to


def test_a_part_declared_done_before_its_robot_read_of_an_inheritance_is_not_done():
    c = _comm()
    c.receive(0, [Lost(3, 0)])  # robot 0 (the lowest survivor) inherits 3's part
    c.receive(7, [SearchDone(0, 7, view=-1), SearchDone(1, 7, view=-1)])
    assert c.done_parts == {1}
    c.receive(9, [SearchDone(0, 9, view=8)])
    assert c.done_parts == {0, 1}


def test_an_heir_that_declared_its_part_done_before_reading_its_inheritance_does_it():
    """Robot 4 dies at once; the notice reaches robot 0, its heir, after robot 0 has swept its own
    subarea and said so: the inherited subarea still holds an object for two."""
    s = build_scenario(Grid(9, 9), [ObjectSpec(0, (5, 7), (6, 5), 2)], n_agents=6, nmax=2)
    r, report = run_realtime(s, "hcp", failures={4: 0}, seed=1, latency=Latency(0, 4))
    assert r.completed and report.disagreements == 0 and r.objects[0].agents == (0, 5)


def test_a_group_broken_twice_leaves_no_request_open():
    """A second member of a group broken already dies: the group is not broken again (its object
    is the heir's by then, requested again and withdrawn when too few survive)."""
    objs = [
        ObjectSpec(0, (4, 0), (14, 5), 3),
        ObjectSpec(1, (8, 3), (6, 6), 3),
        ObjectSpec(2, (16, 3), (4, 4), 3),
        ObjectSpec(3, (18, 5), (6, 6), 3),
    ]
    s = build_scenario(Grid(21, 7), objs, n_agents=5, nmax=4)
    r, _ = run_realtime(s, "hcp", failures={0: 11, 3: 0, 2: 18}, seed=0, latency=Latency(0, 3))
    assert r.error is not None and "4 of 4 objects cannot be delivered" in r.error


def test_a_request_and_its_withdrawal_in_one_batch_leave_no_request_open():
    objs = [
        ObjectSpec(0, (2, 6), (1, 3), 2),
        ObjectSpec(1, (9, 2), (3, 3), 2),
        ObjectSpec(2, (9, 8), (4, 8), 3),
    ]
    bases = [(5, 8), (0, 0), (0, 0), (0, 0), (0, 2)]
    s = build_scenario(
        Grid(10, 9), objs, partition=(5, 1), agents=[AgentSpec(k, b) for k, b in enumerate(bases)], nmax=5
    )
    r, report = run_realtime(
        s, "hcp", failures={2: 217, 1: 137, 4: 203}, latency=Latency(11, 24), seed=131072,
        speed_jitter=0.3, base_lag=0.5, declare_after=40.0, mirrors=True,
    )  # fmt: skip
    assert r.error is not None and "1 of 3 objects cannot be delivered" in r.error
    assert [o.delivered is not None for o in r.objects] == [True, True, False]
    assert report.disagreements == 0 and report.mirror_errors == []


def test_a_robot_silent_past_the_timeout_is_out_for_good_and_its_part_inherited():
    """HCP readmits nobody: a robot declared out stays out, as if dead, and the run ends without
    it (its part swept again by its heir)."""
    s = generate_scenario(6, 10, 919, Grid(120, 60), nmax=3)
    r, report = run_realtime(
        s, "hcp", CoordinationPolicy(), latency=Latency(5, 5), seed=1, silences=[(2, 100, 50)]
    )
    assert r.completed and report.disagreements == 0
    assert (report.declared, report.rejoins, report.out_at_end) == (1, 0, [2])


@pytest.mark.parametrize(("protocol", "when"), [("hcp", 198), ("hcp", 200), ("ccp", 150), ("ccp", 152)])
def test_a_partners_failure_heard_before_its_base_says_so_blocks_nobody(protocol, when):
    """As over DDS: the monitor stamps robot 6's notice at its last watermark, which a survivor
    can take before its base's abort of the carry with robot 6 reaches it (the move under way
    ends first, then ``base_lag``). The abort must not block the object for good (HCP: its new
    group held forever), and a carry whose group lost a member is not kept by the recovery as
    under way (CCP: kept with the dead robot in its group, never to be lifted)."""
    g = Grid(21, 10)
    s = build_scenario(g, generate_objects(12, 728510, g, 6), partition=(3, 3), nmax=6)
    r, report = run_realtime(
        s,
        protocol,
        seed=832645,
        failures={6: when},
        speed_jitter=1.0,
        base_lag=3.0,
        declare_after=5.0,
        silences=[(0, 1.0, 1.0)],
        failure_timeout=60.0,
    )  # fmt: skip  (the 1-step silence only brings the monitor in, as over DDS)
    assert r.completed and report.disagreements == 0 and not r.warnings
