"""The agreement layer by hand: stamps never at or below a given watermark, a batch complete
only once every live participant has covered it, one order whatever the arrival order, and a
failure notice that every receiver applies from the same batch."""

import itertools
import math

import pytest

from ost_ros.realtime.commit import CommitRule, Gate
from ost_ros.realtime.messages import Envelope, Lost, Mark, Need
from ost_ros.realtime.stamps import Batches, LateMessage, Ledger, Speaker, stamp_of


def test_stamps_follow_the_event_and_never_fall_at_or_below_a_commitment():
    assert stamp_of(5.0, -1) == 5 and stamp_of(5.3, -1) == 6 and stamp_of(5.0, 5) == 6
    sp = Speaker(0)
    a = sp.send("a", 3.0)
    assert (a.seq, a.stamp) == (1, 3)
    assert sp.commit(7) == [Mark(0, 7, 1)]  # batch 3 is wanted (its own message): announced
    b = sp.send("b", 4.0)  # an event of time 4 handled after committing 7 goes out stamped 8
    assert (b.seq, b.stamp) == (2, 8) and sp.committed == 7
    stamps = [sp.send(i, t).stamp for i, t in enumerate([8.0, 8.5, 2.0, 9.0])]
    assert stamps == sorted(stamps) and min(stamps) > 7


def test_a_watermark_is_announced_once_and_only_when_someone_waits():
    sp = Speaker(1)
    assert sp.commit(4) == []  # nobody waits: no heartbeat
    assert sp.want(3) == [Mark(1, 4, 0)]  # committed already: answered at once
    assert sp.want(2) == []  # covered by the announcement
    assert sp.want(9) == [] and sp.next_wanted() == 9  # not yet: answered when committed
    assert sp.commit(8) == []
    assert sp.commit(9) == [Mark(1, 9, 0)]
    assert sp.commit(12) == []


def env(sender, seq, stamp, msg=None):
    return Envelope(sender, seq, stamp, msg if msg is not None else f"{sender}.{seq}")


def test_a_batch_waits_for_every_participant_and_every_message_up_to_its_watermark():
    me = Speaker(0)
    b = Batches(0, (0, 1, 2), me)
    b.accept(env(1, 1, 5))
    assert b.next_stamp() == 5 and not b.complete(5)
    me.commit(5)
    assert b.lacking(5) == [1, 2]  # 1's message stamped 5 only says "nothing more ≤ 4"
    b.accept_mark(Mark(2, 6, 2))  # 2 has sent 2 messages, none of them arrived yet
    b.accept_mark(Mark(1, 5, 1))
    assert b.lacking(5) == [2]
    b.accept(env(2, 2, 6))
    assert b.lacking(5) == [2]  # its message 1 is still on the way
    b.accept(env(2, 1, 5))
    assert b.complete(5)
    assert b.take(5) == ["1.1", "2.1"]  # by (sender, seq), whatever the arrival order
    assert b.done == 5 and b.next_stamp() == 6
    with pytest.raises(LateMessage):
        b.accept(env(1, 2, 5))  # 1 announced 5: a message stamped 5 now breaks that


def test_every_arrival_order_gives_the_same_batches():
    msgs = [env(1, 1, 2), env(1, 2, 2), env(1, 3, 4), env(2, 1, 3), env(2, 2, 4)]
    marks = [Mark(1, 4, 3), Mark(2, 4, 2)]
    seen = set()
    for order in itertools.permutations(msgs + marks):
        me = Speaker(0)
        me.commit(4)
        b = Batches(0, (0, 1, 2), me)
        out = []
        for x in order:
            if isinstance(x, Mark):
                b.accept_mark(x)
            else:
                b.accept(x)
            while (t := b.next_stamp()) is not None and b.complete(t):
                out.append((t, tuple(b.take(t))))
        seen.add(tuple(out))
    assert seen == {((2, ("1.1", "1.2")), (3, ("2.1",)), (4, ("1.3", "2.2")))}


def test_a_need_is_only_for_a_batch_without_messages():
    me = Speaker(0)
    b = Batches(0, (0, 1), me)
    assert b.ask(7) == Need(0, 7, -1, 0) and b.ask(7) is None  # once
    b.accept(env(1, 1, 9))
    assert b.ask(9) is None  # its message reaches everyone: they announce on it


def test_a_failure_notice_drops_the_robot_from_the_same_batch_everywhere():
    notice = Lost(2, 6, seq=2, at=(0, 0))
    orders = [
        [env(2, 1, 4), env(2, 2, 6), notice],
        [notice, env(2, 2, 6), env(2, 1, 4)],
        [env(2, 2, 6), notice, env(2, 1, 4)],
    ]
    results = set()
    for order in orders:
        me = Speaker(0)
        me.commit(8)
        b = Batches(0, (0, 1, 2), me)
        b.accept_mark(Mark(1, 8, 0))
        for x in order:
            b.accept_lost(x) if isinstance(x, Lost) else b.accept(x)
        out = []
        while (t := b.next_stamp()) is not None and b.complete(t):
            out.append((t, tuple(b.take(t))))
        results.add(tuple(out))
        assert [p for p in b.team if b.member(p, 6)] == [0, 1]
        assert [p for p in b.team if b.member(p, 5)] == [0, 1, 2]
    # its message stamped 6 is at or after the notice: dropped; the notice comes last in batch 6
    assert results == {((4, ("2.1",)), (6, (notice,)))}


def test_a_batch_before_a_notice_waits_for_the_dead_robots_counted_messages():
    me = Speaker(0)
    me.commit(9)
    b = Batches(0, (0, 1), me)
    b.accept_lost(Lost(1, 8, seq=3, at=(0, 0)))
    assert not b.complete(5)  # three of its messages count and none has arrived
    for seq, stamp in ((1, 2), (2, 5), (3, 9)):
        b.accept(env(1, seq, stamp))
    assert [(t, b.take(t)) for t in (2, 5)] == [(2, ["1.1"]), (5, ["1.2"])]
    assert b.next_stamp() == 8  # its message stamped 9 is past its notice: gone


def test_a_later_batch_waits_for_a_dead_robots_message_still_on_the_way():
    me = Speaker(0)
    me.commit(9)
    b = Batches(0, (0, 1, 2), me)
    b.accept_mark(Mark(2, 9, 0))
    b.accept_lost(Lost(1, 1, seq=1, at=(0, 0)))  # it sent one message before it failed
    b.accept(env(2, 1, 4))
    assert not b.complete(4)  # its message (stamped 0, say) may still come: batch 0 first
    b.accept(env(1, 1, 0))
    notice = b.failed[1]
    assert [(t, b.take(t)) for t in (0, 1, 4)] == [(0, ["1.1"]), (1, [notice]), (4, ["2.1"])]


def test_a_need_carries_the_watermark_of_the_one_who_asks():
    me = Speaker(0)
    me.commit(7)
    b = Batches(0, (0, 1), me)
    need = b.ask(7)
    assert need == Need(0, 7, 7, 0) and me.announced == 7
    peer = Batches(1, (0, 1), Speaker(1))
    peer.accept_mark(need)  # the asker's own watermark: nobody waits for its Mark
    assert 0 not in peer.lacking(7)


def test_a_commitment_held_back_by_its_base_rides_on_the_message_explicitly():
    sp = Speaker(0)
    rule = CommitRule(base_known=103.0)  # its base's events are in up to 103
    assert sp.commit(rule.limit(110.0)) == [] and sp.committed == 103
    m = sp.send(
        "find", 105.3, limit=rule.base_limit()
    )  # decided at 105.3 (its clock runs ahead of its base's)
    assert (m.stamp, m.watermark, m.implied) == (106, 103, 103) and sp.committed == 103
    late = sp.send("late find", 104.0, limit=rule.base_limit())  # reported late: it keeps its own step
    assert late.stamp == 104 and late.implied == 103
    b = Batches(1, (0, 1), Speaker(1))
    b.speaker.commit(200)
    b.accept(m)
    b.accept(late)
    assert b.lacking(104) == [0]  # 0 only said "nothing more at or below 103"
    rule.base_known = 120.0
    assert sp.commit(rule.limit(110.0)) == [Mark(0, 110, 2)]
    b.accept_mark(Mark(0, 110, 2))
    assert [(t, b.take(t)) for t in (104, 106)] == [(104, ["late find"]), (106, ["find"])]
    unheld = Speaker(2).send("x", 5.0)  # no limit: the watermark is stamp - 1 (not spelt out)
    assert unheld.watermark is None and unheld.implied == 4


def test_the_commit_rule_takes_the_smallest_of_what_holds_a_robot_back():
    rule = CommitRule(remote=True)
    assert rule.limit(7.4) == 7  # its clock
    rule.base_known = 5.5
    assert rule.limit(7.4) == 5  # its base's events
    rule.base_known = math.inf
    rule.due.update({6.2, 9.0})
    assert rule.due_by(7.4) == [6.2] and rule.limit(7.4) == 6  # a decision due at 6.2: below its step 7
    rule.due.clear()
    rule.gate = Gate(batch=3, step=6)
    assert rule.limit(6.0) == 5 and rule.limit(7.0) == 7  # the gated step's decision may change
    rule.gate = Gate(batch=3, step=None)
    assert rule.limit(6.0) == 6
    rule.defer(4.0)
    rule.defer(3.0)
    assert rule.deferred == 4.0
    # held: its base's events keep it below a stamp someone waits for by now
    rule.base_known = 4.0
    assert rule.held(6.0, committed=4, waited_for=[5, None])
    assert not rule.held(6.0, committed=4, waited_for=[7, None])
    rule.base_known = 6.0
    assert not rule.held(6.0, committed=4, waited_for=[5])
    rule.unsure, rule.status_wait = True, 8.0  # a status about a carry waits for its base
    assert (
        rule.held(6.0, committed=4, waited_for=[]) and not rule.status_ready(7.0) and rule.status_ready(8.0)
    )


def test_a_cross_check_joins_no_batch_but_counts_as_arrived():
    sp = Speaker(1)
    check = sp.send("selection", 6.0, shared=False)
    assert sp.wanted == set()  # nobody waits for its stamp
    b = Batches(0, (0, 1), Speaker(0))
    b.speaker.commit(9)
    assert b.accept(check, shared=False) and b.next_stamp() is None
    assert not b.accept(check, shared=False)  # a copy
    b.accept_mark(Mark(1, 9, 1))
    assert b.complete(6) and b.take(6) == []


def test_a_mark_is_left_out_when_a_message_at_the_same_moment_carries_it():
    from ost_ros.realtime.agent import _fold_marks
    from ost_ros.realtime.outputs import Publish

    mark, msg = Publish(Mark(0, 7, 3)), Publish(env(0, 4, 8))  # the message implies 7, count 4
    assert _fold_marks([mark, msg]) == [msg]
    higher = Publish(Mark(0, 9, 4))
    assert _fold_marks([higher, msg]) == [higher, msg]  # it says more than the message: kept
    assert _fold_marks([mark]) == [mark]


def test_a_ledger_holds_the_highest_watermark_whose_messages_all_arrived():
    led = Ledger()
    assert led.held() == (-1, 0)
    led.mark(3, 2)  # messages 1..2 stamped ≤ 3
    led.mark(7, 5)
    led.mark(5, 4)  # older, heard late: adds nothing
    assert led.arrived(1) and led.arrived(2) and not led.arrived(2)
    assert led.held() == (3, 2) and led.covers(3) and not led.covers(4)
    assert led.arrived(4) and led.held() == (3, 2)  # message 3 still missing
    assert led.arrived(3) and led.has(3) and led.held() == (3, 2)  # message 5 not in yet
    assert led.arrived(5) and led.held() == (7, 5) and led.covers(7)
