"""Frames of a run (``ost sim --animate``): each frame is the world at its step, decision points
are never thinned away, and the number of frames stays bounded however long the run."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.protocols import names
from ost_ros.scenario import generate_scenario
from ost_ros.watch.frames import FrameRecorder


class Truth:
    """Every step's positions and carried objects, straight from the world."""

    def __init__(self, scenario):
        self.positions = {0: [a.base for a in scenario.agents]}
        self.ids = [a.id for a in scenario.agents]
        self.objects = {0: [o.location for o in scenario.objects]}
        self.oids = [o.id for o in scenario.objects]

    def __call__(self, world, _actions):
        self.positions[world.t] = [world.positions[a] for a in self.ids]
        self.objects[world.t] = [world.objects[i].at for i in self.oids]


def run(scenario, protocol="ccp", every=None, target=400):
    truth, rec = Truth(scenario), FrameRecorder(scenario, every=every, target=target)

    def both(world, actions):
        truth(world, actions)
        rec(world, actions)

    result = simulate(scenario, protocol, CoordinationPolicy(), on_step=both, engine="step")
    return result, rec.finish(), truth


@settings(max_examples=25)
@given(
    protocol=st.sampled_from(names()),
    seed=st.integers(0, 10_000),
    n=st.integers(1, 5),
    m=st.integers(0, 6),
    target=st.integers(4, 60),
)
def test_each_frame_is_the_world_at_its_step(protocol, seed, n, m, target):
    scenario = generate_scenario(n, m, seed, Grid(24, 10), min(n, 3))
    result, frames, truth = run(scenario, protocol, target=target)
    steps = [f.t for f in frames]
    assert steps[0] == 0 and steps[-1] == result.steps
    assert steps == sorted(set(steps))
    for f in frames:
        assert [tuple(p) for p in f.positions] == truth.positions[f.t]
        assert [tuple(p) for p in f.objects] == truth.objects[f.t]
        assert f.delivered.sum() == sum(
            o.delivered is not None and o.delivered <= f.t for o in result.objects
        )
    # decision points survive any thinning: every first lift and every delivery has its frame
    for o in result.objects:
        if o.start is not None:
            assert o.start + 1 in steps
        if o.delivered is not None:
            assert o.delivered in steps
    regular = [f for f in frames if not f.event]
    assert len(regular) <= target + 1


def test_a_long_run_renders_in_a_few_hundred_frames():
    scenario = generate_scenario(10, 20, 1, Grid(500, 200), 10)
    result, frames, _ = run(scenario)
    assert result.steps > 10_000
    assert len(frames) <= 400 + 2 * 20 + 2
    assert len(frames) >= 200


def test_a_fixed_spacing_keeps_every_kth_step():
    scenario = generate_scenario(3, 4, 2, Grid(30, 12), 2)
    result, frames, _ = run(scenario, every=7)
    steps = {f.t for f in frames}
    assert set(range(0, result.steps + 1, 7)) <= steps


def test_robots_holding_an_object_are_its_group():
    scenario = generate_scenario(4, 5, 3, Grid(30, 12), 3)
    result, frames, _ = run(scenario, every=1)
    by_object = {o.id: set(o.agents) for o in result.objects}
    ids = [a.id for a in scenario.agents]
    for f in frames:
        for k, held in enumerate(f.holding):
            if held >= 0 and f.states[k] == "MOVING":
                assert ids[k] in by_object[int(held)]
    assert any((f.holding >= 0).sum() >= 2 for f in frames)  # a group seen together
    assert np.all(frames[-1].delivered)
