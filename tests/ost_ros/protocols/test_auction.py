"""The auction (market-based allocation): the rules on a hand-checked case (finder auctions,
lowest bids win, ties to the lower id, award order is execution order), and the promises as
properties on random scenarios — no deadlock (every run completes), every object delivered by
n_i robots, agents agree, planned = executed, engines equal; with failures every object the
survivors can carry is still delivered; a malformed award or bid is refused with a warning."""

import dataclasses

from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate, simulate_events
from ost_ros.engines.step import run_steps
from ost_ros.model import Grid, ObjectSpec
from ost_ros.protocols import make_agents
from ost_ros.protocols.auction.messages import Award, Bid
from ost_ros.scenario import build_scenario
from tests.ost_ros.protocols.test_failures import failing_runs
from tests.strategies import scenarios


def line_scenario():
    # 12x3 grid, 3 robots (one column band each); object 0 needs 2 robots
    objs = [ObjectSpec(0, (1, 1), (11, 1), 2), ObjectSpec(1, (10, 2), (0, 2), 1)]
    return build_scenario(Grid(12, 3), objs, n_agents=3, nmax=2)


def test_finder_auctions_and_the_lowest_bids_win():
    # Robots 0, 1, 2 sweep 4-column bands of a 12x3 grid along row 1 (each done in step 3, at
    # its band's far end: (3, 1), (7, 1), (11, 1)). Robot 0 senses object 0 at step 0 and
    # auctions it; robot 2 senses object 1 at step 1, which waits: one auction at a time.
    s = line_scenario()
    agents = make_agents(s, "auction")
    heard = []
    receive = agents[0].comm.receive

    def listen(t, messages):
        heard.extend((t, m) for m in messages if isinstance(m, (Bid, Award)))
        receive(t, messages)

    agents[0].comm.receive = listen
    r = run_steps(s, agents)
    assert r.completed and r.agreement and not r.warnings and r.trigger == "auction"
    assert [(t, m.sender, m.object, m.cost) for t, m in heard if isinstance(m, Bid)] == [
        # object 0 at (1, 1): free at step 3 at the sweep end, then the walk
        (1, 0, 0, 3 + 2),
        (1, 1, 0, 3 + 6),
        (1, 2, 0, 3 + 10),
        # object 1 at (10, 2), opened once object 0 is awarded: robots 0 and 1 won object 0
        # (delivered at (11, 1) in step 19), so they bid 19 + 2; robot 2 is free
        (3, 0, 1, 21),
        (3, 1, 1, 21),
        (3, 2, 1, 5),
    ]
    assert [(t, m.sender, m.object, m.agents) for t, m in heard if isinstance(m, Award)] == [
        (2, 0, 0, (0, 1)),  # the two lowest bids, awarded by the finder
        (4, 2, 1, (2,)),  # robot 2 found object 1: its auction
    ]
    by_obj = {a.object: a for a in r.schedule}
    assert (by_obj[0].start, by_obj[0].finish) == (9, 19)  # robot 1 arrives last, at 9
    assert r.predicted_makespan == r.makespan


def test_bids_and_awards_that_break_the_rules_are_refused():
    s = line_scenario()
    agents = make_agents(s, "auction")
    comm = agents[0].comm
    comm.receive(0, [Bid(1, 0, 5, 10)])  # nobody auctions object 5
    comm.receive(1, [Award(2, 1, 0, (0, 1))])  # object 0 is not being auctioned by 2
    assert any("not being auctioned" in w for w in comm.knowledge.warnings)
    assert any("does not auction" in w for w in comm.knowledge.warnings)
    assert comm.knowledge.schedule == []


@settings(max_examples=150, deadline=None)
@given(scenarios(agents=(1, 6), objects=(0, 8)), st.lists(st.sampled_from([1, 1, 2, 3]), min_size=6))
def test_no_deadlock_every_object_delivered_engines_equal(s, periods):
    if periods[0] > 1:  # some teams with unequal speeds
        agents = [dataclasses.replace(a, period=k) for a, k in zip(s.agents, periods)]
        s = build_scenario(s.grid, s.objects, partition=s.partition, agents=agents, nmax=s.nmax)
    r = simulate(s, "auction")
    assert r.completed, r.error  # no deadlock: every run ends with everything delivered
    assert r.agreement and not r.rejections and not r.warnings
    assert r.predicted_makespan == r.makespan
    for o, spec in zip(r.objects, s.objects):
        assert o.delivered is not None and len(o.agents) == spec.required
    assert simulate_events(s, "auction").to_dict() == r.to_dict()


@settings(max_examples=120, deadline=None)
@given(run=failing_runs())
def test_failures_are_re_auctioned(run):
    s, _, failures = run
    r = simulate(s, "auction", CoordinationPolicy(), failures=failures)
    survivors = s.n_agents - len(failures)
    assert not r.rejections and not r.warnings and r.agreement
    for o, spec in zip(r.objects, s.objects):
        if spec.required <= survivors:
            assert o.delivered is not None and len(o.agents) == spec.required
    assert r.completed == all(o.delivered is not None for o in r.objects)
    if r.predicted_makespan is not None:
        assert r.predicted_makespan == r.makespan
