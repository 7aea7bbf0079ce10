"""Frames of a run (``ost sim --animate``): each frame is the world at its step, decision points
are never thinned away, and the number of frames stays bounded however long the run. Without a
barrier (``--latency``) the same, plus who was in the team, and watching changes nothing."""

import json
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.model import Grid
from ost_ros.protocols import names
from ost_ros.realtime.membership import ABSENT, DEAD, IN, OUT, SILENT
from ost_ros.realtime.net import Latency, Split
from ost_ros.realtime.run import run_realtime
from ost_ros.scenario import generate_scenario
from ost_ros.watch.frames import FrameRecorder, RealtimeRecorder
from tests.ost_ros.realtime.test_membership import faults, splits
from tests.ost_ros.realtime.test_run import READMIT, teams


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


# ----------------------------------------------------------------------------- without a barrier


class Watch(RealtimeRecorder):
    """The realtime frames, and the run kept to compare them with its world afterwards."""

    def end(self, run):
        super().end(run)
        self.run = run


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_realtime_frames_are_the_world_at_their_step_and_watching_changes_nothing(data):
    """Over random runs without a barrier (latency, jitter, speed noise, kills, silences, joins,
    partitions): the run watched is the run unwatched, byte for byte; each frame is the world at
    its step (where robots were, what was delivered, who was in the team, the partition's
    sides); every first lift and delivery has its frame; the frames stay bounded."""
    s, protocol, policy, how = data.draw(teams(agents=(2, 5), protocols=READMIT))
    kills, silences, joins = data.draw(faults(s))
    split = data.draw(splits(s))
    kw = dict(
        latency=Latency(data.draw(st.integers(0, 30)), data.draw(st.integers(0, 30))),
        seed=data.draw(st.integers(0, 10**6)),
        speed_jitter=data.draw(st.sampled_from([0.0, 0.3])),
        failures=kills,
        silences=silences,
        joins=joins,
        failure_timeout=float(data.draw(st.sampled_from([5, 20]))),
        splits=split,
    )
    every, target = data.draw(st.sampled_from([None, 1, 7])), data.draw(st.integers(4, 40))
    plain, plain_report = run_realtime(s, protocol, policy, how, **kw)
    rec = Watch(s, every=every, target=target)
    result, report = run_realtime(s, protocol, policy, how, observe=rec, **kw)
    assert json.dumps(result.to_dict() | report.to_dict()) == json.dumps(
        plain.to_dict() | plain_report.to_dict()
    )
    frames, world = rec.finish(), rec.run.world
    steps = [f.t for f in frames]
    assert steps[0] == 0 and steps[-1] == result.steps and steps == sorted(set(steps))
    ids = [a.id for a in s.agents]
    for f in frames:
        assert [tuple(p) for p in f.positions] == [world.position(a, f.t) for a in ids]
        assert f.delivered.sum() == sum(
            o.delivered is not None and o.delivered <= f.t for o in result.objects
        )
        for k, a in enumerate(ids):
            dead = a in world.failed and a in kills and kills[a] <= f.t
            assert (f.team[k] == DEAD) == dead, (f.t, a, f.team)
            if a in joins and not dead:
                assert (f.team[k] == ABSENT) == (f.t < joins[a])
        live = [sp for sp in split if sp.start <= f.t < sp.start + sp.steps]
        assert bool(f.split) == bool(f.sides) == bool(live)
        if live:
            assert all((a in live[0].groups[f.sides[k]]) for k, a in enumerate(ids))
    for o in result.objects:  # decision points survive any thinning
        for t in (o.start, o.delivered):
            if t is not None:
                assert math.ceil(t - 1e-9) in steps
    if every is None:
        assert sum(not f.event for f in frames) <= target + 1


def test_realtime_frames_say_who_is_in_the_team_and_what_changed_last():
    scenario = generate_scenario(4, 6, 1, Grid(40, 20), 3)
    rec = RealtimeRecorder(scenario, every=10)
    run_realtime(
        scenario,
        latency=Latency(4, 4),
        silences=[(1, 30.0, 60.0)],
        joins={3: 50.0},
        failure_timeout=8.0,
        splits=[Split((frozenset({0, 1}), frozenset({2, 3})), 100.0, 40.0)],
        observe=rec,
    )
    frames = {f.t: f for f in rec.finish()}
    assert frames[0].team == (IN, IN, IN, ABSENT) and frames[0].note == "agent 3 not there yet at 0"
    assert frames[30].team[1] == SILENT and frames[30].note == "agent 1 silent at 30" and frames[30].event
    assert frames[38].team[1] == OUT and frames[38].note == "agent 1 declared out at 38"
    assert frames[50].team[3] == OUT and frames[50].note == "agent 3 joins at 50"
    admitted = next(f for f in frames.values() if f.team[3] == IN)
    assert admitted.event and admitted.note.startswith("agent 3 admitted at")
    back = next(f for f in frames.values() if f.t > 90 and f.team[1] == IN)
    assert back.event and "agent 1 back at" in back.note
    assert frames[100].split == "0,1 | 2,3" and frames[100].sides == (0, 0, 1, 1)
    assert frames[100].note == "partition at 100" and frames[100].event
    assert frames[140].split == "" and frames[140].note == "partition healed at 140"
    assert all(f.team == (IN,) * 4 for f in frames.values() if f.t > 140)
