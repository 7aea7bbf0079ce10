"""Who is in the team, without a barrier (ROS-free, pure): the monitor that declares a robot out
and whose watermark every batch waits for, so that a robot declared out while it was only silent
can never have its later messages counted by some members and not by others.

The monitor is a participant of the agreement layer with no messages of its own but its notices
(:class:`~ost_ros.realtime.messages.Lost`, numbered by ``serial``). It commits a step only once it
has heard every member's watermark up to it (it is the last to commit): so when it declares robot
R — silent too long — it stamps the notice ``w + 1``, where ``(w, q)`` is R's last watermark it
heard, and no member can have taken that batch (none takes a batch above the monitor's watermark,
nor before it holds every notice the monitor counted up to it). R's messages stamped ≤ w are
exactly its seq ≤ q (the watermark's own promise), so the notice's two rules — seq ≤ q, stamp < s
— agree, whatever R sends after it wakes up.

A robot out asks to come back (:class:`~ost_ros.realtime.messages.Hello`); every member answers
with a stamped :class:`~ost_ros.realtime.messages.Back`, and the first in batch order readmits it
(:mod:`ost_ros.realtime.stamps`). From its Hello on, the monitor waits for its watermark again (it
may be a member from any Back's stamp on); if it dies meanwhile, it is declared again, for the
life a Back gave it.

The same object serves the in-process run (:mod:`ost_ros.realtime.run`: every broadcast through
:meth:`Monitor.hear`) and a membership node (``world_node.membership``), which must hold every
message it counts — it relays them — so it notes of each robot only the watermark whose messages
it holds all of (:meth:`Monitor.note`, with :meth:`Monitor.want` and :meth:`Monitor.readmitted` for
what else a message says) and hands a Hello to :meth:`Monitor.hear`; it never writes the monitor's
state itself.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field

from ost_ros.realtime.messages import MONITOR, Back, Envelope, Hello, Lost, Mark, Need

# Where a robot stands in the team at a time, as an observer of the run sees it (the animation):
IN = ""  # a member
SILENT = "silent"  # its process stopped, not declared yet (every batch waits for it)
OUT = "out"  # declared out, not back yet (its base stopped)
DEAD = "dead"  # failed for good
ABSENT = "absent"  # not joined yet


def misfit(payload: object, team: Collection[int], lives: Mapping[int, int]) -> str | None:
    """Why a membership message does not fit the team (None: it does) — a Hello, a notice or a
    Back from or about a robot not on the team, or for a life older than the one ``lives`` knows
    (a copy of the newest is fine: a robot says its Hello again when peers come back). Such a
    message is dropped, warned about and counted by the node that receives it (``stale``)."""
    if isinstance(payload, Hello):
        who, life, what = payload.sender, payload.incarnation, "hello"
    elif isinstance(payload, Lost):
        who, life, what = payload.agent, payload.incarnation, "notice"
    elif isinstance(payload, Back) or (isinstance(payload, Envelope) and isinstance(payload.message, Back)):
        b = payload if isinstance(payload, Back) else payload.message
        who, life, what = b.agent, b.incarnation, "back"
    else:
        return None
    if who not in team:
        return f"a {what} for agent {who}, not on the team"
    now = lives.get(who, 0)
    if life < now:
        return f"a {what} for life {life} of agent {who}, whose life now is {now}"
    return None


@dataclass
class Declaration:
    """What the monitor stamps on a notice: robot ``agent``'s life ``life`` ends at batch
    ``stamp``; its messages with seq ≤ ``seq`` count (its last watermark heard: ``watermark``,
    where its counted sensing ends); the notice is the monitor's ``serial``-th."""

    agent: int
    life: int
    stamp: int
    seq: int
    watermark: int
    serial: int


@dataclass
class Monitor:
    """The monitor's side of the agreement layer (see the module docstring)."""

    team: tuple[int, ...]
    committed: int = -1  # it declares nothing stamped ≤ committed any more
    announced: int = -1
    serial: int = 0  # notices issued
    heard: dict[int, tuple[int, int]] = field(default_factory=dict)  # agent -> (watermark, seq)
    out: dict[int, int] = field(default_factory=dict)  # agent -> the life that ended (until a Hello)
    lives: dict[int, int] = field(default_factory=dict)  # agent -> its life now (what a notice ends)
    wanted: set[int] = field(default_factory=set)
    dead: set[int] = field(default_factory=set)  # declared for good (their lives end as they come)
    declared: list[Declaration] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.heard = {a: (-1, 0) for a in self.team}
        self.lives = {a: 0 for a in self.team}

    # ------------------------------------------------------------------ input

    def hear(self, payload: object, now: float) -> list[Mark]:
        """Anything a robot broadcast: its watermark, a stamp someone will wait for, a Hello, a
        Back. Returns the Marks to send."""
        if isinstance(payload, Envelope):
            self.note(payload.sender, payload.implied, payload.seq)
            if isinstance(payload.message, Back):
                self.readmitted(payload.message)
            if bool(getattr(payload.message, "SHARED", True)):
                self.want(payload.stamp)
        elif isinstance(payload, Mark):
            self.note(payload.sender, payload.watermark, payload.seq)
        elif isinstance(payload, Need):
            self.note(payload.sender, payload.watermark, payload.seq)
            self.want(payload.stamp)
        elif isinstance(payload, Hello) and payload.incarnation > self.out.get(payload.sender, 1 << 30):
            # it may be a member again from any Back's stamp on: wait for its watermark
            del self.out[payload.sender]
        return self.tick(now)

    def note(self, agent: int, watermark: int, seq: int) -> None:
        """Robot ``agent`` has passed ``watermark`` with ``seq`` messages sent (a node that must
        hold every message it counts — to relay them — notes only what it holds without a gap)."""
        if agent not in self.lives:
            return
        w, q = self.heard.get(agent, (-1, 0))
        if watermark > w:
            self.heard[agent] = (watermark, max(seq, q))

    def want(self, stamp: int) -> None:
        """Every member will need batch ``stamp`` (a message stamped so, a Need, a notice): the
        next :meth:`tick` that commits it says so."""
        self.wanted.add(stamp)

    def readmitted(self, back: Back) -> None:
        """A member's Back readmits ``back.agent`` as its life ``back.incarnation``: the life its
        next notice ends (a copy, or an older life's Back heard late, changes nothing)."""
        self.lives[back.agent] = max(self.lives.get(back.agent, 0), back.incarnation)

    def misfit(self, payload: object) -> str | None:
        """Why a membership message does not fit the team as the monitor knows it (:func:`misfit`)."""
        return misfit(payload, self.team, self.lives)

    def away(self) -> list[int]:
        """The robots out or dead, in id order (their messages nobody but the monitor says again)."""
        return sorted(set(self.out) | self.dead)

    def members(self) -> list[int]:
        """The robots whose watermark it waits for: every robot not out (a robot asking back
        included), not dead."""
        return [a for a in self.team if a not in self.out and a not in self.dead]

    def tick(self, now: float) -> list[Mark]:
        """Commit as far as its clock (``now``; infinite: none — a node's, whose members'
        watermarks bound it anyway) and every member's watermark allow; announce what is
        wanted."""
        marks = [self.heard[a][0] for a in self.members()]
        clock = [math.floor(now + 1e-9)] if math.isfinite(now) else []
        top = min(clock + marks) if clock + marks else self.committed
        if top > self.committed:
            self.committed = top
        due = [w for w in self.wanted if w <= self.committed]
        if not due:
            return []
        self.wanted.difference_update(due)
        if max(due) <= self.announced:
            return []
        self.announced = self.committed
        return [Mark(MONITOR, self.committed, self.serial)]

    def next_wanted(self) -> int | None:
        """The smallest stamp someone waits for that it has not committed (a timer for then, if
        only its clock holds it back)."""
        ahead = [w for w in self.wanted if w > self.committed]
        return min(ahead) if ahead else None

    # ------------------------------------------------------------------ notices

    def declare(self, agent: int, dead: bool = False) -> Declaration | None:
        """Robot ``agent`` is silent too long (``dead``: and gone for good): the stamp and counts
        of its notice, or None if its life now has a notice already. Stamped one above its last
        watermark heard (the monitor never commits beyond it while it waits for it)."""
        if dead:
            self.dead.add(agent)
        life = self.lives.get(agent, 0)
        if agent in self.out and self.out[agent] >= life:
            return None
        if any(d.agent == agent and d.life == life for d in self.declared):
            return None
        w, q = self.heard.get(agent, (-1, 0))
        self.serial += 1
        d = Declaration(agent, life, max(w + 1, self.committed + 1), q, w, self.serial)
        self.declared.append(d)
        self.want(d.stamp)  # every member will need that batch: say when it is passed
        self.out[agent] = life
        return d
