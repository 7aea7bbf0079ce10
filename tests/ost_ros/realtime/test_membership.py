"""Who is in the team, in process: robots silent longer than the failure timeout are declared
out and come back as their next life; robots join mid-run. As properties over random small
scenarios mixed with latency, jitter, stalls and failures: every coordination's digest equal on
every robot, every object delivered by exactly its n_i robots (or impossible for the robots
left), no deadlock — and no robot leaves except the ones killed."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import ObjectInfo
from ost_ros.model import AgentSpec, Grid, Scenario, Subarea
from ost_ros.protocols.ccp import CcpSettings
from ost_ros.realtime.membership import misfit
from ost_ros.realtime.messages import Back, Envelope, Hello, Lost, Mark
from ost_ros.realtime.net import Latency, Split
from ost_ros.realtime.run import run_realtime
from ost_ros.scenario import generate_scenario
from tests.ost_ros.realtime.test_run import READMIT, check_run, teams


@st.composite
def faults(draw, s):
    """Kills, silences shorter and longer than the timeout, and joins, on distinct robots (one
    robot is left alone, so someone is always there to readmit the others)."""
    ids = list(draw(st.permutations([a.id for a in s.agents])))[1:]
    kills, silences, joins = {}, [], {}
    for a in ids:
        kind = draw(st.sampled_from(["none", "kill", "silence", "silence", "join"]))
        if kind == "kill":
            kills[a] = draw(st.integers(0, 200))
        elif kind == "silence":
            for _ in range(draw(st.integers(1, 2))):
                silences.append((a, float(draw(st.integers(0, 300))), float(draw(st.integers(1, 120)))))
        elif kind == "join":
            joins[a] = float(draw(st.integers(1, 300)))
    return kills, silences, joins


@st.composite
def splits(draw, s):
    """Sometimes a partition of the team in two for 1–300 steps, what crosses it held or lost
    (then said again when it heals)."""
    ids = [a.id for a in s.agents]
    if len(ids) < 2 or not draw(st.booleans()):
        return []
    order = draw(st.permutations(ids))
    cut = draw(st.integers(1, len(ids) - 1))
    groups = (frozenset(order[:cut]), frozenset(order[cut:]))
    start, steps = float(draw(st.integers(0, 300))), float(draw(st.integers(1, 300)))
    return [Split(groups, start, steps, lost=draw(st.booleans()))]


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_robots_declared_out_come_back_and_joiners_are_used_and_all_agree(data):
    """(1 000 runs of the same mix: benchmarks/bench_membership.py, figures in docs/benchmarks.md)"""
    s, protocol, policy, how = data.draw(teams(agents=(2, 6), protocols=READMIT))
    kills, silences, joins = data.draw(faults(s))
    r, report = run_realtime(
        s,
        protocol,
        policy,
        how,
        latency=Latency(data.draw(st.integers(0, 50)), data.draw(st.integers(0, 50))),
        seed=data.draw(st.integers(0, 10**6)),
        speed_jitter=data.draw(st.sampled_from([0.0, 0.3])),
        stalls=data.draw(
            st.lists(
                st.tuples(st.sampled_from([a.id for a in s.agents]), st.integers(0, 150), st.integers(1, 80)),
                max_size=1,
            )
        ),
        failures=kills,
        silences=silences,
        joins=joins,
        failure_timeout=float(data.draw(st.sampled_from([5, 20, 60]))),
        splits=data.draw(splits(s)),
    )
    check_run(s, r, report, kills)
    assert {f["agent"] for f in r.failures} <= set(kills)  # nobody but the killed failed
    # no robot leaves: out at the end only if it had finished its part before it fell silent
    assert all(r.agents[a].finished is not None for a in report.out_at_end)


def test_a_robot_silent_past_the_timeout_comes_back_and_works_again():
    s = generate_scenario(6, 10, 919, Grid(120, 60), nmax=3)
    base, _ = run_realtime(s, "ccp", CoordinationPolicy(), latency=Latency(5, 5), seed=1)
    r, report = run_realtime(
        s, "ccp", CoordinationPolicy(), latency=Latency(5, 5), seed=1, silences=[(2, 100, 50)]
    )
    assert r.completed and report.disagreements == 0
    assert (report.declared, report.rejoins, report.out_at_end, r.failures) == (1, 1, [], [])
    assert any(2 in o.agents and o.start > 150 for o in r.objects)  # given work after it came back
    assert base.completed


def test_a_silence_shorter_than_the_timeout_only_delays():
    s = generate_scenario(6, 10, 919, Grid(120, 60), nmax=3)
    r, report = run_realtime(
        s, "ccp", CoordinationPolicy(), latency=Latency(5, 5), seed=1, silences=[(2, 100, 8)]
    )
    assert r.completed and report.disagreements == 0 and report.declared == 0


def test_a_robot_that_joins_mid_run_is_given_work():
    s = generate_scenario(6, 10, 919, Grid(120, 60), nmax=3)
    r, report = run_realtime(s, "ccp", CoordinationPolicy(), latency=Latency(5, 5), seed=1, joins={3: 150})
    assert r.completed and report.disagreements == 0 and report.rejoins == 1
    assert any(3 in o.agents for o in r.objects)


@pytest.mark.parametrize(
    "kw, why",
    [
        ({"silences": [(9, 10, 5)]}, "silence of agent 9: no such agent"),
        ({"joins": {9: 10}}, "join of agent 9: no such agent"),
        ({"joins": {1: 0}}, "join of agent 1 at step 0"),
        ({"failure_timeout": 0}, "failure timeout 0"),
    ],
)
def test_bad_membership_faults_are_refused_in_one_line(kw, why):
    s = generate_scenario(3, 2, 1, Grid(20, 10), nmax=2)
    with pytest.raises(ValueError, match=why):
        run_realtime(s, "ccp", CoordinationPolicy(), latency=Latency(1, 0), **kw)


def test_the_monitor_stamps_a_notice_above_the_last_watermark_it_heard_and_commits_no_further():
    from ost_ros.realtime.membership import MONITOR, Monitor
    from ost_ros.realtime.messages import Mark

    m = Monitor((0, 1, 2))
    for a, w in ((0, 40), (1, 12), (2, 30)):
        m.hear(Mark(a, w, 3), now=50.0)
    m.hear(Mark(0, 45, 4), now=50.0)
    assert m.committed == 12  # it waits for every member: robot 1 is at 12
    d = m.declare(1)
    assert (d.agent, d.life, d.stamp, d.seq, d.watermark, d.serial) == (1, 0, 13, 3, 12, 1)
    assert m.declare(1) is None  # one notice per life
    m.tick(50.0)
    assert m.committed == 30  # without robot 1
    m.hear(Mark(2, 60, 5), now=50.0)
    assert m.committed == 45  # robot 0's watermark
    m.wanted.add(46)  # someone waits for batch 46: announced once committed, with its count
    assert m.hear(Mark(0, 70, 6), now=70.0) == [Mark(MONITOR, 60, 1)]


def test_a_robot_back_counts_only_what_it_sends_in_its_new_life():
    from ost_ros.realtime.messages import Back, Envelope, Lost, ObjectFound, ObjectInfo
    from ost_ros.realtime.stamps import Batches, Speaker

    b = Batches(0, (0, 1), Speaker(0))
    found = ObjectFound(1, 1, ObjectInfo(0, (1, 1), (2, 2), 1))
    b.accept(Envelope(1, 1, 3, found))
    b.accept_lost(Lost(1, 5, seq=1))
    assert not b.accept(Envelope(1, 2, 7, found))  # beyond its notice: kept aside
    b.speaker.commit(9)
    assert not b.member(1, 6)
    b.done = 8  # (batches 3 and 5 taken)
    back = b.readmit(1, 8, seq=2)
    assert back == [] and b.member(1, 9) and not b.member(1, 8)
    assert b.accept(Envelope(1, 3, 9, found)) and not b.counts(Envelope(1, 2, 9, found))
    assert Back(0, 8, 1, 1, 2, (0, 0)).after == 2


def test_a_batch_asked_for_ahead_is_announced_by_the_one_who_asked_once_its_clock_passes():
    """Found by the property test above: the improved planner asks ahead for the batch that
    settles a carry (its Need carrying a watermark below it); the monitor then waits for the
    asker's watermark, and asks nobody — the asker must say it once passed (a deadlock at step 16
    before: a robot waiting at its object for a batch only the monitor's Mark could complete)."""
    s = Scenario(
        grid=Grid(4, 5),
        partition=(1, 2),
        agents=(AgentSpec(0, (0, 1), 1, (), ()), AgentSpec(1, (0, 4), 1, (), ())),
        objects=(ObjectInfo(0, (0, 2), (3, 4), 1), ObjectInfo(1, (2, 2), (0, 0), 2)),
        nmax=2,
        subareas=(Subarea(0, 0, 4, 3), Subarea(0, 3, 4, 2)),
    )
    r, report = run_realtime(
        s, "ccp", CoordinationPolicy(ci=1), CcpSettings(planner="improved"),
        latency=Latency(0, 0), silences=[(1, 0.0, 1.0)], failure_timeout=5.0,
    )  # fmt: skip
    assert r.completed, r.error
    assert report.disagreements == 0 and all(o.delivered is not None for o in r.objects)


def test_a_membership_message_that_does_not_fit_the_team_is_named():
    """Bad input: a Hello, notice or Back from or about a robot not on the team, or for a life
    older than the newest the receiver knows, is dropped (``stale``) with the reason; a copy of
    the newest is not (a robot says its Hello again when peers come back)."""
    team, lives = (0, 1, 2), {1: 2}
    assert misfit(Hello(7, 1, 0, (0, 0)), team, lives) == "a hello for agent 7, not on the team"
    assert misfit(Hello(1, 1, 0, (0, 0)), team, lives) == "a hello for life 1 of agent 1, whose life now is 2"
    assert (
        misfit(Hello(1, 2, 0, (0, 0)), team, lives) is None
        and misfit(Hello(1, 3, 0, (0, 0)), team, lives) is None
    )
    assert misfit(Lost(9, 4, ()), team, lives) == "a notice for agent 9, not on the team"
    assert misfit(Lost(1, 4, (), incarnation=0), team, lives) == (
        "a notice for life 0 of agent 1, whose life now is 2"
    )
    back = Back(0, 5, 1, 1, 0, (0, 0))
    assert misfit(back, team, lives) == "a back for life 1 of agent 1, whose life now is 2"
    assert misfit(Envelope(0, 5, 1, back), team, lives) == misfit(back, team, lives)
    assert misfit(Back(0, 5, 2, 1, 0, (0, 0)), team, lives) is None
    assert misfit(Mark(0, 3, 1), team, lives) is None  # not a membership message
    assert (
        misfit(Hello(2, -1, 0, (0, 0)), team, lives) == "a hello for life -1 of agent 2, whose life now is 0"
    )


def test_the_monitors_api_is_all_a_membership_node_needs_of_it():
    """What a membership node tells the monitor beside the watermarks it holds (``note``): a
    stamp every member will need (``want``), a Back (``readmitted``: the life a next notice
    ends); what it asks (``misfit``, ``away``). The same calls ``hear`` makes of a broadcast."""
    from ost_ros.realtime.membership import MONITOR, Monitor

    m = Monitor((0, 1, 2))
    m.note(0, 20, 2)
    m.note(1, 20, 2)
    m.want(5)
    assert m.tick(float("inf")) == [] and m.committed == -1  # robot 2 holds it back
    assert m.declare(2) is not None and m.away() == [2]
    assert m.tick(float("inf")) == [Mark(MONITOR, 20, 1)]  # 5 and the notice's 0 committed
    m.readmitted(Back(0, 21, 2, 1, 0, (0, 0)))
    m.readmitted(Back(1, 21, 2, 0, 0, (0, 0)))  # an older life's, late: nothing
    assert m.lives[2] == 1 and m.misfit(Hello(2, 0, 0, (0, 0))) is not None
    assert m.misfit(Hello(2, 1, 0, (0, 0))) is None and m.misfit(Hello(5, 1, 0, (0, 0))) is not None
    assert m.declare(1, dead=True) is not None and m.away() == [1, 2]
