"""One robot without a barrier, ROS-free: its body (search and motion, driving its base by goals)
and its comm module (fed batch by batch by the agreement layer).

:class:`RealtimeAgent` is a set of callbacks — ``start``, ``on_message``, ``on_result``,
``on_detection``, ``on_carry``, ``on_feedback``, ``on_clock`` — each given the current time and
returning what to do as a list of outputs: :class:`Publish` (to every peer), :class:`SendGoal`
(to its own base), :class:`AskFeedback` (where will the base be at a time), :class:`WakeAt` (call
``on_clock`` then), :class:`~ost_ros.realtime.messages.Digest` (for observers). It knows nothing
of who calls it: the in-process run (:mod:`ost_ros.realtime.run`) and the agent node wire the
same object.

The body reuses the protocol's own agent (:class:`RtScheduleAgent`, a
:class:`~ost_ros.protocols.shared.agent.ScheduleAgent` that never writes into the comm's
knowledge) the way the event engine does: at each decision (a goal reached, news in its sensor,
the comm changed something, a step after it acted) it asks for its own plan; a settled first
segment becomes a goal (sweep/walk: FOLLOW that path; hold/carry: CARRY with the assignment's
group; wait: STAND), otherwise it acts for one step. So at latency 0 the run is the step engine's.

The comm module sees only complete batches, in stamp order: the schedule it computes is a
function of the stamped messages. Everything the body reports — finds, search done, its status
after a failure — goes out as a stamped message and enters the comm (its own included) only
through a batch.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from ost_ros.coordination import Assignment
from ost_ros.model import Cell, can_move
from ost_ros.motion import apply
from ost_ros.protocols.plans import Plan, Segment
from ost_ros.protocols.shared.agent import GlobalState, ScheduleAgent, _Planner
from ost_ros.protocols.shared.recovery import Sweep
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
    ObjectFound,
    ObjectInfo,
    Observation,
    RtStatus,
    SearchDone,
)
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
from ost_ros.search import SearchState, route

EPS = 1e-9


# ----------------------------------------------------------------------------- outputs


@dataclass(frozen=True)
class Publish:
    """Broadcast to every peer (an Envelope, a Mark or a Need)."""

    payload: Envelope | Mark | Need | Hello


@dataclass(frozen=True)
class SendGoal:
    """A goal for the agent's own base (client id ``id``), taking over at its first boundary at or
    after ``at``."""

    id: int
    goal: Goal
    at: float


@dataclass(frozen=True)
class AskFeedback:
    """Where will the base be at its first boundary at or after ``at`` (answer: ``on_feedback``)."""

    at: float


# A robot whose base is across a network decides as of the time its decision was due if that is
# less than this much ago (steps): its goal then has the rest of the step to reach the base, which
# takes it over at that time (RealtimeWorld.takeover) — as a base on board would.
DECIDE_WINDOW = 0.5


def decision_time(at: float, now: float) -> float:
    """The moment a decision asked for ``at`` is taken as of, answered at ``now`` (a robot whose
    base is across a network: its picture of the base answers): ``at`` if due less than
    DECIDE_WINDOW ago, else now."""
    return at if now - DECIDE_WINDOW < at else max(at, now)


@dataclass(frozen=True)
class WakeAt:
    time: float


Output = Publish | SendGoal | AskFeedback | WakeAt | Digest


# ----------------------------------------------------------------------------- the body


class RtScheduleAgent(ScheduleAgent):
    """The schedule agent's body without a barrier: its finds go out as messages and enter the
    shared knowledge only through its comm's batches (``reported`` remembers what it said)."""

    def __init__(self, *args, **kw) -> None:
        super().__init__(*args, **kw)
        self.reported: set[int] = set()
        self.sweep_task: Sweep | None = None  # the take-over sweep it is on (None: its own)
        # The object its base last lifted, as its runtime knows (its base across a network: a
        # hold may come too late, and where its base went says nothing of a carry); None: unused
        self.lifted: int | None = None

    def act(self, obs: Observation) -> Action:
        self.t, self.position = obs.t, obs.position
        self._search(obs)
        self._walk_back()
        kind, direction, obj = self._motion(obs)
        return Action(self.id, self.t, kind, direction, obj, self.state.value)

    def _walk_back(self) -> None:
        """Holding or carrying by its picture, but its base moved on without the load (a hold
        that came after its base had left the object's cell): nothing is carried — back to it
        (the lockstep agent would take "it has moved" for a carry under way)."""
        cur = self.current
        if (
            self.lifted is not None
            and cur is not None
            and self.state in (GlobalState.WAITING, GlobalState.MOVING)
            and self.lifted != cur.object
            and self.position != self.knowledge.objects[cur.object].location
        ):
            self.state = GlobalState.HELPING

    def _search(self, obs: Observation) -> None:
        if self.state is not GlobalState.SEARCHING:
            return
        for o in obs.sensed:
            if self.news(o):
                self.reported.add(o.id)
                self._outbox.append(ObjectFound(self.id, obs.t, o))
        if self.search.at_end(self.position):
            self.search.state = SearchState.DONE
            self.state = GlobalState.DECISION
            self._outbox.append(self._search_done(obs.t))

    def report_late(self, t: int, sensed: Sequence[ObjectInfo]) -> list:
        """Finds its base sensed at step ``t`` that it hears of only now (a network between the
        robot and its base): reported as sensed then, without acting (it has moved on)."""
        out = []
        for o in sensed:
            if self.news(o):
                self.reported.add(o.id)
                out.append(ObjectFound(self.id, t, o))
        return out

    def _search_done(self, t: int) -> SearchDone:
        return SearchDone(self.id, t)

    def _decide(self, obs: Observation) -> bool:
        self._read_schedule()
        if self.tasks and isinstance(self.tasks[0], Sweep):
            self.sweep_task = self.tasks[0]
        return super()._decide(obs)

    def news(self, obj: ObjectInfo) -> bool:
        return obj.id not in self.knowledge.objects and obj.id not in self.reported

    def plan(self, t: int, position: Cell) -> Plan:
        return _Planner(self, t, position, None).run()

    def communicate(self, t: int, messages: Sequence) -> None:
        self.comm.receive(t, messages)  # the runtime reacts to failures and recoveries

    def body_messages(self) -> list:
        out, self._outbox = self._outbox, []
        return out


# ----------------------------------------------------------------------------- the runtime


def _digest(text: str) -> str:
    return hashlib.blake2b(text.encode(), digest_size=8).hexdigest()


@dataclass
class RealtimeAgent:
    """One robot's runtime without a barrier (see the module docstring)."""

    agent: RtScheduleAgent
    team: tuple[int, ...]
    remote_base: bool = False  # its base's events cross a network (an agent node), not in process
    monitor: bool = False  # a membership monitor takes part (ost_ros.realtime.membership)
    speaker: Speaker = field(init=False)
    batches: Batches = field(init=False)
    max_lag: float = 0.0  # the most a batch was processed after its stamp (steps)
    sent: list[tuple[int, int]] = field(default_factory=list)  # (stamp, seq) of what it sent
    digests: dict[int, Digest] = field(default_factory=dict)  # stamp -> digest (coordinations)
    processed: set[int] = field(default_factory=set)  # stamps of every batch taken
    taken_at: dict[int, float] = field(default_factory=dict)  # stamp -> when it was taken
    goal: Goal | None = None  # the goal running on its base
    goal_id: int = 0
    label: str = SEARCHING_STATE  # the state label its base last got
    _sweep: tuple[Sequence[Cell], int] | None = None  # running goal = that sweep from that index
    _asked: bool = False
    _asked_at: float = -1.0  # when it asked (sim time)
    _decided: float = -1.0  # time of the last decision
    _acted: int = -1  # step of the last act
    _wakes: set[float] = field(default_factory=set)
    _dues: set[float] = field(default_factory=set)  # times a decision is due at
    _goal_at: float = -1.0  # the time the last goal it sent takes over at (at the earliest)
    _carry_started: int = -1  # object whose carry the base has begun
    _blocked: int = -1  # object whose group lost a member: no CARRY for it until the comm knows
    _keep: int = 0  # own schedule entries done or under way when a failure was learnt
    _status_due: bool = False  # a failure was learnt: its status goes out at the next decision
    # A carry sent whose lift its base may not have told of yet (its base across a network): the
    # status waits for its base's events up to its time (``_status_wait``), then says
    _unsure_carry: bool = False
    _status_wait: float | None = None
    _letting_go: int = -1  # its let-go of such a hold, sent and not answered yet (its goal id)
    _held: tuple[int, Goal | None, str, tuple[Sequence[Cell], int] | None] | None = (
        None  # (the hold's goal id, goal, label, sweep)
    )
    _commit_at: float | None = None  # a time to commit once the decision asked for is taken
    # CCP's improved planner: the batch a carry waits to be known (_frozen), open_entries cached
    _gate: int | None = None
    _gated_at: int = -1  # the step of the decision the gate holds (it commits below it meanwhile)
    _asked_for: Assignment | None = None  # the task it asked ahead for (_ask_ahead)
    _open: tuple[tuple[int, ...], dict[int, frozenset[int]]] = field(default_factory=lambda: ((), {}))
    _event: int | None = None  # the comm's next event after the last batch (cached)
    _event_for: int = -2
    # Membership: declared out (a notice of it taken), its life now, the Hello it sent (the
    # incarnation it asked for), peers' Hellos it is to answer, how often it came back
    out: bool = False
    incarnation: int = 0
    _hello: int = 0
    _asked_back: Hello | None = None  # its last Hello (said again to peers back from a partition)
    _hellos: dict[int, Hello] = field(default_factory=dict)
    _revive: bool = False
    rejoins: int = 0
    _sign: tuple = ()
    _view: str = ""
    _out: list[Output] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.speaker = Speaker(self.agent.id)
        self.batches = Batches(self.agent.id, self.team, self.speaker, monitor=self.monitor)
        self._view = self._schedule_view() or ""

    @property
    def id(self) -> int:
        return self.agent.id

    @property
    def comm(self):
        return self.agent.comm

    def destination(self, obj: int) -> Cell:
        """Where a known object goes (its base's picture of a carry needs it)."""
        return self.comm.knowledge.objects[obj].destination

    def base_known(self, t: float) -> None:
        """Every event of its base up to time ``t`` has been handled (an agent node: its base's
        clock says how many it has sent up to t, and all are in): it may commit up to t, and
        never further (in process the base is its own hardware: no limit)."""
        self.speaker.ceiling = t
        if self._status_wait is not None and t >= self._status_wait - EPS:
            self._decided = -1.0
            self._dues.add(t)  # its status can say now (its caller's clock comes)

    def held(self, now: float) -> bool:
        """Whether its commitment is held back by its base's events (not all in up to ``now``)
        while someone waits for it, or a batch due waits for it: its caller calls
        :meth:`on_clock` again once more of them are in."""
        if self._status_wait is not None and self._unsure_carry:
            return True
        if self.speaker.ceiling >= math.floor(now + EPS):
            return False
        nxt = self.speaker.next_wanted()
        if nxt is not None and self.speaker.committed < nxt <= now + EPS:
            return True
        t = self._next_batch()
        return t is not None and self.speaker.committed < t <= now + EPS

    def asking(self) -> float | None:
        """The time of the decision waiting for where its base is, if one is."""
        return self._asked_at if self._asked else None

    def waiting(self, now: float) -> tuple[int, str] | None:
        """The oldest batch due and still incomplete, if any: (its stamp, what it lacks)."""
        t = self._next_batch()
        if t is None or t > now or self.batches.complete(t):
            return None
        if self.speaker.committed < t:
            if self.speaker.ceiling < t:
                known = self.speaker.ceiling
                return t, f"batch {t} waits for its own commit: its base's events are in up to {known:g}"
            return t, f"batch {t} waits for its own commit"
        return t, f"batch {t} waits for the messages or watermarks of agents {self.batches.lacking(t)}"

    # ------------------------------------------------------------------ callbacks

    def start(self, now: float) -> list[Output]:
        self._decide_at(now, now)
        return self._flush(now)

    def on_clock(self, now: float) -> list[Output]:
        """A timer fired (``WakeAt``): decisions due, then commit the time passed."""
        self._wakes = {w for w in self._wakes if w > now + EPS}
        due = self._due(now)
        if due:
            self._dues.difference_update(due)
            self._decide_at(min(due), now)
        self._commit(now)
        return self._flush(now)

    def on_message(self, payload: Envelope | Mark | Need | Lost | Hello, now: float) -> list[Output]:
        """A peer's message (or the world's failure notice), as it arrives."""
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
            if payload.agent == self.id and payload.incarnation == self.incarnation and not self.out:
                self._declared_out(now)
        elif isinstance(payload, Hello) and payload.incarnation > self.comm.incarnation.get(
            payload.sender, 0
        ):
            self._hellos[payload.sender] = payload
            self._sponsor(now)
        return self._flush(now)

    def again(self, now: float) -> list[Output]:
        """Peers cut off are back, and what crossed meanwhile is lost (a partition longer than
        DDS keeps a peer): its watermark again, and the batch it waits for asked for again (its
        Needs may be lost too). Its messages again are its node's to send: it keeps them as
        sealed (``RealtimeAgentNode.readers_back``; in process, ``_Run.heal``)."""
        self._commit(now)
        self.batches.ask_again()
        if self.speaker.committed >= 0:
            self._out.append(Publish(Mark(self.id, self.speaker.committed, self.speaker.seq)))
        if self.out and self._asked_back is not None and self._asked_back.incarnation > self.incarnation:
            self._out.append(Publish(self._asked_back))  # out, it still asks to come back
        return self._flush(now)

    def on_result(self, res: GoalResult, now: float) -> list[Output]:
        if res.code == "CARRYING" and self._lifted_first(res, now):
            return self._flush(now)
        if res.goal != self.goal_id or self.out:
            return self._flush(now)  # an older goal's (preempted) result
        if self.remote_base and res.time <= self._decided + EPS:
            # a decision at or after its time was taken without it (its base's events cross a
            # network, and one that came first made its picture look whole): that one again
            self._decided = -1.0
        if res.outcome == REACHED:
            if self._sweep is not None and isinstance(self.goal, Follow):
                self.agent.search.index = self._sweep[1] + len(self.goal.path) - 1
            self.goal, self._sweep = None, None
            self._decide_at(res.time, now)
        elif res.outcome in (ABORTED, REFUSED):
            self.goal, self._sweep, self._carry_started = None, None, -1
            task = self._task()
            if res.code == "MEMBER_FAILED":
                if task is None:
                    pass  # it let go of it already (its comm heard of the failure first)
                elif self._member_lost(task):
                    # its comm has heard of the failure already (the notice may be stamped well
                    # before the abort reached it): decide on what the comm now says
                    self._decided = -1.0
                    self._decide_at(now, now)
                else:
                    self._blocked = task.object  # until the comm hears of the failure
            elif res.code in ("START", "PREEMPTED", "DELIVERED") or (
                res.code == "NOT_AT_OBJECT" and self.remote_base
            ):
                # planned from a stale feedback (over DDS an answer from mid-carry can come after
                # the carry's result: the object is delivered; a hold comes after its base moved
                # on past the object), or another client took its base over (an operator's
                # goal): look again, decide again
                self._decided = -1.0
                self._decide_at(now, now)
            elif res.code == "FAILED":
                pass  # its base was stopped: it was declared out (its notice is on the way)
            elif res.outcome == REFUSED:
                self.agent.warnings.append(f"goal refused at {res.time}: {res.reason}")
        return self._flush(now)

    def on_detection(self, det: Detection, now: float) -> list[Output]:
        a = self.agent
        if self.out:
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
            self._carry_started = ev.object
        return self._flush(now)

    def on_feedback(self, fb: Feedback, now: float) -> list[Output]:
        self._asked = False
        if fb.time > now + EPS:  # mid-move: decide when the move ends
            self._decide_at(fb.time, now)
        else:
            self._decide(fb, now)
        if self._commit_at is not None and not self._asked:
            t, self._commit_at = self._commit_at, None
            self._commit(t)
        return self._flush(now)

    # ------------------------------------------------------------------ decisions

    def _decide_at(self, t: float, now: float) -> None:
        """A decision is due at time t (asked for now if t has come)."""
        if t > now + EPS:
            self._dues.add(t)
            self._wake(t)
            return
        if not self._asked:
            self._asked, self._asked_at = True, now
            # (its base across a network: as of when it was due — decision_time — unless that
            # goes back before its last decision or the goal it sent last)
            back = t < max(self._goal_at, self._decided) - EPS
            self._out.append(AskFeedback(t if self.remote_base and not back else now))

    def _decide(self, fb: Feedback, now: float) -> None:
        if abs(fb.time - self._decided) < EPS:
            return  # one decision per moment
        self._decided = fb.time
        if self.out:
            self._say_hello(fb)
            return
        a = self.agent
        s = math.ceil(fb.time - EPS)
        self._sync(fb, s)
        if self._status_due and self._sure_of_carry(fb, now):
            self._status(fb, s)
        plan = a.plan(s, fb.cell)
        searching = a.state.value == SEARCHING_STATE
        if plan.settled and not (searching and any(a.news(o) for o in fb.sensed)):
            self._follow_plan(plan[0], fb)
            return
        s = max(s, self._acted + 1)
        self._acted = s
        action = a.act(Observation(self.id, s, fb.cell, fb.sensed))
        for m in a.body_messages():
            self._send(m, fb.time)
        self._follow_action(action, fb)
        self._decide_at(s + 1, now)
        self._ask_ahead()

    def _sync(self, fb: Feedback, s: int) -> None:
        a = self.agent
        a.t, a.position = s, fb.cell
        if self.remote_base:
            a.lifted = fb.carrying if fb.carrying >= 0 else self._carry_started
        if self._sweep is not None and fb.goal == self.goal_id and fb.index >= 0:
            path, base = self._sweep
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
            g = self.goal
            if (
                isinstance(g, Follow)
                and fb.goal == self.goal_id
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
            g = self.goal
            if isinstance(g, Follow) and can_move(action.t, a.period):
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
        if task.object == self._blocked or self._member_lost(task):
            # its group has lost a member: wait for the comm (to hear of it, or to re-plan)
            self._goal(Stand(state), fb)
            return
        if not self._frozen(task):
            self._goal(Stand(state), fb)  # a re-plan may still move it: wait for the comm
            return
        g = self.goal
        if (
            self.remote_base
            and isinstance(g, Follow)
            and fb.goal == self.goal_id
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
        a plan keeps it for. A robot may walk to an object before that (nobody sees
        a walk), never hold or carry it: a lagging robot never holds for a group that a re-plan
        it has not read yet dissolved. Until then it asks for those batches (a :class:`Need`)
        and decides again once they are in (:meth:`_flush`)."""
        self._gate = None
        u = self._settles(task)
        if u is None or u <= self.batches.done or self._known(u):
            return u is not None
        # (its commit stays below this step meanwhile — unless the gate needs this step itself)
        self._gate, self._gated_at = u, (self.agent.t if u < self.agent.t - 1 else -1)
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
        if self._letting_go >= 0:
            return  # its let-go is not answered yet: nothing else goes to its base meanwhile
        if self.out:
            return  # its base was stopped when it was declared: nothing until it is back
        g = self.goal
        running = g is not None and fb.goal == self.goal_id
        if not force and running:
            if isinstance(goal, Follow) and isinstance(g, Follow) and fb.index >= 0:
                if g.path[fb.index :] == goal.path and _searching(g.state) == _searching(goal.state):
                    return
            elif isinstance(goal, Carry) and isinstance(g, Carry):
                if (g.object, g.group) == (goal.object, goal.group):
                    return
            elif isinstance(goal, Stand) and isinstance(g, Stand) and g.state == goal.state:
                return
        same = isinstance(goal, Stand) and not running and _finish(goal.state) == _finish(self.label)
        if same and not self._revive:
            return  # it stands already, and nothing about it changes
        self._revive = False
        self.goal_id += 1
        self.goal = goal
        self._sweep = sweep
        self.label = goal.state
        self._carry_started = -1  # a new goal: no lift of it yet (on_carry says when)
        self._goal_at = fb.time
        self._out.append(SendGoal(self.goal_id, goal, fb.time))

    # ------------------------------------------------------------------ failures

    def _freeze(self, now: float) -> None:
        """The comm has learnt of a failure: stop what is not under way (a carry the group has
        begun, a sweep go on), read no more of the schedule until the recovery, and say so (the
        status, at the next decision)."""
        a = self.agent
        k = self.comm.knowledge
        a.tasks.clear()
        a._seen_schedule = len(k.schedule)
        # (a carry whose group has lost a member is over, even if its base has not said so yet:
        # the notice may be stamped well before the abort reaches it)
        carry = isinstance(self.goal, Carry) and not (a.current is not None and self._member_lost(a.current))
        going = carry and self._carry_started == self.goal.object  # type: ignore[union-attr]
        # (its base across a network may have lifted and not said so yet: it says once it has)
        self._unsure_carry = carry and not going and self.remote_base and a.current is not None
        if a.current is not None and not going and not self._unsure_carry:
            self._let_go(now)
        elif a.current is None and a.state in (GlobalState.RETURNING, GlobalState.FINISH):
            a.state = GlobalState.DECISION
        self._blocked = -1
        self._keep = a._taken
        self._status_due = True
        self._decide_at(math.floor(now + EPS) + 1, now)

    def _let_go(self, now: float) -> None:
        """What it has taken up and not begun goes back into the pool; a hold is let go now (no
        lift without it)."""
        self._give_back()
        if isinstance(self.goal, Carry) and not self.out:
            self._stand(now)

    def _give_back(self) -> None:
        """The task it has taken up goes back into the pool: it decides again."""
        a = self.agent
        a.current = None
        a._taken -= 1
        if a.state is not GlobalState.SEARCHING:
            a.state = GlobalState.DECISION

    def _stand(self, now: float, unless_carrying: bool = False) -> None:
        """Its base stands from now (``unless_carrying``: refused once its group has lifted)."""
        self.goal_id += 1
        self.goal = Stand(GlobalState.DECISION.value, unless_carrying=unless_carrying)
        self.label = GlobalState.DECISION.value
        self._goal_at = max(self._goal_at, now)
        self._out.append(SendGoal(self.goal_id, self.goal, now))

    def _sure_of_carry(self, fb: Feedback, now: float) -> bool:
        """Whether its status can say now if its carry is under way: its base's events are in up
        to the moment it first asked (else it waits for them: :meth:`base_known`); the lift among
        them, it keeps the carry; if not, it lets go — with a let-go its base refuses if its group
        has lifted meanwhile (the two cross the network) — and says so once its base answers."""
        if not self._unsure_carry:
            return True
        if self._status_wait is None:  # (the moment it first asked: its status is of then)
            self._status_wait = fb.time
        if self.speaker.ceiling < self._status_wait - EPS:
            return False
        task = self._task()
        if task is None or self._carry_started == task.object:  # (lifted: its result may be in)
            return self._sure()
        if self._letting_go < 0:
            self._held = (self.goal_id, self.goal, self.label, self._sweep)
            self._stand(now, unless_carrying=True)
            self._letting_go = self.goal_id
            return False
        if fb.goal != self._letting_go:
            return False  # (its base's answer is still to come)
        self._give_back()  # its let-go took over: not lifted, and never will be
        self._keep = self.agent._taken  # (what it keeps: without it)
        return self._sure()

    def _sure(self) -> bool:
        self._unsure_carry, self._status_wait, self._letting_go, self._held = False, None, -1, None
        return True

    def _lifted_first(self, res: GoalResult, now: float) -> bool:
        """Its let-go came after its group had lifted (refused, CARRYING): the hold goes on as
        the carry it is, and its status says so."""
        if res.goal != self._letting_go or self._held is None:
            return False
        self.goal_id, self.goal, self.label, self._sweep = self._held
        self._sure()
        self._decided = -1.0
        self._decide_at(now, now)
        return True

    def _status(self, fb: Feedback, s: int) -> None:
        """Where and when it is free of what it keeps doing, and what of the schedule it keeps."""
        self._status_due = False
        a, comm = self.agent, self.comm
        free_at, where = s + 1, fb.cell
        if a.current is not None:
            o = comm.knowledge.objects[a.current.object]
            free_at, where = max(a.current.finish, s + 1), o.destination
        elif a.state is GlobalState.SEARCHING:
            sw = a.sweep_task or comm._sweeps_of(self.id)[0]
            free_at, where = max(sw.finish, s + 1), sw.path[-1]
        stamp = stamp_of(fb.time, self.speaker.committed)
        self._send(RtStatus(self.id, stamp, free_at, where, failure=comm.losses, keep=self._keep), fb.time)

    def _resync(self) -> None:
        """A recovery completed: its own kept entries are what it has done or is doing; the
        entries after them are new."""
        a, comm = self.agent, self.comm
        sched = comm.knowledge.schedule
        kept = comm.kept_len if comm.kept_len is not None else len(sched)
        a.tasks.clear()
        a._seen_schedule = kept
        a._taken = sum(1 for e in sched[:kept] if self.id in e.agents)
        if a.current is not None and a.current not in sched[:kept]:
            a.current = None
            if a.state is not GlobalState.SEARCHING:
                a.state = GlobalState.DECISION

    def _replanned(self) -> None:
        """CCP's improved planner moved entries nobody can have taken up: what it carried is
        kept (:meth:`_frozen`), so its task list is its part of the schedule after what it has
        taken up — unless the task it was walking to went to the new plan: it lets it go."""
        a, comm = self.agent, self.comm
        sched = comm.knowledge.schedule
        if a.current is not None and not any(e is a.current for e in sched):
            a.current = None
            a._taken -= 1
            if a.state is not GlobalState.SEARCHING:
                a.state = GlobalState.DECISION
        a._resync()  # (the lockstep agent's: its part of the schedule after what it took up)

    # ------------------------------------------------------------------ membership

    def _declared_out(self, now: float) -> None:
        """Its own notice: it is out (what it sent beyond the notice counts for nobody). It sends
        nothing more and leaves its base alone until a member's Back readmits it; it asks to come
        back (:class:`Hello`) from where its base stands."""
        self.out = True
        self.goal, self._sweep, self._carry_started, self._blocked = None, None, -1, -1
        self._decided = -1.0
        self._decide_at(now, now)

    def _say_hello(self, fb: Feedback) -> None:
        if self._hello > self.incarnation:
            return  # asked already
        self._hello = self.incarnation + 1
        self._asked_back = Hello(self.id, self._hello, self.speaker.seq, fb.cell)
        self._out.append(Publish(self._asked_back))

    def _sponsor(self, now: float) -> None:
        """Answer the Hellos of robots its comm has taken out (their notices taken): a stamped
        Back each (every member sends one; the first in batch order counts)."""
        if self.out:
            return
        comm = self.comm
        for j, h in list(self._hellos.items()):
            life = comm.incarnation.get(j, 0)
            if h.incarnation <= life:
                del self._hellos[j]  # it is back already
            elif j in comm.lost and h.incarnation == life + 1 and self.batches.done >= comm.lost[j]:
                del self._hellos[j]
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
        self.out = False
        self.incarnation = self.comm.incarnation[self.id]
        self.rejoins += 1
        self.speaker.committed = max(self.speaker.committed, t)
        a, k = self.agent, self.comm.knowledge
        a.tasks.clear()
        a.current, a.sweep_task = None, None
        # what is left of its old life in the schedule is done or under way by others: counted as
        # taken (its status's ``keep`` counts its entries from the first)
        a._seen_schedule = self.comm.rejoin_len(self.id)  # (the batch may have planned for it)
        a._taken = sum(1 for e in k.schedule[: a._seen_schedule] if self.id in e.agents)
        a.search.state = SearchState.DONE
        a.state = GlobalState.DECISION
        a.reported &= set(k.objects)  # what it said while out counted for nobody: news again
        self._status_due, self._keep = False, 0
        self._sure()
        self.goal, self._sweep = None, None
        self._revive = True  # its base was stopped: its next goal, even to stand, takes it back
        self._decided = -1.0
        self._decide_at(now, now)

    # ------------------------------------------------------------------ the comm side

    def _send(self, message, time: float) -> None:
        if self.out:
            return  # it counts for nobody until it is back (its Hello said how many it sent)
        shared = _shared(message)
        env = self.speaker.send(message, time, shared)
        self.sent.append((env.stamp, env.seq))
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
        """Every event of time ≤ now is handled — unless a decision asked for is still to come
        (then once it is taken), and no later than its base's events are in (:meth:`base_known`)."""
        if self._asked:
            self._commit_at = now if self._commit_at is None else max(self._commit_at, now)
            return
        c = self._capped(math.floor(now + EPS))
        if self.remote_base:  # (a decision due is taken as of its time: not committed past)
            due = self._due(now)
            if due:
                c = min(c, math.ceil(min(due) - EPS) - 1)
        self._marks(self.speaker.commit(c), now)

    def _due(self, now: float) -> list[float]:
        """The decisions due by now and not taken yet (their times)."""
        return [d for d in self._dues if d <= now + EPS]

    def _capped(self, t: int) -> int:
        """A carry gated in step s (:meth:`_frozen`) is decided again in s once the gate opens:
        the decision of s may still change, so it commits below s meanwhile (as in lockstep, its
        step s comes before anything stamped s); past step s, the decision of s stands."""
        if self._gate is not None and t <= self._gated_at:
            return self._gated_at - 1
        return t

    def _wake(self, t: float) -> None:
        if t not in self._wakes:
            self._wakes.add(t)
            self._out.append(WakeAt(t))

    def _next_batch(self) -> int | None:
        n = self.batches.next_stamp()
        if self._event_for != self.batches.done:  # the comm changes only when it takes a batch
            self._event_for = self.batches.done
            self._event = self.comm.next_event(self.batches.done + 1)
        e = self._event
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
        self.processed.add(t)
        self.taken_at[t] = now
        self.max_lag = max(self.max_lag, now - t)
        self.agent.communicate(t, msgs)
        self._readmit(t, msgs, now)
        for m in self.comm.drain():
            self._send(m, now)
        view = self._schedule_view()
        if view is not None:
            self._view = view
            self.digests[t] = Digest(
                self.id, t, self.comm.knowledge.coordinations, _digest(repr(msgs)), _digest(view)
            )
            self._out.append(self.digests[t])
        comm = self.comm
        if comm.reset:
            comm.reset = False
            self._freeze(now)
        if comm.recovered:
            comm.recovered = False
            self._resync()
        if getattr(comm, "replanned", False):
            self._replanned()
        if self._hellos:
            self._sponsor(now)
        a = self.agent
        if a.state in (GlobalState.RETURNING, GlobalState.FINISH) and a.current is None and a._unread():
            a.state = GlobalState.DECISION  # called back: a robot came back, and with it work
        self._decide_at(math.floor(now + EPS) + 1, now)

    def _ungate(self, now: float) -> None:
        """A carry waits for the batches up to its gate (:meth:`_frozen`): once they are known,
        decide again; until then ask for them."""
        u = self._gate
        if u is None:
            return
        if not self._known(u):
            nxt = self._next_batch()
            if nxt is not None and nxt <= u:
                return  # a batch before it is under way (the pump asks for it)
            if not self._asked:  # its own watermark first (nothing else may wake it to commit it)
                self._commit(now)
            if not self._known(u):
                if self.speaker.committed >= u:
                    self._need(u)
                return
        self._gate = None
        self._decided = -1.0
        self._decide_at(now, now)
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
        if not self._asked:
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
