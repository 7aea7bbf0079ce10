"""A run rebuilt from its messages (``ost_ros.lockstep.follow``): whatever order the messages come in,
the world's bookkeeping fed them gives the run's result, and its frames are the simulator's."""

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_msgs_py.wire import round_trip
from ost_ros.bounds import lower_bound
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.lockstep.follow import FollowError, RunFollower
from ost_ros.lockstep.inprocess import run_lockstep
from ost_ros.lockstep.messages import Tick
from ost_ros.model import Grid
from ost_ros.protocols import names
from ost_ros.scenario import generate_scenario
from ost_ros.watch.frames import FrameRecorder


def recorded(scenario, protocol, kill=None):
    messages: list = []
    result, _ = run_lockstep(
        scenario, protocol, CoordinationPolicy(), tap=messages.append, kill=kill, carry=round_trip
    )
    result.lower_bound = lower_bound(scenario).value
    return result, messages


def text(result) -> str:
    return json.dumps(result.to_dict())


@settings(max_examples=20)
@given(
    protocol=st.sampled_from(names()),
    seed=st.integers(0, 10_000),
    n=st.integers(2, 5),
    m=st.integers(0, 6),
    order=st.randoms(use_true_random=False),
)
def test_any_arrival_order_gives_the_run(protocol, seed, n, m, order):
    scenario = generate_scenario(n, m, seed, Grid(30, 12), min(n, 3))
    result, messages = recorded(scenario, protocol)
    shuffled = list(messages)
    order.shuffle(shuffled)  # DDS orders nothing across topics and writers
    follower = RunFollower()
    for msg in shuffled:
        follower.feed(msg)
    assert text(follower.result()) == text(result)


@pytest.mark.parametrize("protocol, kill", [("ccp", {2: 150}), ("hcp", {1: 120})])
def test_failures_are_applied_where_the_world_put_them(protocol, kill):
    scenario = generate_scenario(4, 6, 1, Grid(40, 16), 3)
    result, messages = recorded(scenario, protocol, kill)
    assert result.failures
    follower = RunFollower()
    for msg in messages:
        follower.feed(msg)
    assert text(follower.result()) == text(result)


def test_replayed_frames_are_the_simulators():
    scenario = generate_scenario(4, 8, 4, Grid(50, 20), 3)
    _, messages = recorded(scenario, "ccp")
    live = FrameRecorder(scenario, every=3)
    follower = RunFollower(on_step=live)
    for msg in messages:
        follower.feed(msg)
    sim = FrameRecorder(scenario, every=3)
    simulate(scenario, "ccp", CoordinationPolicy(), on_step=sim, engine="step")
    a, b = live.finish(), sim.finish()
    assert [f.t for f in a] == [f.t for f in b]
    for x, y in zip(a, b):
        assert (x.positions == y.positions).all() and x.states == y.states
        assert (x.objects == y.objects).all() and (x.holding == y.holding).all()
    assert follower.rt is not None and follower.rt.skipped > 0  # the skipped steps were rebuilt too


def test_a_tick_that_does_not_fit_stops_the_follower():
    scenario = generate_scenario(3, 4, 1, Grid(30, 12), 2)
    _, messages = recorded(scenario, "ccp")
    ticks = [k for k, m in enumerate(messages) if isinstance(m, Tick) and m.last >= 0]
    k = ticks[len(ticks) // 2]
    bad = messages[k]
    obs = bad.observation
    moved = type(obs)(obs.agent, obs.t, (obs.position[0], obs.position[1] + 1), obs.sensed)
    messages[k] = Tick(bad.t, bad.last, moved, bad.peers, bad.counts, bad.run, bad.failed)
    follower = RunFollower()
    for msg in messages:
        follower.feed(msg)
    with pytest.raises(FollowError, match="left the world's steps"):
        follower.result()


def test_without_run_info_or_reports_it_says_what_is_missing():
    scenario = generate_scenario(3, 4, 1, Grid(30, 12), 2)
    _, messages = recorded(scenario, "ccp")
    follower = RunFollower()
    with pytest.raises(FollowError, match="no run_info"):
        follower.result()
    for msg in messages:
        if type(msg).__name__ != "AgentReport":
            follower.feed(msg)
    with pytest.raises(FollowError, match="no report from agents"):
        follower.result()
