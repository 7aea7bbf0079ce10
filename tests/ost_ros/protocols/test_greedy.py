"""Greedy dispatch (the MRTA baseline): the rules on hand-checked cases (the n_i nearest free
robots, ties to the lower id, first found first served, an object waits until enough robots are
free, the step it goes is the comm module's next event), and the promises as properties on random
scenarios — no deadlock, every object delivered by n_i robots, agents agree, planned = executed,
the step and event engines (and the lockstep runtime) give the same run. What every protocol is
tested for iterates the registry (failures: tests/ost_ros/protocols/test_failures.py; DDS:
tests/ros/test_bringup.py and test_dds_failures.py)."""

import dataclasses

from hypothesis import given, settings
from hypothesis import strategies as st

from ost_msgs_py.wire import round_trip
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate, simulate_events
from ost_ros.lockstep.inprocess import run_lockstep
from ost_ros.model import Grid, ObjectSpec
from ost_ros.protocols import make_agents
from ost_ros.scenario import build_scenario
from tests.strategies import scenarios


def line_scenario(first_needs: int):
    # 12x3 grid, 3 robots sweeping 4-column bands along row 1: each is done at step 3 at its
    # band's far end, (3, 1), (7, 1), (11, 1). Robot 0 senses object 0 at step 0, robot 2
    # senses object 1 at step 1.
    objs = [ObjectSpec(0, (1, 1), (11, 1), first_needs), ObjectSpec(1, (10, 2), (0, 2), 1)]
    return build_scenario(Grid(12, 3), objs, n_agents=3, nmax=3)


def groups(r):
    return {a.object: (a.agents, a.start, a.finish) for a in r.schedule}


def test_each_object_goes_to_its_nearest_free_robots():
    # Nobody is free before its search ends (step 3). In step 2 (free from step 3 on) object 0
    # takes the two nearest: robot 0 there at 3 + 2, robot 1 at 3 + 6 (the carry starts then);
    # robot 2, still free, is the only one left for object 1: there at 3 + 2.
    s = line_scenario(2)
    r = simulate(s, "greedy", engine="step")
    assert r.completed and r.agreement and not r.warnings and r.trigger == "greedy"
    assert groups(r) == {0: ((0, 1), 9, 19), 1: ((2,), 5, 15)}
    assert r.predicted_makespan == r.makespan
    assert simulate_events(s, "greedy").to_dict() == r.to_dict()


def test_an_object_waits_for_enough_free_robots_and_holds_the_queue():
    # Object 0 needs all three: the last, robot 2, is there at 3 + 10; delivered at 23. Object
    # 1 (one robot) waits behind it — first come, first served — until step 23, when all three
    # stand at (11, 1), two cells from it: the tie goes to robot 0. No message marks step 22,
    # the dispatch's step: the comm module names it (next_event), and both engines agree.
    s = line_scenario(3)
    r = simulate(s, "greedy", engine="step")
    assert r.completed and groups(r) == {0: ((0, 1, 2), 13, 23), 1: ((0,), 25, 35)}
    assert simulate_events(s, "greedy").to_dict() == r.to_dict()


def test_next_event_is_the_step_the_head_can_go():
    s = line_scenario(3)
    comm = make_agents(s, "greedy")[1].comm
    k = comm.knowledge
    assert comm.next_event(0) is None  # nothing found, nobody done: only a message can change that
    for o in s.objects:
        k.note_found(o, 0)
    assert comm.next_event(0) == 2  # everyone's search ends at 3: free in step 2 for step 3
    comm.receive(2, [])
    assert [a.object for a in k.assignments] == [0] and comm.queue() == [1]
    assert comm.next_event(3) == 22  # delivered at 23: free in step 22


@settings(max_examples=150, deadline=None)
@given(scenarios(agents=(1, 6), objects=(0, 8)), st.lists(st.sampled_from([1, 1, 2, 3]), min_size=6))
def test_no_deadlock_every_object_delivered_engines_equal(s, periods):
    if periods[0] > 1:  # some teams with unequal speeds
        agents = [dataclasses.replace(a, period=k) for a, k in zip(s.agents, periods)]
        s = build_scenario(s.grid, s.objects, partition=s.partition, agents=agents, nmax=s.nmax)
    r = simulate(s, "greedy")
    assert r.completed, r.error  # no deadlock: every run ends with everything delivered
    assert r.agreement and not r.rejections and not r.warnings
    assert r.predicted_makespan == r.makespan
    for o, spec in zip(r.objects, s.objects):
        assert o.delivered is not None and len(o.agents) == spec.required
    assert simulate_events(s, "greedy").to_dict() == r.to_dict()


@settings(max_examples=25, deadline=None)
@given(scenarios(agents=(1, 6), objects=(0, 8)))
def test_the_lockstep_runtime_gives_the_same_run(s):
    policy = CoordinationPolicy()
    got, _ = run_lockstep(s, "greedy", policy, 64, True, carry=round_trip)
    assert got.to_dict() == simulate(s, "greedy", policy).to_dict()
