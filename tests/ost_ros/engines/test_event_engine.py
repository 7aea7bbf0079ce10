"""The event engines give exactly the step simulator's run: every found time, the schedule,
every object's group/start/delivery, every agent's cost/idle/carry/search/travel, the makespan,
message and coordination counts — for every protocol of the registry (under every trigger kind),
on the engine it runs on (the analytic one for shared knowledge, else the generic one), and on
the generic engine for those that normally run on the analytic one (their ``plan``)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import choose_engine, simulate, simulate_events
from ost_ros.engines.event import run_events
from ost_ros.model import Grid
from ost_ros.partition import choose_partition
from ost_ros.protocols import REGISTRY, make_agents, names
from ost_ros.scenario import build_scenario, generate_objects, generate_scenario
from ost_ros.sensing import first_sensing
from tests.strategies import policies, scenarios


def same_run(a, b):
    da, db = a.to_dict(), b.to_dict()
    assert da == db
    assert a.found == b.found and a.schedule == b.schedule


ANALYTIC = [n for n, spec in REGISTRY.items() if spec.capabilities.team_knowledge]


@pytest.mark.parametrize("protocol", names())
@settings(max_examples=150)
@given(scenarios(width=(4, 40), height=(3, 16), agents=(1, 8), objects=(0, 14)), policies)
def test_event_engine_equals_step_engine(protocol, scenario, policy):
    same_run(simulate(scenario, protocol, policy), simulate_events(scenario, protocol, policy))


@st.composite
def crowded(draw):
    # Bigger teams and more objects than above: many simultaneous requests, withdrawals, groups.
    w, h = draw(st.integers(20, 60)), draw(st.integers(9, 30))
    n = draw(st.sampled_from([4, 6, 8, 9, 10, 12]))
    m, k = choose_partition(n, Grid(w, h))
    nmax = draw(st.integers(2, n))
    objects = generate_objects(draw(st.integers(10, 30)), draw(st.integers(0, 10**6)), Grid(w, h), nmax)
    return build_scenario(Grid(w, h), objects, partition=(m, k), nmax=nmax)


@pytest.mark.slow
@settings(max_examples=40)
@given(crowded(), policies)
def test_engines_agree_on_crowded_scenarios(scenario, policy):
    a = simulate(scenario, "hcp")
    assert a.completed and a.rejections == [] and a.warnings == []
    same_run(a, simulate_events(scenario, "hcp"))
    same_run(simulate(scenario, "ccp", policy), simulate_events(scenario, "ccp", policy))


@pytest.mark.slow
@pytest.mark.parametrize("protocol", names())
def test_paper_sized_runs_agree(protocol):
    # One paper-sized object set (500x200, N=10, M=20) per protocol, end to end (CI=1, and
    # CI=M where the protocol has triggers).
    s = generate_scenario(10, 20, 7)
    cis = (1, 20) if REGISTRY[protocol].capabilities.triggers else (1,)
    for ci in cis:
        policy = CoordinationPolicy(ci=ci)
        same_run(simulate(s, protocol, policy), simulate_events(s, protocol, policy))


@pytest.mark.parametrize("protocol", names())
def test_step_limit_falls_back_to_reference(protocol):
    s = build_scenario(Grid(30, 12), generate_objects(4, 5, Grid(30, 12), 2), n_agents=2, nmax=2)
    a = simulate(s, protocol, max_steps=10)
    b = simulate_events(s, protocol, max_steps=10)
    assert not b.completed and b.steps == a.steps == 10 and b.error == a.error


def test_first_sensing_covers_the_3x3_block():
    path = np.array([[0, 1], [1, 1], [2, 1], [3, 1]])
    cells = np.array([[0, 0], [3, 2], [4, 0], [5, 1], [2, 3]])
    assert first_sensing(path, cells).tolist() == [0, 2, 3, -1, -1]


def test_engine_choice():
    small = build_scenario(Grid(10, 3), [], n_agents=1)
    assert choose_engine(small) == "step" and choose_engine(generate_scenario(10, 20, 1)) == "event"
    assert choose_engine(small, "event") == "event"


def _generic(scenario, protocol, policy):
    """The event engine on the agents' own plans, for any protocol (CCP and NCP normally run on
    the analytic engine; this checks their ``plan``, which the DDS runtime relies on too)."""
    return run_events(scenario, make_agents(scenario, protocol, policy))


@settings(max_examples=150)
@given(
    scenarios(width=(4, 40), height=(3, 16), agents=(1, 8), objects=(0, 14)),
    policies,
    st.sampled_from(ANALYTIC),
)
def test_generic_event_engine_equals_step_engine_for_every_analytic_protocol(scenario, policy, protocol):
    same_run(simulate(scenario, protocol, policy), _generic(scenario, protocol, policy))


@pytest.mark.slow
@settings(max_examples=25)
@given(crowded(), policies)
def test_generic_engine_on_crowded_scenarios(scenario, policy):
    for protocol in ANALYTIC:
        same_run(simulate(scenario, protocol, policy), _generic(scenario, protocol, policy))
