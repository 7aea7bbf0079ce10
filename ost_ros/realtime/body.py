"""A robot's body without a barrier: the protocol's own schedule agent (search and motion, its
part of the shared schedule), whose finds go out as messages and enter the shared knowledge only
through its comm's batches.

Its runtime (:class:`~ost_ros.realtime.agent.RealtimeAgent`) drives it by asking for its plan at
each decision and acting for one step where no plan is settled; what the runtime needs of it
beyond that — give a task back, stop reading the schedule after a failure, read it again after a
recovery or a re-plan, come back as its next life — is the public interface at the end of the
class: nothing outside reads or writes its private state.
"""

from __future__ import annotations

from collections.abc import Sequence

from ost_ros.model import Cell
from ost_ros.protocols.plans import Plan
from ost_ros.protocols.shared.agent import GlobalState, ScheduleAgent, _Planner
from ost_ros.protocols.shared.recovery import Sweep
from ost_ros.realtime.messages import Action, ObjectFound, ObjectInfo, Observation, SearchDone
from ost_ros.search import SearchState


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

    # ------------------------------------------------------------------ what its runtime asks

    @property
    def taken(self) -> int:
        """Own entries of the schedule taken up so far (done or under way)."""
        return self._taken

    def has_unread(self) -> bool:
        """Whether the schedule holds own entries it has not read yet."""
        return bool(self._unread())

    def stop_reading(self) -> None:
        """A failure is learnt: its task list is dropped and it reads nothing of what the
        schedule holds now (the recovery decides what it keeps)."""
        self.tasks.clear()
        self._seen_schedule = len(self.knowledge.schedule)

    def give_back(self) -> None:
        """The task it has taken up goes back into the pool: it decides again."""
        self.current = None
        self._taken -= 1
        if self.state is not GlobalState.SEARCHING:
            self.state = GlobalState.DECISION

    def read_kept(self, kept: int) -> None:
        """A recovery completed, keeping the first ``kept`` entries of the schedule: its own
        among them are what it has done or is doing, the entries after them are new."""
        sched = self.knowledge.schedule
        self.tasks.clear()
        self._seen_schedule = kept
        self._taken = sum(1 for e in sched[:kept] if self.id in e.agents)
        if self.current is not None and self.current not in sched[:kept]:
            self.current = None
            if self.state is not GlobalState.SEARCHING:
                self.state = GlobalState.DECISION

    def read_replanned(self) -> None:
        """CCP's improved planner moved entries nobody can have taken up: its task list is its
        part of the schedule after what it has taken up — unless the task it was walking to went
        to the new plan: it gives it back."""
        if self.current is not None and not any(e is self.current for e in self.knowledge.schedule):
            self.give_back()
        self._resync()

    def come_back(self, seen: int) -> None:
        """Back as its next life: nothing of its old tasks (they went to others), its search over,
        free where its base stands. The first ``seen`` entries of the schedule were planned
        before it came back: what is left of its old life there is done or under way by others,
        counted as taken. What it said while out counted for nobody: news again."""
        k = self.knowledge
        self.tasks.clear()
        self.current, self.sweep_task = None, None
        self._seen_schedule = seen
        self._taken = sum(1 for e in k.schedule[:seen] if self.id in e.agents)
        self.search.state = SearchState.DONE
        self.state = GlobalState.DECISION
        self.reported &= set(k.objects)
