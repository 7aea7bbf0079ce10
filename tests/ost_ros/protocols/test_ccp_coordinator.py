"""The coordinator organisation (paper §3): only the lowest-id agent runs Algorithm Coordination
and broadcasts the schedule, read by everyone a step later. Properties: every object delivered,
planned = executed, everyone holds the coordinator's schedule; when the only coordination is the
final one, the run is the distributed run shifted by exactly one step."""

from dataclasses import replace

import pytest
from hypothesis import given, settings

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from tests.strategies import policies, scenarios


@settings(max_examples=80)
@given(scenarios(agents=(1, 6), objects=(0, 7)), policies)
def test_coordinator_runs_deliver_everything_as_planned(s, policy):
    r = simulate(s, "ccp", replace(policy, organisation="coordinator"))
    assert r.completed and r.agreement and not r.rejections and not r.warnings
    assert r.predicted_makespan == r.makespan
    assert all(
        o.delivered is not None and len(o.agents) == spec.required for o, spec in zip(r.objects, s.objects)
    )
    assert r.trigger.endswith(", coordinator")


@settings(max_examples=60)
@given(scenarios(agents=(1, 6), objects=(1, 7)))
def test_only_the_final_coordination_shifts_the_run_by_one_step(s):
    # CI above M: every agent is free at t+1 (distributed) or t+2 (coordinator), nothing else
    # differs, so every start, finish and the makespan move by one step.
    d = simulate(s, "ccp", CoordinationPolicy(ci=1000))
    c = simulate(s, "ccp", CoordinationPolicy(ci=1000, organisation="coordinator"))
    assert [(a.object, a.agents, a.start + 1, a.finish + 1) for a in d.schedule] == [
        (a.object, a.agents, a.start, a.finish) for a in c.schedule
    ]
    assert c.makespan == d.makespan + 1
    assert c.messages == d.messages - s.n_agents + 1  # n selections → one schedule update


def test_refused_combinations():
    from ost_ros.model import Grid
    from ost_ros.scenario import generate_scenario

    s = generate_scenario(3, 4, 1, Grid(20, 9), 2)
    policy = CoordinationPolicy(organisation="coordinator")
    with pytest.raises(ValueError, match="for ccp"):
        simulate(s, "ncp", policy)
    with pytest.raises(ValueError, match="step engine"):
        simulate(s, "ccp", policy, engine="event")
    with pytest.raises(ValueError, match="organisation must be"):
        CoordinationPolicy(organisation="anarchy")


def test_the_lowest_survivor_coordinates_once_the_coordinator_died():
    from ost_ros.engines.step import run_steps
    from ost_ros.model import Grid
    from ost_ros.protocols import make_agents
    from ost_ros.protocols.ccp.messages import ScheduleUpdate
    from ost_ros.scenario import generate_scenario

    s = generate_scenario(4, 8, 1, Grid(30, 12), 3)
    policy = CoordinationPolicy(ci=1, organisation="coordinator")
    found = simulate(s, "ccp", policy).found
    dies = sorted(found.values())[len(found) // 2]  # coordinator 0 dies mid-search
    agents = make_agents(s, "ccp", policy)
    senders = []
    receive = agents[3].comm.receive

    def listen(t, messages):
        senders.extend((t, m.sender) for m in messages if isinstance(m, ScheduleUpdate))
        receive(t, messages)

    agents[3].comm.receive = listen
    r = run_steps(s, agents, failures={0: dies})
    assert r.completed and r.agreement and not r.warnings
    assert {who for t, who in senders if t <= dies} == {0}
    assert {who for t, who in senders if t > dies} == {1}  # agent 0 died: agent 1 coordinates
    assert r.to_dict() == simulate(s, "ccp", policy, failures={0: dies}).to_dict()
