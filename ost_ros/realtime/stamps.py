"""The agreement layer: what a coordination computes is a function of the messages, not of when
they arrived (pure; no clock of its own, no I/O).

Sender side (:class:`Speaker`): every message gets (sender, seq, stamp). ``seq`` counts the
sender's messages from 1; the stamp is an integer step, ``max(ceil(event time), committed + 1)``,
so stamps never decrease with seq and never fall at or below a watermark the sender has given.
A participant *commits* step t once it has handled every event of time ≤ t (its own clock passed
t): from then on it sends nothing stamped ≤ t. It *announces* that (a :class:`Mark`) only when
someone waits for it — a peer's :class:`Need`, or any message stamped t it has sent or received
(everyone will need batch t) — and once per such stamp: no periodic heartbeat. Because the
watermark depends only on the participant's own clock, never on its comm progress, there is no
cascade: batch t is complete one round of announcements after every clock has passed t.

Receiver side (:class:`Batches`): batch t is *complete* once every live participant's announced
watermark is ≥ t and every message it sent up to that announcement has arrived (arrival order
across kinds is free: over DDS each topic is ordered on its own). A complete batch is taken out
in one order: the messages stamped t by (sender, seq), then the world's failure notices of t by
agent. Batches are taken in stamp order, each once.

Failures: the world's notice (:class:`~ost_ros.realtime.messages.Lost`) is stamped s ≥ the
robot's last watermark + 1 — a batch no survivor can have completed without it — and carries how
many messages of the robot count (those with seq ≤ its ``seq`` and a stamp < s). From batch s on
the robot is no participant: every survivor drops it from the same batch, on the same fact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ost_ros.realtime.messages import Envelope, Lost, Mark, Need


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
    # The highest step it may commit: every event up to it has been handled (an agent node: its
    # base's events are in up to there). A message stamped above it announces no more than it.
    ceiling: float = math.inf
    announced: int = -1  # the largest watermark peers can know (explicitly or implied)
    wanted: set[int] = field(default_factory=set)  # stamps peers wait for, not yet announced

    def send(self, message: object, time: float, shared: bool = True) -> Envelope:
        """Stamp ``message`` (happening at ``time``); it carries the watermark it implies — stamp
        - 1 unless the ceiling holds the commitment lower. ``shared``: it belongs to a batch (a
        cross-check does not: nobody waits for its stamp)."""
        stamp = stamp_of(time, self.committed)
        self.seq += 1
        self.committed = max(self.committed, min(stamp - 1, self._top()))
        self.announced = max(self.announced, self.committed)
        if shared:
            self.wanted.add(stamp)  # peers will need batch `stamp`: say when it is passed
        held = self.committed != stamp - 1
        return Envelope(self.me, self.seq, stamp, message, self.committed if held else None)

    def _top(self) -> int:
        return math.floor(self.ceiling + 1e-9) if math.isfinite(self.ceiling) else 1 << 62

    def need(self, stamp: int) -> Need:
        """A request for batch ``stamp``, carrying this participant's own watermark (so nobody
        waits for a Mark of the one who asks)."""
        self.announced = max(self.announced, self.committed)
        return Need(self.me, stamp, self.committed, self.seq)

    def commit(self, t: int) -> list[Mark]:
        """Every event of time ≤ t is handled: commit t (no higher than the ceiling) and announce
        it if someone waits."""
        t = min(t, self._top())
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
class _Peer:
    """What a receiver knows of one participant's messages."""

    marks: list[tuple[int, int]] = field(default_factory=list)  # (watermark, seq), ascending
    contiguous: int = 0  # every seq ≤ contiguous has arrived
    ahead: set[int] = field(default_factory=set)  # arrived seqs above contiguous

    def mark(self, watermark: int, seq: int) -> None:
        if self.marks and watermark <= self.marks[-1][0]:
            return  # an older (or implied, earlier) watermark: nothing new
        self.marks.append((watermark, seq))

    def arrived(self, seq: int) -> bool:
        """Note the arrival of ``seq``; False if it had already arrived."""
        if seq <= self.contiguous or seq in self.ahead:
            return False
        self.ahead.add(seq)
        while self.contiguous + 1 in self.ahead:
            self.contiguous += 1
            self.ahead.discard(self.contiguous)
        return True

    def covers(self, t: int) -> bool:
        """Every message stamped ≤ t has arrived."""
        for watermark, seq in self.marks:
            if watermark >= t:
                return self.contiguous >= seq
        return False

    def forget(self, t: int) -> None:
        """Batch t is taken: watermarks below it are of no more use (the last one stays)."""
        while len(self.marks) > 1 and self.marks[1][0] <= t:
            self.marks.pop(0)


@dataclass
class Batches:
    """One participant's incoming side: messages by stamp, until each batch is complete."""

    me: int
    team: tuple[int, ...]  # every participant, ascending
    speaker: Speaker  # own side: its commitment completes own batches
    done: int = -1  # the last batch taken
    failed: dict[int, Lost] = field(default_factory=dict)  # agent -> its notice
    _peers: dict[int, _Peer] = field(default_factory=dict)
    _pending: dict[int, dict[tuple[int, int], Envelope]] = field(default_factory=dict)  # stamp -> ...
    _notices: dict[int, list[Lost]] = field(default_factory=dict)  # stamp -> notices
    _asked: set[int] = field(default_factory=set)  # stamps a Need was sent for
    _scan: tuple[int, int] = (-1, 0)  # (batch, index in team of the first not known to cover it)

    def __post_init__(self) -> None:
        self._peers = {p: _Peer() for p in self.team if p != self.me}

    # ------------------------------------------------------------------ input

    def accept(self, env: Envelope, shared: bool = True) -> bool:
        """A message (own or a peer's); False if it is a duplicate or of no use (a dead robot's
        beyond its notice). ``shared`` False (a cross-check): its arrival and the watermark it
        implies are noted, but it joins no batch (the caller takes it in as it comes)."""
        if env.sender != self.me:
            peer = self._peers.get(env.sender)
            if peer is None or not peer.arrived(env.seq):
                return False
            peer.mark(env.implied, env.seq)
        notice = self.failed.get(env.sender)
        if notice is not None and not self._counts(env, notice):
            return False
        if not shared:
            return True
        if env.stamp <= self.done:
            raise LateMessage(
                f"message {env.seq} of agent {env.sender} stamped {env.stamp}, batch {self.done} is taken"
            )
        self._pending.setdefault(env.stamp, {})[(env.sender, env.seq)] = env
        return True

    def seen(self, sender: int, seq: int) -> bool:
        """Whether message ``seq`` of ``sender`` has arrived (a copy again is a duplicate)."""
        peer = self._peers.get(sender)
        return peer is not None and (seq <= peer.contiguous or seq in peer.ahead)

    def accept_mark(self, mark: Mark | Need) -> None:
        """A watermark: a Mark's, or the one a Need carries."""
        peer = self._peers.get(mark.sender)
        if peer is not None:
            peer.mark(mark.watermark, mark.seq)

    def accept_lost(self, notice: Lost) -> None:
        """The world's notice: the robot's messages beyond it are dropped from every batch."""
        if notice.agent in self.failed or notice.agent not in self.team:
            return
        if notice.t <= self.done:
            raise LateMessage(
                f"failure notice of agent {notice.agent} stamped {notice.t}, batch {self.done} is taken"
            )
        self.failed[notice.agent] = notice
        for msgs in self._pending.values():
            for key in [
                k for k, e in msgs.items() if e.sender == notice.agent and not self._counts(e, notice)
            ]:
                del msgs[key]
        self._notices.setdefault(notice.t, []).append(notice)
        peer = self._peers.get(notice.agent)
        if peer is not None:
            peer.mark(notice.t - 1, notice.seq)

    @staticmethod
    def _counts(env: Envelope, notice: Lost) -> bool:
        return env.seq <= notice.seq and env.stamp < notice.t

    # ------------------------------------------------------------------ batches

    def participants(self, t: int) -> list[int]:
        """Who batch t waits for the watermark of: the team without robots failed at or before
        it (their counted messages must still all be in: :meth:`complete`)."""
        return [p for p in self.team if p not in self.failed or self.failed[p].t > t]

    def lacking(self, t: int) -> list[int]:
        """Participants whose messages up to stamp t are not all known to have arrived."""
        return [p for p in self.participants(t) if self._lacks(p, t)]

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
        notice = self.failed.get(p)
        if notice is not None and notice.t <= t:  # gone: but every message of it that counts
            return p != self.me and self._peers[p].contiguous < notice.seq  # must be in

        if p == self.me:
            return self.speaker.committed < t
        return not self._peers[p].covers(t)

    def next_stamp(self) -> int | None:
        """The smallest stamp above the last batch taken that holds a message or a notice."""
        stamps = [s for s, m in self._pending.items() if m] + list(self._notices)
        return min(stamps) if stamps else None

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

    def envelopes(self, t: int) -> list[Envelope]:
        """The envelopes of a pending batch, in batch order (for its digest)."""
        msgs = self._pending.get(t, {})
        return [msgs[k] for k in sorted(msgs)]

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
