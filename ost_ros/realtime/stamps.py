"""The agreement layer: what a coordination computes is a function of the messages, not of when
they arrived (pure; no clock of its own, no I/O).

Sender side (:class:`Speaker`): every message gets (sender, seq, stamp). ``seq`` counts the
sender's messages from 1; the stamp is an integer step, ``max(ceil(event time), committed + 1)``,
so stamps never decrease with seq and never fall at or below a watermark the sender has given.
A participant *commits* step t once it has handled every event of time ≤ t (its own clock passed
t): from then on it sends nothing stamped ≤ t. It *announces* that (a :class:`Mark`) only when
someone waits for it — a peer's :class:`Need`, or any message stamped t it has sent or received
(everyone will need batch t) — and once per such stamp: no periodic heartbeat. How far it may
commit is its commit rule's (:class:`~ost_ros.realtime.commit.CommitRule`): its clock, its base's
events, decisions due — and, for CCP's improved planner only, a carry's gate, which holds the
commitment below step s until the batches up to s − 2 are known. No commitment waits for a batch
at or above itself, so there is no cascade: batch t is complete one round of announcements after
every clock has passed t (and every gate below it has opened).

Receiver side (:class:`Batches`): batch t is *complete* once every live participant's announced
watermark is ≥ t and every message it sent up to that announcement has arrived (arrival order
across kinds is free: over DDS each topic is ordered on its own). A complete batch is taken out
in one order: the messages stamped t by (sender, seq), then the world's failure notices of t by
agent. Batches are taken in stamp order, each once.

Failures: the world's notice (:class:`~ost_ros.realtime.messages.Lost`) is stamped s ≥ the
robot's last watermark + 1 — a batch no survivor can have completed without it — and carries how
many messages of the robot count (those with seq ≤ its ``seq`` and a stamp < s). From batch s on
the robot is no participant: every survivor drops it from the same batch, on the same fact.

Rejoins: a robot declared out that is heard again is a member again from the batch after a
member's stamped :class:`~ost_ros.realtime.messages.Back` (taken in batch s'): its next life
(incarnation) counts its messages with seq above the Back's ``seq`` and a stamp > s'. Each life
is a window of stamps and seqs (:class:`Life`); a message counts if it falls in one. What a robot
sends while out is kept aside (not dropped) until its Back is taken, then counted or dropped by
the same rule on every member.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from ost_ros.realtime.commit import NO_LIMIT
from ost_ros.realtime.messages import MONITOR, Envelope, Lost, Mark, Need


class LateMessage(RuntimeError):
    """A message stamped at or below a batch already taken: the sender broke its watermark."""


def stamp_of(time: float, committed: int) -> int:
    """The stamp of something that happens at ``time`` for a sender that has committed
    ``committed``: never below the event's step, never at or below a given watermark."""
    return max(math.ceil(time - 1e-9), committed + 1)


@dataclass
class Speaker:
    """One participant's outgoing side: stamps, its commitment, the watermarks it owes."""

    me: int
    seq: int = 0  # messages sent so far
    committed: int = -1  # nothing more stamped ≤ committed will be sent
    announced: int = -1  # the largest watermark peers can know (explicitly or implied)
    wanted: set[int] = field(default_factory=set)  # stamps peers wait for, not yet announced

    def send(self, message: object, time: float, shared: bool = True, limit: int = NO_LIMIT) -> Envelope:
        """Stamp ``message`` (happening at ``time``); it carries the watermark it implies — stamp
        - 1 unless ``limit`` (the highest step it may commit: :class:`~ost_ros.realtime.commit.CommitRule`)
        holds the commitment lower, then spelt out. ``shared``: it belongs to a batch (a
        cross-check does not: nobody waits for its stamp)."""
        stamp = stamp_of(time, self.committed)
        self.seq += 1
        self.committed = max(self.committed, min(stamp - 1, limit))
        self.announced = max(self.announced, self.committed)
        if shared:
            self.wanted.add(stamp)  # peers will need batch `stamp`: say when it is passed
        held = self.committed != stamp - 1
        return Envelope(self.me, self.seq, stamp, message, self.committed if held else None)

    def need(self, stamp: int) -> Need:
        """A request for batch ``stamp``, carrying this participant's own watermark (so nobody
        waits for a Mark of the one who asks). Asked ahead — its own clock not past the stamp
        yet — that watermark is one the batch still waits for: it says it once passed (the
        monitor, which waits for every member and asks nobody, would wait for it for ever)."""
        self.announced = max(self.announced, self.committed)
        if stamp > self.committed:
            self.wanted.add(stamp)
        return Need(self.me, stamp, self.committed, self.seq)

    def commit(self, t: int) -> list[Mark]:
        """Every event of time ≤ t is handled (its caller asked its commit rule): commit t and
        announce it if someone waits."""
        if t > self.committed:
            self.committed = t
        return self._announce()

    def want(self, stamp: int) -> list[Mark]:
        """A peer waits for batch ``stamp`` (its Need, or a message stamped so): announce now if
        it is committed, else when it is."""
        if stamp > self.announced:
            self.wanted.add(stamp)
        return self._announce()

    def _announce(self) -> list[Mark]:
        due = [w for w in self.wanted if w <= self.committed]
        if not due:
            return []
        self.wanted.difference_update(due)
        if max(due) <= self.announced:
            return []
        self.announced = self.committed
        return [Mark(self.me, self.committed, self.seq)]

    def next_wanted(self) -> int | None:
        """The smallest stamp a peer waits for that is not committed yet (a timer for then)."""
        return min(self.wanted) if self.wanted else None


@dataclass
class Ledger:
    """What a receiver knows of one participant's messages: which arrived, and the watermarks
    they and its marks carried (ascending; an older one heard late adds nothing). A robot's
    batches and the membership monitor keep one per participant."""

    marks: list[tuple[int, int]] = field(default_factory=list)  # (watermark, seq), ascending
    contiguous: int = 0  # every seq ≤ contiguous has arrived
    ahead: set[int] = field(default_factory=set)  # arrived seqs above contiguous

    def mark(self, watermark: int, seq: int) -> None:
        if self.marks and watermark <= self.marks[-1][0]:
            return  # an older (or implied, earlier) watermark: nothing new
        self.marks.append((watermark, seq))

    def arrived(self, seq: int) -> bool:
        """Note the arrival of ``seq``; False if it had already arrived."""
        if self.has(seq):
            return False
        self.ahead.add(seq)
        while self.contiguous + 1 in self.ahead:
            self.contiguous += 1
            self.ahead.discard(self.contiguous)
        return True

    def has(self, seq: int) -> bool:
        """Whether message ``seq`` has arrived."""
        return seq <= self.contiguous or seq in self.ahead

    def covers(self, t: int) -> bool:
        """Every message stamped ≤ t has arrived."""
        for watermark, seq in self.marks:
            if watermark >= t:
                return self.contiguous >= seq
        return False

    def held(self) -> tuple[int, int]:
        """(watermark, seq): the highest watermark whose messages have all arrived ((-1, 0):
        none) — what a receiver that must hold every message it counts may count on."""
        best = (-1, 0)
        for watermark, seq in self.marks:
            if seq > self.contiguous:
                break  # (ascending: every later one needs more)
            best = (watermark, seq)
        return best

    def forget(self, t: int) -> None:
        """Batch t is taken: watermarks below it are of no more use (the last one stays)."""
        while len(self.marks) > 1 and self.marks[1][0] <= t:
            self.marks.pop(0)


@dataclass
class Life:
    """One incarnation of a member: its messages stamped in [``first``, ``end``) with a seq in
    (``after``, ``upto``] count; it is a participant of the batches in [``first``, ``end``)."""

    first: int
    after: int
    end: int = 1 << 62
    upto: int = 1 << 62
    notice: Lost | None = None  # the notice that ended it

    def counts(self, env: Envelope) -> bool:
        return self.first <= env.stamp < self.end and self.after < env.seq <= self.upto


@dataclass
class Batches:
    """One participant's incoming side: messages by stamp, until each batch is complete."""

    me: int
    team: tuple[int, ...]  # every participant, ascending
    speaker: Speaker  # own side: its commitment completes own batches
    # A monitor takes part (its notices numbered): every batch waits for its watermark too
    # (:mod:`ost_ros.realtime.membership`); without one, notices come from whoever knows a robot
    # is dead (the in-process run's world), stamped above the robot's last watermark.
    monitor: bool = False
    done: int = -1  # the last batch taken
    failed: dict[int, Lost] = field(default_factory=dict)  # agent out now -> the notice
    lives: dict[int, list[Life]] = field(default_factory=dict)  # agent -> its incarnations
    _peers: dict[int, Ledger] = field(default_factory=dict)
    _pending: dict[int, dict[tuple[int, int], Envelope]] = field(default_factory=dict)  # stamp -> ...
    _notices: dict[int, list[Lost]] = field(default_factory=dict)  # stamp -> notices
    _ends: dict[tuple[int, int], Lost] = field(default_factory=dict)  # (agent, life) not begun yet
    _aside: dict[int, list[Envelope]] = field(default_factory=dict)  # sent while out
    _asked: set[int] = field(default_factory=set)  # stamps a Need was sent for
    _scan: tuple[int, int] = (-1, 0)  # (batch, index in team of the first not known to cover it)

    def __post_init__(self) -> None:
        if self.monitor and MONITOR not in self.team:
            self.team = (MONITOR, *self.team)
        self._peers = {p: Ledger() for p in self.team if p != self.me}
        self.lives = {p: [Life(-1, 0)] for p in self.team}

    # ------------------------------------------------------------------ input

    def accept(self, env: Envelope, shared: bool = True) -> bool:
        """A message (own or a peer's); False if it is a duplicate or of no use (a robot's beyond
        its notice: kept aside while it is out, in case a rejoin counts it). ``shared`` False (a
        cross-check): its arrival and the watermark it implies are noted, but it joins no batch
        (the caller takes it in as it comes)."""
        if env.sender != self.me:
            peer = self._peers.get(env.sender)
            if peer is None or not peer.arrived(env.seq):
                return False
            peer.mark(env.implied, env.seq)
        lives = self.lives[env.sender]
        ever_out = len(lives) > 1 or lives[0].notice is not None
        if ever_out and not self.counts(env):
            if shared and env.sender in self.failed and env.stamp > self.done:
                self._aside.setdefault(env.sender, []).append(env)
            return False
        if not shared:
            return True
        if env.stamp <= self.done:
            raise LateMessage(
                f"message {env.seq} of agent {env.sender} stamped {env.stamp}, batch {self.done} is taken"
            )
        self._pending.setdefault(env.stamp, {})[(env.sender, env.seq)] = env
        return True

    def counts(self, env: Envelope) -> bool:
        """Whether ``env`` falls in one of its sender's lives (so far)."""
        return any(life.counts(env) for life in self.lives.get(env.sender, ()))

    def seen(self, sender: int, seq: int) -> bool:
        """Whether message ``seq`` of ``sender`` has arrived (a copy again is a duplicate)."""
        peer = self._peers.get(sender)
        return peer is not None and peer.has(seq)

    def accept_mark(self, mark: Mark | Need) -> None:
        """A watermark: a Mark's, or the one a Need carries."""
        peer = self._peers.get(mark.sender)
        if peer is not None:
            peer.mark(mark.watermark, mark.seq)

    def accept_lost(self, notice: Lost) -> None:
        """A notice: the robot's life ``notice.incarnation`` ends; its messages beyond it are
        dropped from every batch (kept aside while it is out). A notice of a life not begun yet
        here (its Back still in a batch to come) ends it as soon as it begins."""
        if self.monitor and notice.serial:  # one of the monitor's notices: its count
            self._peers[MONITOR].arrived(notice.serial)
        lives = self.lives.get(notice.agent)
        if lives is None or notice.agent == MONITOR or (notice.agent, notice.incarnation) in self._ends:
            return
        if notice.incarnation >= len(lives):
            self._ends[(notice.agent, notice.incarnation)] = notice
            return
        life = lives[notice.incarnation]
        if life.notice is not None:
            return  # a copy
        if notice.t <= self.done:
            raise LateMessage(
                f"failure notice of agent {notice.agent} stamped {notice.t}, batch {self.done} is taken"
            )
        life.end, life.upto, life.notice = notice.t, notice.seq, notice
        self.failed[notice.agent] = notice
        for msgs in self._pending.values():
            for key in [k for k, e in msgs.items() if e.sender == notice.agent and not life.counts(e)]:
                if key[1] > notice.seq:
                    self._aside.setdefault(notice.agent, []).append(msgs[key])
                del msgs[key]
        self._notices.setdefault(notice.t, []).append(notice)
        peer = self._peers.get(notice.agent)
        if peer is not None:
            peer.mark(notice.t - 1, notice.seq)

    def readmit(self, agent: int, t: int, seq: int) -> list[Envelope]:
        """Batch ``t`` (just taken) readmits ``agent`` (a :class:`Back`): its next life begins at
        stamp t + 1, counting its messages above ``seq``. Returns its messages kept aside that now
        count (they join their batches)."""
        if agent not in self.failed:
            return []
        del self.failed[agent]
        lives = self.lives[agent]
        life = Life(t + 1, seq)
        lives.append(life)
        end = self._ends.pop((agent, len(lives) - 1), None)
        back: list[Envelope] = []
        for env in self._aside.pop(agent, []):
            if life.counts(env):  # (stamped above t: its sender knew of the Back)
                self._pending.setdefault(env.stamp, {})[(env.sender, env.seq)] = env
                back.append(env)
        if end is not None:  # (declared while a Back was on its way: its life ends at once)
            self.accept_lost(replace(end, t=max(end.t, t + 1)))
        self._scan = (-1, 0)
        return back

    def member(self, agent: int, t: int) -> bool:
        """Whether ``agent`` takes part in batch t (a life of it spans it)."""
        return any(life.first <= t < life.end for life in self.lives[agent])

    # ------------------------------------------------------------------ batches

    def lacking(self, t: int) -> list[int]:
        """Members whose messages up to stamp t are not all known to have arrived."""
        return [p for p in self.team if self._lacks(p, t)]

    def complete(self, t: int) -> bool:
        if t <= self.done:
            return False
        # Who has covered batch t stays so: scan on from the first who had not (once per arrival)
        if self._scan[0] != t:
            self._scan = (t, 0)
        team, k = self.team, self._scan[1]
        while k < len(team):
            if self._lacks(team[k], t):
                self._scan = (t, k)
                return False
            k += 1
        self._scan = (t, k)
        return True

    def _lacks(self, p: int, t: int) -> bool:
        lives = self.lives[p]
        if len(lives) == 1 and lives[0].end > t:  # (the common case: never out)
            return self.speaker.committed < t if p == self.me else not self._peers[p].covers(t)
        if p == self.me:
            return self.member(p, t) and self.speaker.committed < t
        if self.member(p, t):
            return not self._peers[p].covers(t)
        # out at t: but every message of it that counts up to t must be in
        upto = max((life.upto for life in lives if life.end <= t), default=0)
        return self._peers[p].contiguous < upto

    def next_stamp(self) -> int | None:
        """The smallest stamp above the last batch taken that holds a message or a notice."""
        # (after every message a robot takes: no list built)
        best = min((s for s, m in self._pending.items() if m), default=None)
        if self._notices:
            first = min(self._notices)
            best = first if best is None else min(best, first)
        return best

    def take(self, t: int) -> list:
        """Batch t (complete): its messages in the one order, notices last. Skipped stamps
        between the last batch and t must be empty (callers take the next stamp first)."""
        if not self.complete(t):
            raise RuntimeError(f"batch {t} is not complete (waiting for {self.lacking(t)})")
        nxt = self.next_stamp()
        if nxt is not None and nxt < t:
            raise RuntimeError(f"batch {t} taken before batch {nxt}")
        msgs = self._pending.pop(t, {})
        notices = self._notices.pop(t, [])
        self.done = t
        for peer in self._peers.values():
            peer.forget(t)
        self._asked = {s for s in self._asked if s > t}
        batch: list = [msgs[k].message for k in sorted(msgs)]
        batch.extend(sorted(notices, key=lambda n: n.agent))
        return batch

    def ask_again(self) -> None:
        """The Needs sent so far may be lost (peers back from a partition that lost them): the
        next batch lacking is asked for again."""
        self._asked.clear()

    def ask(self, t: int) -> Need | None:
        """A Need for batch t, the first time it is asked for and only if a peer is lacking —
        and only for a batch without messages: a message stamped t reaches every participant,
        and each announces its watermark on it."""
        if t in self._asked or self._pending.get(t) or t in self._notices:
            return None
        if not [p for p in self.lacking(t) if p != self.me]:
            return None
        self._asked.add(t)
        return self.speaker.need(t)
