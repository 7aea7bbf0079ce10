"""One robot without a barrier, ROS-free: its runtime drives its body (search and motion,
driving its base by goals: :mod:`ost_ros.realtime.body`) and feeds its comm module batch by batch
(the agreement layer: :mod:`ost_ros.realtime.stamps`).

:class:`RealtimeAgent` is a set of callbacks — ``start``, ``on_message``, ``on_result``,
``on_detection``, ``on_carry``, ``on_feedback``, ``on_clock``, ``again`` — each given the current
time and returning what to do as a list of outputs (:mod:`ost_ros.realtime.outputs`):
:class:`Publish` (to every peer), :class:`SendGoal` (to its own base), :class:`AskFeedback` (where
will the base be at a time), :class:`WakeAt` (call ``on_clock`` then), and a
:class:`~ost_ros.realtime.messages.Digest` (for observers). It knows nothing of who calls it: the
in-process run (:mod:`ost_ros.realtime.run`) and the agent node wire the same object.

The body reuses the protocol's own agent the way the event engine does: at each decision (a goal
reached, news in its sensor, the comm changed something, a step after it acted) it asks for its
own plan; a settled first segment becomes a goal (sweep/walk: FOLLOW that path; hold/carry: CARRY
with the assignment's group; wait: STAND), otherwise it acts for one step. So at latency 0 the
run is the step engine's.

The comm module sees only complete batches, in stamp order: the schedule it computes is a
function of the stamped messages. Everything the body reports — finds, search done, its status
after a failure — goes out as a stamped message and enters the comm (its own included) only
through a batch. How far the robot commits is its :class:`~ost_ros.realtime.commit.CommitRule`'s.

Its state, in named parts: ``rule`` (what it may commit), ``decisions`` (when it last decided
and acted, whether a decision is to be taken again), ``goals`` (what runs on its base),
``status`` (its status after a failure), ``life`` (its place in the team: out, its life, the
Hellos it answers) and ``record`` (what the run reports of it).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from enum import Enum

from ost_ros.coordination import Assignment
from ost_ros.model import Cell, can_move
from ost_ros.motion import apply
from ost_ros.protocols.plans import Segment
from ost_ros.protocols.shared.agent import GlobalState
from ost_ros.realtime.body import RtScheduleAgent
from ost_ros.realtime.commit import EPS, CommitRule, Gate
from ost_ros.realtime.messages import (
    FINISH_STATE,
    SEARCHING_STATE,
    Action,
    ActionKind,
    Back,
    Digest,
    Envelope,
    Hello,
    Lost,
    Mark,
    Need,
    Observation,
    RtStatus,
)
from ost_ros.realtime.outputs import AskFeedback, Output, Publish, SendGoal, WakeAt
from ost_ros.realtime.stamps import Batches, Speaker, stamp_of
from ost_ros.realtime.world import (
    ABORTED,
    REACHED,
    REFUSED,
    Carry,
    CarryStarted,
    Detection,
    Feedback,
    Follow,
    Goal,
    GoalResult,
    Stand,
)
from ost_ros.search import route

__all__ = ["EPS", "RealtimeAgent", "RtScheduleAgent"]


def _digest(text: str) -> str:
    return hashlib.blake2b(text.encode(), digest_size=8).hexdigest()


# ----------------------------------------------------------------------------- its state, in parts


@dataclass
class Decisions:
    """When its body last decided and acted."""

    last: float = -1.0  # the time of the last decision
    # The next answer is decided on even if it is of the last decision's moment, and may be as of
    # a time before the last decision (never before the last goal it sent): a decision asked for
    # again (its picture was stale, a goal ended, the comm changed what it should do)
    again: bool = True
    acted: int = -1  # step of the last act
    wakes: set[float] = field(default_factory=set)  # the timers asked for (WakeAt), not fired yet

    def redo(self) -> None:
        """The next decision is taken whatever the last one was (see ``again``)."""
        self.again = True

    def took(self, at: float) -> bool:
        """A decision as of ``at``: False if one was taken at that moment already."""
        if not self.again and abs(at - self.last) < EPS:
            return False  # one decision per moment
        self.last, self.again = at, False
        return True

    def floor(self, goal_at: float) -> float:
        """No decision is taken as of before this (its last goal's time; its last decision's,
        unless one is asked for again)."""
        return goal_at if self.again else max(goal_at, self.last)


@dataclass
class Goals:
    """What it asked of its base (by its own picture)."""

    goal: Goal | None = None  # the goal running on its base
    id: int = 0  # the id of the last goal sent
    label: str = SEARCHING_STATE  # the state label its base last got
    sweep: tuple[Sequence[Cell], int] | None = None  # the running goal = that sweep from that index
    at: float = -1.0  # the time the last goal it sent takes over at (at the earliest)
    lifted: int = -1  # the object whose carry its base has begun (-1: none, as Feedback.carrying)
    blocked: int = -1  # the object whose group lost a member: no CARRY for it until the comm knows
    revive: bool = False  # its base was stopped (it was out): the next goal, even to stand, is sent


@dataclass
class Status:
    """Its status after a failure (an :class:`~ost_ros.realtime.messages.RtStatus`)."""

    due: bool = False  # a failure was learnt: its status goes out at the next decision
    keep: int = 0  # own schedule entries done or under way when it was learnt
    # Its let-go of a hold it is unsure of (CommitRule.unsure), sent and not answered yet (its goal
    # id), and the hold it let go of — (goal id, goal, label, sweep): resumed if its group lifted first
    letting_go: int | None = None
    held: tuple[int, Goal | None, str, tuple[Sequence[Cell], int] | None] | None = None


@dataclass
class Life:
    """Its place in the team: declared out (a notice of it taken), its life now, its own Hello
    (the life it asked for), peers' Hellos it is to answer, how often it came back."""

    out: bool = False
    incarnation: int = 0
    hello: int = 0  # the life its last Hello asked for
    asked_back: Hello | None = None  # its last Hello (said again to peers back from a partition)
    hellos: dict[int, Hello] = field(default_factory=dict)
    rejoins: int = 0


@dataclass
class Record:
    """What the run reports of the robot. ``whole`` (in process): every batch's stamp, when it
    was taken and its digest, and every message's (stamp, seq) — the run's report computes the
    disagreements, the heal times and the messages counted from them at the end; an agent node
    keeps only the counts (the run is as long as it is, and these would grow with it)."""

    whole: bool = True
    max_lag: float = 0.0  # the most a batch was processed after its stamp (steps)
    batches: int = 0  # batches taken
    messages: int = 0  # messages sent
    last: tuple[int, int] | None = None  # (stamp, seq) of the last message sent
    sent: list[tuple[int, int]] = field(default_factory=list)  # (stamp, seq) of every message
    digests: dict[int, Digest] = field(default_factory=dict)  # stamp -> digest (coordinations)
    processed: set[int] = field(default_factory=set)  # stamps of every batch taken
    taken_at: dict[int, float] = field(default_factory=dict)  # stamp -> when it was taken

    def took(self, t: int, now: float) -> None:
        self.batches += 1
        self.max_lag = max(self.max_lag, now - t)
        if self.whole:
            self.processed.add(t)
            self.taken_at[t] = now

    def said(self, env: Envelope) -> None:
        self.messages += 1
        self.last = (env.stamp, env.seq)
        if self.whole:
            self.sent.append(self.last)

    def digest(self, d: Digest) -> None:
        if self.whole:
            self.digests[d.stamp] = d


class Unfinished(Enum):
    """Why a goal of its base ended without reaching its end, as the runtime takes it."""

    MEMBER_FAILED = "a member of its group failed: wait for the comm, or decide on what it says"
    STALE = "planned from a picture gone stale, or another client took its base over: decide again"
    STOPPED = "its base was stopped: it was declared out (its notice is on the way)"


# The base's code (RealtimeWorld's REFUSALS) -> how the runtime takes it; a code not here that
# refused a goal is a warning (a fault of its own planning).
UNFINISHED = {
    "MEMBER_FAILED": Unfinished.MEMBER_FAILED,
    "START": Unfinished.STALE,  # its path started where the base no longer is
    "PREEMPTED": Unfinished.STALE,  # (an operator's goal took its base over)
    "DELIVERED": Unfinished.STALE,  # (an answer from mid-carry came after the carry's result)
    "FAILED": Unfinished.STOPPED,
}
# Its base across a network: a hold may come after its base moved on past the object.
UNFINISHED_REMOTE = {**UNFINISHED, "NOT_AT_OBJECT": Unfinished.STALE}


# ----------------------------------------------------------------------------- the runtime


@dataclass
class RealtimeAgent:
    """One robot's runtime without a barrier (see the module docstring)."""

    agent: RtScheduleAgent
    team: tuple[int, ...]
    remote_base: bool = False  # its base's events cross a network (an agent node), not in process
    monitor: bool = False  # a membership monitor takes part (ost_ros.realtime.membership)
    record: Record = field(default_factory=Record)
    speaker: Speaker = field(init=False)
    batches: Batches = field(init=False)
    rule: CommitRule = field(init=False)
    decisions: Decisions = field(default_factory=Decisions, init=False)
    goals: Goals = field(default_factory=Goals, init=False)
    status: Status = field(default_factory=Status, init=False)
    life: Life = field(default_factory=Life, init=False)
    _asked_for: Assignment | None = field(default=None, init=False)  # the task it asked ahead for
    # caches: CCP's improved planner's open entries, the comm's next event after the last batch,
    # the shared view's signature and text
    _open: tuple[tuple[int, ...], dict[int, frozenset[int]]] = field(
        default_factory=lambda: ((), {}), init=False
    )
    _event: tuple[int, int | None] = field(default=(-2, None), init=False)
    _sign: tuple = field(default=(), init=False)
    _view: str = field(default="", init=False)
    _out: list[Output] = field(default_factory=list, init=False)

    def __post_init__(self) -> None:
        self.speaker = Speaker(self.agent.id)
        self.batches = Batches(self.agent.id, self.team, self.speaker, monitor=self.monitor)
        self.rule = CommitRule(remote=self.remote_base)
        self._view = self._schedule_view() or ""

    @property
    def id(self) -> int:
        return self.agent.id

    @property
    def comm(self):
        return self.agent.comm

    @property
    def out(self) -> bool:
        """Declared out, not back yet."""
        return self.life.out

    @property
    def incarnation(self) -> int:
        """Its life now (0 until it comes back)."""
        return self.life.incarnation

    def across_a_network(self) -> None:
        """Its base's events cross a network (an agent node; in process, ``--base-delay``)."""
        self.remote_base = self.rule.remote = True

    def destination(self, obj: int) -> Cell:
        """Where a known object goes (its base's picture of a carry needs it)."""
        return self.comm.knowledge.objects[obj].destination

    def base_known(self, t: float) -> None:
        """Every event of its base up to time ``t`` has been handled (an agent node: its base's
        clock says how many it has sent up to t, and all are in): it may commit up to t, and
        never further (in process without a base lag: no limit)."""
        self.rule.base_known = t
        if self.rule.status_ready(t):
            self.decisions.redo()
            self.rule.due.add(t)  # its status can say now (its caller's clock comes)

    def held(self, now: float) -> bool:
        """Whether its commitment is held back by its base's events (not all in up to ``now``)
        while someone waits for it, or a batch due waits for it: its caller calls
        :meth:`on_clock` again once more of them are in."""
        return self.rule.held(now, self.speaker.committed, self._waited_for())

    def _waited_for(self) -> Iterator[int | None]:
        yield self.speaker.next_wanted()
        yield self._next_batch()

    def decision_due(self, now: float) -> bool:
        """Whether a decision is due by ``now`` and not taken yet."""
        return bool(self.rule.due_by(now))

    def next_wake(self, now: float) -> float | None:
        """The earliest timer it asked for after ``now`` (None: none)."""
        return min((w for w in self.decisions.wakes if w > now), default=None)

    def asking(self) -> float | None:
        """The time of the decision waiting for where its base is, if one is."""
        return self.rule.asked

    def waiting(self, now: float) -> tuple[int, str] | None:
        """The oldest batch due and still incomplete, if any: (its stamp, what it lacks)."""
        t = self._next_batch()
        if t is None or t > now or self.batches.complete(t):
            return None
        if self.speaker.committed < t:
            if self.rule.base_known < t:
                known = self.rule.base_known
                return t, f"batch {t} waits for its own commit: its base's events are in up to {known:g}"
            return t, f"batch {t} waits for its own commit"
        return t, f"batch {t} waits for the messages or watermarks of agents {self.batches.lacking(t)}"

    # ------------------------------------------------------------------ callbacks

    def start(self, now: float) -> list[Output]:
        self._decide_at(now, now)
        return self._flush(now)

    def on_clock(self, now: float) -> list[Output]:
        """A timer fired (``WakeAt``): decisions due, then commit the time passed."""
        self.decisions.wakes = {w for w in self.decisions.wakes if w > now + EPS}
        due = self.rule.due_by(now)
        if due:
            self.rule.due.difference_update(due)
            self._decide_at(min(due), now)
        self._commit(now)
        return self._flush(now)

    def on_message(self, payload: Envelope | Mark | Need | Lost | Hello, now: float) -> list[Output]:
        """A peer's message (or the monitor's failure notice), as it arrives."""
        self._commit(now)
        if isinstance(payload, Envelope):
            shared = _shared(payload.message)
            if self.batches.accept(payload, shared):
                if shared:
                    self._marks(self.speaker.want(payload.stamp), now)
                else:  # a cross-check: taken in as it comes (no batch waits for it)
                    self.comm.cross_check(payload.message)
        elif isinstance(payload, Mark):
            self.batches.accept_mark(payload)
        elif isinstance(payload, Need):
            self.batches.accept_mark(payload)  # the watermark it carries
            self._marks(self.speaker.want(payload.stamp), now)
        elif isinstance(payload, Lost):
            self.batches.accept_lost(payload)
            self._marks(self.speaker.want(payload.t), now)
            if (
                payload.agent == self.id
                and payload.incarnation == self.life.incarnation
                and not self.life.out
            ):
                self._declared_out(now)
        elif isinstance(payload, Hello) and payload.incarnation > self.comm.incarnation.get(
            payload.sender, 0
        ):
            self.life.hellos[payload.sender] = payload
            self._sponsor(now)
        return self._flush(now)

    def again(self, now: float) -> list[Output]:
        """Peers cut off are back, and what crossed meanwhile is lost (a partition longer than
        DDS keeps a peer): its watermark again, and the batch it waits for asked for again (its
        Needs may be lost too). Its messages again are its node's to send: it keeps them as
        sealed (``RealtimeAgentNode.readers_back``; in process, the runner's ``heal``)."""
        self._commit(now)
        self.batches.ask_again()
        if self.speaker.committed >= 0:
            self._out.append(Publish(Mark(self.id, self.speaker.committed, self.speaker.seq)))
        life = self.life
        if life.out and life.asked_back is not None and life.asked_back.incarnation > life.incarnation:
            self._out.append(Publish(life.asked_back))  # out, it still asks to come back
        return self._flush(now)

    def on_result(self, res: GoalResult, now: float) -> list[Output]:
        if res.code == "CARRYING" and self._lifted_first(res, now):
            return self._flush(now)
        g = self.goals
        if res.goal != g.id or self.life.out:
            return self._flush(now)  # an older goal's (preempted) result
        d = self.decisions
        if self.remote_base and not d.again and res.time <= d.last + EPS:
            # a decision at or after its time was taken without it (its base's events cross a
            # network, and one that came first made its picture look whole): that one again
            d.redo()
        if res.outcome == REACHED:
            if g.sweep is not None and isinstance(g.goal, Follow):
                self.agent.search.index = g.sweep[1] + len(g.goal.path) - 1
            g.goal, g.sweep = None, None
            self._decide_at(res.time, now)
        elif res.outcome in (ABORTED, REFUSED):
            g.goal, g.sweep, g.lifted = None, None, -1
            why = (UNFINISHED_REMOTE if self.remote_base else UNFINISHED).get(res.code)
            if why is Unfinished.MEMBER_FAILED:
                self._member_failed(now)
            elif why is Unfinished.STALE:
                self._decide_again(now)
            elif why is None and res.outcome == REFUSED:
                self.agent.warnings.append(f"goal refused at {res.time}: {res.reason}")
        return self._flush(now)

    def _member_failed(self, now: float) -> None:
        """Its carry was aborted: a member of its group failed."""
        task = self._task()
        if task is None:
            return  # it let go of it already (its comm heard of the failure first)
        if self._member_lost(task):
            # its comm has heard of the failure already (the notice may be stamped well before
            # the abort reached it): decide on what the comm now says
            self._decide_again(now)
        else:
            self.goals.blocked = task.object  # until the comm hears of the failure

    def on_detection(self, det: Detection, now: float) -> list[Output]:
        a = self.agent
        if self.life.out:
            return self._flush(now)
        if not any(a.news(o) for o in det.objects):
            return self._flush(now)
        if self.remote_base or det.time < now - EPS:
            # Its base is across a network (a node: the robot moves on while it hears of the
            # detection and asks where it is), or this one came late: what it sensed there is
            # reported as of then, not looked for again — whatever the body does by now (it may
            # have moved its sweep past the cell on its picture before the base got there).
            for m in a.report_late(math.ceil(det.time - EPS), det.sensed):
                self._send(m, det.time)
        elif a.state is GlobalState.SEARCHING:  # (heard of at once: as the lockstep robot senses)
            self._decide_at(det.time, now)
        return self._flush(now)

    def on_carry(self, ev: CarryStarted, now: float) -> list[Output]:
        if self.id in ev.group:
            self.goals.lifted = ev.object
        return self._flush(now)

    def on_feedback(self, fb: Feedback, now: float) -> list[Output]:
        self.rule.asked = None
        if fb.time > now + EPS:  # mid-move: decide when the move ends
            self._decide_at(fb.time, now)
        else:
            self._decide(fb, now)
        if self.rule.deferred is not None and self.rule.asked is None:
            t, self.rule.deferred = self.rule.deferred, None
            self._commit(t)
        return self._flush(now)

    # ------------------------------------------------------------------ decisions

    def _decide_at(self, t: float, now: float) -> None:
        """A decision is due at time t (asked for now if t has come)."""
        if t > now + EPS:
            self.rule.due.add(t)
            self._wake(t)
            return
        if self.rule.asked is None:
            self.rule.asked = now
            # (its base across a network: as of when it was due — decision_time — unless that
            # goes back before its last decision or the goal it sent last)
            back = t < self.decisions.floor(self.goals.at) - EPS
            self._out.append(AskFeedback(t if self.remote_base and not back else now))

    def _decide_again(self, now: float) -> None:
        """Decide now, whatever it decided last."""
        self.decisions.redo()
        self._decide_at(now, now)

    def _decide(self, fb: Feedback, now: float) -> None:
        if not self.decisions.took(fb.time):
            return  # one decision per moment
        if self.life.out:
            self._say_hello(fb)
            return
        a = self.agent
        s = math.ceil(fb.time - EPS)
        self._sync(fb, s)
        if self.status.due and self._sure_of_carry(fb, now):
            self._status(fb, s)
        plan = a.plan(s, fb.cell)
        searching = a.state.value == SEARCHING_STATE
        if plan.settled and not (searching and any(a.news(o) for o in fb.sensed)):
            self._follow_plan(plan[0], fb)
            return
        s = max(s, self.decisions.acted + 1)
        self.decisions.acted = s
        action = a.act(Observation(self.id, s, fb.cell, fb.sensed))
        for m in a.body_messages():
            self._send(m, fb.time)
        self._follow_action(action, fb)
        self._decide_at(s + 1, now)
        self._ask_ahead()

    def _sync(self, fb: Feedback, s: int) -> None:
        a, g = self.agent, self.goals
        a.t, a.position = s, fb.cell
        if self.remote_base:
            a.lifted = fb.carrying if fb.carrying >= 0 else g.lifted
        if g.sweep is not None and fb.goal == g.id and fb.index >= 0:
            path, base = g.sweep
            if a.search.path is path:
                a.search.index = base + fb.index

    def _follow_plan(self, seg: Segment, fb: Feedback) -> None:
        if seg.kind == "sweep":
            path = tuple(seg.path[seg.index :])
            self._goal(Follow(path, seg.state), fb, sweep=(seg.path, seg.index))
        elif seg.kind == "walk":
            assert seg.target is not None
            self._goal(Follow(tuple(route([fb.cell, seg.target])), seg.state), fb)
        elif seg.kind == "wait":
            self._goal(Stand(seg.state), fb)
        else:
            task = self._task()
            assert task is not None and task.object == seg.object
            self._carry(task, seg.state, fb)

    def _follow_action(self, action: Action, fb: Feedback) -> None:
        a = self.agent
        if action.kind is ActionKind.MOVE:
            nxt = apply(fb.cell, action.direction)
            g = self.goals.goal
            if (
                isinstance(g, Follow)
                and fb.goal == self.goals.id
                and 0 <= fb.index < len(g.path) - 1
                and g.path[fb.index + 1] == nxt
                and _searching(g.state) == _searching(action.state)
            ):
                return  # the running goal makes this very move
            self._goal(Follow((fb.cell, nxt), action.state), fb)
        elif action.kind is ActionKind.CARRY:
            task = self._task()
            assert task is not None and task.object == action.object
            self._carry(task, action.state, fb)
        else:
            if isinstance(self.goals.goal, Follow) and can_move(action.t, a.period):
                self._goal(Stand(action.state), fb, force=True)  # it would move: stop it
            else:
                self._goal(Stand(action.state), fb)

    def _task(self) -> Assignment | None:
        """What it holds or carries (or goes to): its schedule entry (the object and its group)."""
        return self.agent.current

    def _member_lost(self, task: Assignment) -> bool:
        lost = self.comm.lost
        return any(j in lost for j in task.agents if j != self.id)

    def _carry(self, task: Assignment, state: str, fb: Feedback) -> None:
        if task.object == self.goals.blocked or self._member_lost(task):
            # its group has lost a member: wait for the comm (to hear of it, or to re-plan)
            self._goal(Stand(state), fb)
            return
        if not self._frozen(task):
            self._goal(Stand(state), fb)  # a re-plan may still move it: wait for the comm
            return
        g = self.goals.goal
        if (
            self.remote_base
            and isinstance(g, Follow)
            and fb.goal == self.goals.id
            and 0 <= fb.index < len(g.path) - 1
        ):
            # its base runs on past this cell, and a hold crossing the network would come after
            # it left: stop it first (where it stops, its base says; then it holds, or walks back)
            self._goal(Stand(state), fb, force=True)
            return
        self._goal(Carry(task.object, tuple(task.agents), state), fb)

    def _frozen(self, task: Assignment) -> bool:
        """Whether no re-plan of a batch it has not taken yet can move ``task`` (always true but
        for CCP's improved planner). A re-plan in batch t moves only what no member can have
        taken up by step t + 1 (:meth:`Knowledge.open_entries`), and what is kept for a step is
        kept for every later one: so the task is safe to hold for once every batch up to s* − 2
        is known — taken, or complete and empty with no comm event — where s* is the first step
        a plan keeps it for. A robot may walk to an object before that (nobody sees a walk),
        never hold or carry it: a lagging robot never holds for a group that a re-plan it has
        not read yet dissolved. Until then its commitment stays below this step (the rule's
        gate), it asks for those batches (a :class:`Need`) and decides again once they are in
        (:meth:`_ungate`)."""
        self.rule.gate = None
        u = self._settles(task)
        if u is None or u <= self.batches.done or self._known(u):
            return u is not None
        # (its commit stays below this step meanwhile — unless the gate needs this step itself)
        self.rule.gate = Gate(u, self.agent.t if u < self.agent.t - 1 else None)
        return False

    def _settles(self, task: Assignment) -> int | None:
        """The last batch that can still re-plan ``task`` (−1: none; None: it is re-planned
        away already, its batch's resync on the way)."""
        comm = self.comm
        if getattr(comm, "planner", "paper") != "improved":
            return -1
        k = comm.knowledge
        pos = next((p for p, e in enumerate(k.schedule) if e is task), None)
        if pos is None:
            return None
        done = self.batches.done
        lo, hi = done + 2, max(done + 2, task.start)
        while lo < hi:  # the first step a plan keeps it for (a plan for its start does)
            mid = (lo + hi) // 2
            if pos in self._open_at(mid):
                lo = mid + 1
            else:
                hi = mid
        return lo - 2

    def _ask_ahead(self) -> None:
        """Taking up a task it will hold or carry, it asks now for the batches that settle it
        (:meth:`_frozen`): peers announce their watermarks as their clocks pass it, so on its
        arrival the gate is open, not a round trip away."""
        task = self._task()
        if task is None or self._asked_for is task:
            return
        self._asked_for = task
        u = self._settles(task)
        if u is None or u <= self.batches.done:
            return
        nxt = self._next_batch()
        if (nxt is None or nxt > u) and not self.batches.complete(u):
            self._need(u)

    def _need(self, u: int) -> None:
        """Ask the peers lacking for batch u to announce their watermarks (once per batch)."""
        need = self.batches.ask(u)
        if need is not None:
            self._out.append(Publish(need))

    def _open_at(self, s: int) -> frozenset[int]:
        k, comm = self.comm.knowledge, self.comm
        key = (len(k.schedule), k.coordinations, comm.losses, comm.joins, k.base_len)
        if self._open[0] != key:
            self._open = (key, {})
        cache = self._open[1]
        if s not in cache:
            cache[s] = frozenset(k.open_entries(s))
        return cache[s]

    def _known(self, u: int) -> bool:
        """Every batch up to stamp u is taken, or complete with nothing in it for the comm."""
        if u <= self.batches.done:
            return True
        nxt = self._next_batch()
        return (nxt is None or nxt > u) and self.batches.complete(u)

    def _goal(
        self, goal: Goal, fb: Feedback, sweep: tuple[Sequence[Cell], int] | None = None, force: bool = False
    ) -> None:
        """Send ``goal`` unless the running one already does it."""
        if self.status.letting_go is not None:
            return  # its let-go is not answered yet: nothing else goes to its base meanwhile
        if self.life.out:
            return  # its base was stopped when it was declared: nothing until it is back
        gs = self.goals
        g = gs.goal
        running = g is not None and fb.goal == gs.id
        if not force and running:
            if isinstance(goal, Follow) and isinstance(g, Follow) and fb.index >= 0:
                if g.path[fb.index :] == goal.path and _searching(g.state) == _searching(goal.state):
                    return
            elif isinstance(goal, Carry) and isinstance(g, Carry):
                if (g.object, g.group) == (goal.object, goal.group):
                    return
            elif isinstance(goal, Stand) and isinstance(g, Stand) and g.state == goal.state:
                return
        same = isinstance(goal, Stand) and not running and _finish(goal.state) == _finish(gs.label)
        if same and not gs.revive:
            return  # it stands already, and nothing about it changes
        gs.revive = False
        gs.id += 1
        gs.goal = goal
        gs.sweep = sweep
        gs.label = goal.state
        gs.lifted = -1  # a new goal: no lift of it yet (on_carry says when)
        gs.at = fb.time
        self._out.append(SendGoal(gs.id, goal, fb.time))

    # ------------------------------------------------------------------ failures

    def _freeze(self, now: float) -> None:
        """The comm has learnt of a failure: stop what is not under way (a carry the group has
        begun, a sweep go on), read no more of the schedule until the recovery, and say so (the
        status, at the next decision)."""
        a, gs = self.agent, self.goals
        a.stop_reading()
        # (a carry whose group has lost a member is over, even if its base has not said so yet:
        # the notice may be stamped well before the abort reaches it)
        carry = isinstance(gs.goal, Carry) and not (a.current is not None and self._member_lost(a.current))
        going = carry and gs.lifted == gs.goal.object  # type: ignore[union-attr]
        # (its base across a network may have lifted and not said so yet: it says once it has)
        self.rule.unsure = carry and not going and self.remote_base and a.current is not None
        if a.current is not None and not going and not self.rule.unsure:
            self._let_go(now)
        elif a.current is None and a.state in (GlobalState.RETURNING, GlobalState.FINISH):
            a.state = GlobalState.DECISION
        gs.blocked = -1
        self.status.keep = a.taken
        self.status.due = True
        self._decide_at(math.floor(now + EPS) + 1, now)

    def _let_go(self, now: float) -> None:
        """What it has taken up and not begun goes back into the pool; a hold is let go now (no
        lift without it)."""
        self.agent.give_back()
        if isinstance(self.goals.goal, Carry) and not self.life.out:
            self._stand(now)

    def _stand(self, now: float, unless_carrying: bool = False) -> None:
        """Its base stands from now (``unless_carrying``: refused once its group has lifted)."""
        gs = self.goals
        gs.id += 1
        gs.goal = Stand(GlobalState.DECISION.value, unless_carrying=unless_carrying)
        gs.label = GlobalState.DECISION.value
        gs.at = max(gs.at, now)
        self._out.append(SendGoal(gs.id, gs.goal, now))

    def _sure_of_carry(self, fb: Feedback, now: float) -> bool:
        """Whether its status can say now if its carry is under way: its base's events are in up
        to the moment it first asked (else it waits for them: :meth:`base_known`); the lift among
        them, it keeps the carry; if not, it lets go — with a let-go its base refuses if its group
        has lifted meanwhile (the two cross the network) — and says so once its base answers."""
        rule, st, gs = self.rule, self.status, self.goals
        if not rule.unsure:
            return True
        if rule.status_wait is None:  # (the moment it first asked: its status is of then)
            rule.status_wait = fb.time
        if rule.base_known < rule.status_wait - EPS:
            return False
        task = self._task()
        if task is None or gs.lifted == task.object:  # (lifted: its result may be in)
            return self._sure()
        if st.letting_go is None:
            st.held = (gs.id, gs.goal, gs.label, gs.sweep)
            self._stand(now, unless_carrying=True)
            st.letting_go = gs.id
            return False
        if fb.goal != st.letting_go:
            return False  # (its base's answer is still to come)
        self.agent.give_back()  # its let-go took over: not lifted, and never will be
        st.keep = self.agent.taken  # (what it keeps: without it)
        return self._sure()

    def _sure(self) -> bool:
        self.rule.unsure, self.rule.status_wait = False, None
        self.status.letting_go, self.status.held = None, None
        return True

    def _lifted_first(self, res: GoalResult, now: float) -> bool:
        """Its let-go came after its group had lifted (refused, CARRYING): the hold goes on as
        the carry it is, and its status says so."""
        st, gs = self.status, self.goals
        if res.goal != st.letting_go or st.held is None:
            return False
        gs.id, gs.goal, gs.label, gs.sweep = st.held
        self._sure()
        self._decide_again(now)
        return True

    def _status(self, fb: Feedback, s: int) -> None:
        """Where and when it is free of what it keeps doing, and what of the schedule it keeps."""
        self.status.due = False
        a, comm = self.agent, self.comm
        free_at, where = s + 1, fb.cell
        if a.current is not None:
            o = comm.knowledge.objects[a.current.object]
            free_at, where = max(a.current.finish, s + 1), o.destination
        elif a.state is GlobalState.SEARCHING:
            sw = a.sweep_task or comm.sweeps_of(self.id)[0]
            free_at, where = max(sw.finish, s + 1), sw.path[-1]
        stamp = stamp_of(fb.time, self.speaker.committed)
        status = RtStatus(self.id, stamp, free_at, where, failure=comm.losses, keep=self.status.keep)
        self._send(status, fb.time)

    def _resync(self) -> None:
        """A recovery completed: its own kept entries are what it has done or is doing; the
        entries after them are new."""
        comm = self.comm
        kept = comm.kept_len if comm.kept_len is not None else len(comm.knowledge.schedule)
        self.agent.read_kept(kept)

    # ------------------------------------------------------------------ membership

    def _declared_out(self, now: float) -> None:
        """Its own notice: it is out (what it sent beyond the notice counts for nobody). It sends
        nothing more and leaves its base alone until a member's Back readmits it; it asks to come
        back (:class:`Hello`) from where its base stands."""
        self.life.out = True
        gs = self.goals
        gs.goal, gs.sweep, gs.lifted, gs.blocked = None, None, -1, -1
        self._decide_again(now)

    def _say_hello(self, fb: Feedback) -> None:
        life = self.life
        if life.hello > life.incarnation:
            return  # asked already
        life.hello = life.incarnation + 1
        life.asked_back = Hello(self.id, life.hello, self.speaker.seq, fb.cell)
        self._out.append(Publish(life.asked_back))

    def _sponsor(self, now: float) -> None:
        """Answer the Hellos of robots its comm has taken out (their notices taken): a stamped
        Back each (every member sends one; the first in batch order counts)."""
        if self.life.out:
            return
        comm = self.comm
        hellos = self.life.hellos
        for j, h in list(hellos.items()):
            life = comm.incarnation.get(j, 0)
            if h.incarnation <= life:
                del hellos[j]  # it is back already
            elif j in comm.lost and h.incarnation == life + 1 and self.batches.done >= comm.lost[j]:
                del hellos[j]
                back = Back(self.id, math.ceil(now - EPS), j, h.incarnation, h.seq, h.at)
                self._send(back, now)

    def _readmit(self, t: int, msgs: Sequence, now: float) -> None:
        """Batch t readmitted robots (their Back counted): they take part from t + 1 — this robot
        too, if it is one of them."""
        comm = self.comm
        for m in msgs:
            if isinstance(m, Back) and comm.rejoined.get(m.agent) == t and m.agent in self.batches.failed:
                for env in self.batches.readmit(m.agent, t, m.after):
                    self._marks(self.speaker.want(env.stamp), now)
                if m.agent == self.id:
                    self._come_back(t, now)

    def _come_back(self, t: int, now: float) -> None:
        """Back as its next life: nothing of its old tasks (they went to others), its search over,
        free now where its base stands; it commits t (it sent nothing while out)."""
        life = self.life
        life.out = False
        life.incarnation = self.comm.incarnation[self.id]
        life.rejoins += 1
        self.speaker.committed = max(self.speaker.committed, t)
        self.agent.come_back(self.comm.rejoin_len(self.id))  # (the batch may have planned for it)
        self.status.due, self.status.keep = False, 0
        self._sure()
        self.goals.goal, self.goals.sweep = None, None
        self.goals.revive = True  # its base was stopped: its next goal, even to stand, takes it back
        self._decide_again(now)

    # ------------------------------------------------------------------ the comm side

    def _send(self, message, time: float) -> None:
        if self.life.out:
            return  # it counts for nobody until it is back (its Hello said how many it sent)
        shared = _shared(message)
        env = self.speaker.send(message, time, shared, self.rule.base_limit())
        self.record.said(env)
        self.batches.accept(env, shared)
        self._out.append(Publish(env))
        if shared:
            self._wake(float(env.stamp))  # to commit its stamp: its batch waits for that

    def _marks(self, marks: list[Mark], now: float) -> None:
        for m in marks:
            self._out.append(Publish(m))
        nxt = self.speaker.next_wanted()
        if nxt is not None and nxt > self.speaker.committed and nxt > now:
            self._wake(float(nxt))  # (one due already waits for its base's events: held())

    def _commit(self, now: float) -> None:
        """Commit what its rule allows at ``now`` — once the decision asked for is taken, if one
        is still to come."""
        if self.rule.asked is not None:
            self.rule.defer(now)
            return
        self._marks(self.speaker.commit(self.rule.limit(now)), now)

    def _wake(self, t: float) -> None:
        if t not in self.decisions.wakes:
            self.decisions.wakes.add(t)
            self._out.append(WakeAt(t))

    def _next_batch(self) -> int | None:
        n = self.batches.next_stamp()
        done = self.batches.done
        if self._event[0] != done:  # the comm changes only when it takes a batch
            self._event = (done, self.comm.next_event(done + 1))
        e = self._event[1]
        cands = [x for x in (n, e) if x is not None]
        return min(cands) if cands else None

    def _pump(self, now: float) -> None:
        """Take every complete batch, in stamp order; ask for what the next one lacks."""
        while True:
            t = self._next_batch()
            if t is None:
                return
            if not self.batches.complete(t):
                if self.speaker.committed < t:
                    if t > now:  # its own clock first (a Need for later may be moot)
                        self._wake(float(t))
                    # else its base's events up to t are not all in: it commits once they are
                    # (its caller calls on_clock then: held())
                    return
                need = self.batches.ask(t)
                if need is not None:
                    self._out.append(Publish(need))
                return
            self._take(t, now)

    def _take(self, t: int, now: float) -> None:
        msgs = self.batches.take(t)
        self.record.took(t, now)
        self.agent.communicate(t, msgs)
        self._readmit(t, msgs, now)
        for m in self.comm.drain():
            self._send(m, now)
        self._digest(t, msgs, self.comm.knowledge.coordinations)
        comm = self.comm
        if comm.reset:
            comm.reset = False
            self._freeze(now)
        if comm.recovered:
            comm.recovered = False
            self._resync()
        if getattr(comm, "replanned", False):
            self.agent.read_replanned()
        if self.life.hellos:
            self._sponsor(now)
        a = self.agent
        if a.state in (GlobalState.RETURNING, GlobalState.FINISH) and a.current is None and a.has_unread():
            a.state = GlobalState.DECISION  # called back: a robot came back, and with it work
        self._decide_at(math.floor(now + EPS) + 1, now)

    def _digest(self, t: int, msgs: list, coordination: int) -> None:
        """A digest of batch t if it changed the shared view (observers compare them)."""
        view = self._schedule_view()
        if view is not None:
            self._view = view
            d = Digest(self.id, t, coordination, _digest(repr(msgs)), _digest(view))
            self.record.digest(d)
            self._out.append(d)

    def _ungate(self, now: float) -> None:
        """A carry waits for the batches up to its gate (:meth:`_frozen`): once they are known,
        decide again; until then ask for them."""
        if self.rule.gate is None:
            return
        u = self.rule.gate.batch
        if not self._known(u):
            nxt = self._next_batch()
            if nxt is not None and nxt <= u:
                return  # a batch before it is under way (the pump asks for it)
            if self.rule.asked is None:  # its own watermark first (nothing else may wake it to commit it)
                self._commit(now)
            if not self._known(u):
                if self.speaker.committed >= u:
                    self._need(u)
                return
        self.rule.gate = None
        self._decide_again(now)
        self._wake(now)  # to commit this step once that decision and its base's events are in

    def _schedule_view(self) -> str | None:
        """The shared view (schedule and pool) if it may have changed since the last one, else
        None: it changes only with a coordination, a find, an award or a failure."""
        k, comm = self.comm.knowledge, self.comm
        sign = (len(k.schedule), k.coordinations, len(k.unscheduled), comm.losses, comm.joins, comm.kept_len)
        if sign == self._sign:
            return None
        self._sign = sign
        view = repr((k.schedule, sorted(k.unscheduled)))
        return None if view == self._view else view

    def _flush(self, now: float) -> list[Output]:
        """What to do now: first every batch that became complete (its reactions included) —
        not while a decision asked for is still to come: the body acts before the comm moves on."""
        if self.rule.asked is None:
            self._pump(now)
            self._ungate(now)
        out, self._out = self._out, []
        return _fold_marks(out)


def _shared(message: object) -> bool:
    """Whether a protocol message joins a batch (False: a cross-check, taken in as it comes)."""
    return bool(getattr(message, "SHARED", True))


def _fold_marks(out: list[Output]) -> list[Output]:
    """A watermark rides on what is sent anyway: a Mark is left out when a message going out at
    the same moment carries it (an envelope says "nothing more stamped ≤ its watermark", with a
    count that includes every message before it)."""
    implied = max(
        (o.payload.implied for o in out if isinstance(o, Publish) and isinstance(o.payload, Envelope)),
        default=None,
    )
    if implied is None:
        return out
    return [
        o
        for o in out
        if not (isinstance(o, Publish) and isinstance(o.payload, Mark) and o.payload.watermark <= implied)
    ]


def _searching(state: str) -> bool:
    return state == SEARCHING_STATE


def _finish(state: str) -> bool:
    return state == FINISH_STATE
