"""The lockstep protocol without DDS: world and agent runtimes wired directly, every message
converted to its ost_msgs interface and back (``carry=round_trip``). Skipping on and off give exactly ``simulate``'s result (no transport here;
the DDS tests run the same runtimes in real processes)."""

import dataclasses

import pytest

from ost_msgs_py.wire import round_trip as wire
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.lockstep.agent import AgentRuntime, ProtocolViolation
from ost_ros.lockstep.inprocess import run_lockstep
from ost_ros.lockstep.messages import Acted, AgentReport, Resend, RunEnd, Sample
from ost_ros.lockstep.world import WorldRuntime
from ost_ros.messages import SearchDone
from ost_ros.model import Grid
from ost_ros.protocols import make_agents, names
from ost_ros.protocols.ccp.messages import Selection
from ost_ros.scenario import generate_scenario


def run(*args, **kwargs):
    """The lockstep in one process, every message through its interface and back."""
    return run_lockstep(*args, carry=wire, **kwargs)


CASES = [(4, 6, 1, 30, 12, 1), (4, 6, 1, 30, 12, 6), (10, 15, 2, 40, 20, 1), (6, 12, 5, 36, 18, 3)]


@pytest.mark.parametrize("protocol", names())
@pytest.mark.parametrize("n, m, seed, w, h, ci", CASES)
def test_skipping_on_and_off_equal_simulate(protocol, n, m, seed, w, h, ci):
    scenario = generate_scenario(n, m, seed, Grid(w, h), 4)
    policy = CoordinationPolicy(ci=ci)
    expected = simulate(scenario, protocol, policy).to_dict()
    plain, w0 = run(scenario, protocol, policy, 0, False)
    skipping, w1 = run(scenario, protocol, policy, 64, True)
    assert plain.to_dict() == expected
    assert skipping.to_dict() == expected
    assert w0.skipped == 0 and w0.round_trips == expected["steps"]
    assert w1.round_trips + w1.skipped == expected["steps"]
    if protocol == "ccp":  # CCP runs are mostly quiet: far fewer round trips
        assert w1.round_trips * 3 < w0.round_trips


@pytest.mark.parametrize(
    "protocol, ci, at_64, at_1024",
    [("ccp", 1, 81, 63), ("hcp", None, 360, 360), ("ncp", 1, 109, 91)],
)
def test_skipping_keeps_its_recorded_round_trips(protocol, ci, at_64, at_1024):
    """How much the world skips is the DDS run's cost: the counts recorded before the agents'
    sensing prediction and the world's plan check were made cheaper (commit 11fdeb3, lookahead
    64) must stay, and the default lookahead (1 024) may only need fewer."""
    scenario = generate_scenario(10, 20, 1, Grid(100, 40))
    policy = CoordinationPolicy(ci=ci) if ci else CoordinationPolicy()
    expected = simulate(scenario, protocol, policy).to_dict()
    for lookahead, trips in ((64, at_64), (1024, at_1024)):
        result, world = run(scenario, protocol, policy, lookahead)
        assert result.to_dict() == expected
        assert world.round_trips == trips, (lookahead, world.round_trips)


@pytest.mark.parametrize("protocol", names())
def test_agents_replay_skipped_steps_in_bulk_with_the_same_result(protocol, monkeypatch):
    """An agent replays the steps the world skipped by the event engine's rule: it acts only
    where it decides and skips settled segments — far fewer calls than steps, same result."""
    import ost_ros.lockstep.inprocess as inprocess

    calls = {"act": 0, "skip": 0}

    def counting(name, method):
        def call(*args):
            calls[name] += 1
            return method(*args)

        return call

    def counted(agents):
        for a in agents:
            for name in calls:
                setattr(a, name, counting(name, getattr(a, name)))
        return agents

    make = inprocess.make_agents
    monkeypatch.setattr(inprocess, "make_agents", lambda *a, **k: counted(make(*a, **k)))
    scenario = generate_scenario(10, 15, 2, Grid(40, 20), 4)
    policy = CoordinationPolicy(ci=1)
    expected = simulate(scenario, protocol, policy).to_dict()
    result, _ = run(scenario, protocol, policy, 64, True)
    assert result.to_dict() == expected
    agent_steps = expected["steps"] * len(scenario.agents)
    # (acts per agent-step measured: 0.19 CCP, 0.24 NCP, 0.22 auction, 0.50 HCP, which talks more)
    assert calls["skip"] > 0 and calls["act"] < 0.6 * agent_steps, (calls, agent_steps)


def test_out_of_turn_messages_are_refused():
    scenario = generate_scenario(2, 2, 1, Grid(12, 6), 2)
    ids = (0, 1)
    agents = make_agents(scenario, "ccp", CoordinationPolicy())
    rt = AgentRuntime(agents[0], ids)
    world = WorldRuntime(scenario)
    ticks = world.start()
    with pytest.raises(ProtocolViolation, match="this is agent 0"):
        rt.accept_tick(ticks[1])
    rt.accept_tick(ticks[0])
    with pytest.raises(ProtocolViolation, match="not in the team"):
        rt.accept_sample(Sample(SearchDone(7, 0), 0, 0))
    (acted,) = rt.progress()
    world.accept_acted(acted)
    world.accept_acted(acted)  # the same answer again (a resend): ignored
    assert world.acted_agents() == (0,)
    changed = dataclasses.replace(acted, sent=acted.sent + 1)
    with pytest.raises(ProtocolViolation, match="second, different action"):
        world.accept_acted(changed)
    with pytest.raises(ProtocolViolation, match="before the run ended"):
        world.accept_report(rt.report())


def run_lossy(scenario, protocol, policy, lose):
    """Like ``run``, but ``lose(k)`` drops the k-th delivery; on a stall the recovery the nodes do
    on their timers runs: the world re-sends ticks / run_end, agents ask for missing messages."""
    ids = tuple(a.id for a in scenario.agents)
    rts = {a.id: AgentRuntime(a, ids, 64) for a in make_agents(scenario, protocol, policy)}
    world = WorldRuntime(scenario, skipping=True)
    count = iter(range(10**9))
    lost = 0

    def deliver(msg):
        nonlocal lost
        if lose(next(count)):
            lost += 1
            return None
        return wire(msg)

    def send(nxt, only):
        for r in rts.values():
            if r.me in only:
                m = deliver(nxt if isinstance(nxt, RunEnd) else nxt[ids.index(r.me)])
                if m is not None:
                    (r.accept_end if isinstance(m, RunEnd) else r.accept_tick)(m)

    nxt = world.start()
    send(nxt, ids)
    for _ in range(10**6):
        out = [m for r in rts.values() for m in r.progress()]
        for m in out:
            if isinstance(m, Sample):
                for r in rts.values():
                    if (d := deliver(m)) is not None:
                        r.accept_sample(d)
            elif (d := deliver(m)) is not None:
                (world.accept_report if isinstance(d, AgentReport) else world.accept_acted)(d)
        if isinstance(nxt, RunEnd):
            if not world.missing_reports:
                return world.result(), lost
        elif world.step_complete:
            nxt = world.advance()
            send(nxt, ids)
            continue
        if out:
            continue
        # Stalled: what the nodes' timers do after RESEND_S.
        send(
            nxt,
            world.missing_reports
            if isinstance(nxt, RunEnd)
            else [i for i in ids if i not in world.acted_agents()],
        )
        for r in rts.values():
            held = r.held()
            if held is not None and held[1]:
                for peer in rts.values():
                    if (req := deliver(Resend(r.me, r.last, held[1]))) is not None:
                        peer.accept_resend(req)
    raise AssertionError("no progress")


@pytest.mark.parametrize("protocol", names())
def test_lost_samples_are_recovered_and_change_nothing(protocol):
    # One delivery in five is lost (ticks, answers, messages, run_end, reports, resend requests).
    scenario = generate_scenario(5, 8, 4, Grid(30, 12), 3)
    policy = CoordinationPolicy(ci=2)
    result, lost = run_lossy(scenario, protocol, policy, lambda k: k % 5 == 3)
    assert lost > 50
    assert result.to_dict() == simulate(scenario, protocol, policy).to_dict()


def test_the_barrier_waits_for_every_counted_message_and_keeps_the_outbox_order():
    from ost_ros.negotiation.messages import NegotiationOffer

    scenario = generate_scenario(2, 2, 1, Grid(12, 6), 2)
    rt = AgentRuntime(make_agents(scenario, "ncp", CoordinationPolicy())[0], (0, 1))
    rt.last, rt.run = 5, ""  # as if its first tick (of run "") had come
    move = NegotiationOffer(1, 5, 1, 0, "offer", (3, 4))
    done = SearchDone(1, 5)
    # the sender's outbox was [done, move]; its samples arrive on two topics, move first
    rt.accept_sample(wire(Sample(move, 5, 1)))
    assert not rt._ready((1,), (2,))
    rt.accept_sample(wire(Sample(done, 5, 0)))
    assert rt._ready((1,), (2,))
    assert [rt._inbox[5][1][k] for k in range(2)] == [done, move]
    rt.accept_sample(wire(Sample(done, 5, 0)))  # the same again (a resend): ignored
    with pytest.raises(ProtocolViolation, match="second, different message #0"):
        rt.accept_sample(Sample(move, 5, 0))
    with pytest.raises(ProtocolViolation, match="not a message of protocol ncp"):
        rt.accept_sample(Sample(Selection(1, 5, 1, (2,)), 5, 2))


@pytest.mark.parametrize("protocol", ["ccp", "ncp"])
def test_heterogeneous_team_equals_simulate(protocol):
    from ost_ros.scenario import build_scenario

    base = generate_scenario(4, 8, 3, Grid(30, 12), 3)
    agents = [dataclasses.replace(a, period=k) for a, k in zip(base.agents, (1, 2, 3, 1))]
    scenario = build_scenario(base.grid, base.objects, agents=agents, nmax=3)
    policy = CoordinationPolicy(ci=2)
    expected = simulate(scenario, protocol, policy).to_dict()
    assert run(scenario, protocol, policy, 64, True)[0].to_dict() == expected
    assert run(scenario, protocol, policy, 0, False)[0].to_dict() == expected


def test_messages_of_another_run_are_dropped():
    scenario = generate_scenario(2, 2, 1, Grid(12, 6), 2)
    policy = CoordinationPolicy()
    ids = (0, 1)
    agents = make_agents(scenario, "ccp", policy)
    world = WorldRuntime(scenario, run="r1")
    rt = AgentRuntime(agents[0], ids)
    stray = Sample(SearchDone(1, 0), 0, 0, run="other")
    rt.accept_sample(stray)  # before the first tick: held, then judged
    ticks = world.start()
    rt.accept_tick(ticks[0])
    assert rt.run == "r1" and rt.dropped and "run 'other'" in rt.dropped[0][1]
    with pytest.raises(ProtocolViolation, match="run 'other'"):
        rt.accept_sample(stray)
    out = rt.progress()
    acted = next(m for m in out if isinstance(m, Acted))
    assert acted.run == "r1"
    world.accept_acted(acted)
    with pytest.raises(ProtocolViolation, match="action of run 'x'"):
        world.accept_acted(dataclasses.replace(acted, run="x"))


@pytest.mark.parametrize("protocol", names())
@pytest.mark.parametrize("skipping", [False, True])
@pytest.mark.parametrize("kill", [{1: 0}, {2: 40}, {0: 25, 3: 60}, {5: 120}])
def test_failed_agents_equal_simulate_with_the_same_failures(kill, skipping, protocol):
    scenario = generate_scenario(6, 10, 3, Grid(36, 18), 3)
    policy = CoordinationPolicy(ci=2)
    got, _ = run(scenario, protocol, policy, 64 if skipping else 0, skipping, kill)
    failures = {f["agent"]: f["step"] for f in got.failures}
    assert set(failures) == set(kill) and all(failures[a] >= kill[a] for a in kill)
    if not skipping:
        assert failures == kill
    assert got.to_dict() == simulate(scenario, protocol, policy, failures=failures).to_dict()
    assert got.completed and got.agreement


def test_a_failure_under_a_protocol_that_cannot_recover_ends_the_run_with_the_reason(monkeypatch):
    from ost_ros import protocols

    ncp = protocols.REGISTRY["ncp"]
    fragile = dataclasses.replace(
        ncp, name="fragile", capabilities=dataclasses.replace(ncp.capabilities, recovers_failures=False)
    )
    monkeypatch.setitem(protocols.REGISTRY, "fragile", fragile)
    scenario = generate_scenario(4, 6, 1, Grid(30, 12), 3)
    world = WorldRuntime(scenario, protocol="fragile")
    world.start()
    end = world.fail(2)
    assert isinstance(end, RunEnd) and not end.completed
    assert [(m.agent, m.t) for m in end.failed] == [(2, 0)]
    r = world.result()
    assert not r.completed and "does not recover" in r.error
