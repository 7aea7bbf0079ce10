"""Shared knowledge of a schedule-executing agent (CCP, NCP): every found object, the global
schedule, and when and where each agent becomes free (CA_j, loc_j of paper §3.3).

Every agent stores every broadcast find, so every agent holds the same copy; whatever extends
the schedule (Algorithm Coordination, a negotiation, a coordinator's update) does so through
:meth:`Knowledge.assign`, which moves each member's free time and place to the object's delivery.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ost_ros.coordination import Assignment, CoordinationPolicy
from ost_ros.messages import AgentMessage
from ost_ros.model import Cell, ObjectSpec, arrival_np
from ost_ros.protocols.shared.recovery import Sweep
from ost_ros.team import TeamInfo

# A global schedule entry: an object and its group, or (after a failure) a taken-over sweep.
Entry = Assignment | Sweep


@dataclass
class Knowledge:
    """One agent's copy of what the whole team knows."""

    me: int
    team: TeamInfo
    objects: dict[int, ObjectSpec] = field(default_factory=dict)
    found_at: dict[int, int] = field(default_factory=dict)
    unscheduled: set[int] = field(default_factory=set)
    schedule: list[Entry] = field(default_factory=list)
    searched: set[int] = field(default_factory=set)  # agents whose search work is done
    coordinations: int = 0
    predicted_makespan: int | None = None
    warnings: list[str] = field(default_factory=list)
    drops: dict[int, Cell] = field(default_factory=dict)  # objects left where a failed group held them

    def __post_init__(self) -> None:
        n = self.team.size
        self.lengths = self.team.sweep_lengths()  # when each agent's search work ends
        self.free_at = np.zeros(n, dtype=np.int64)  # finish of each agent's last scheduled object
        self.free_loc = self.team.sweep_ends()  # where it then stands (sweep end if none)
        # What the schedule extends: each agent's free time and place before the entries from
        # ``base_len`` on (the start; after a failure, the survivors' statuses).
        self.base_len = 0
        self.base_at, self.base_loc = self.free_at.copy(), self.free_loc.copy()

    def note_found(self, obj: ObjectSpec, t: int) -> bool:
        """Store an object (sensed or heard of); True if it was new."""
        known = self.objects.get(obj.id)
        if known is None:
            self.objects[obj.id] = obj
            self.found_at[obj.id] = t
            self.unscheduled.add(obj.id)
            return True
        if known != obj and not (obj.id in self.drops and replace(known, location=obj.location) == obj):
            self.warnings.append(f"object {obj.id} reported as {obj} but known as {known}; kept")
        return False

    def costs(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """CA_j and loc_j for a coordination in step t: the schedule applies from step t+1."""
        return np.maximum(np.maximum(self.free_at, self.lengths), t + 1), self.free_loc.copy()

    def assign(self, assignments: Sequence[Assignment]) -> None:
        """Extend the schedule; each member is free at the delivery, at the destination."""
        for a in assignments:
            members = [self.team.index(j) for j in a.agents]
            self.free_at[members] = a.finish
            self.free_loc[members] = self.objects[a.object].destination
        self.schedule.extend(assignments)

    def rebase(self) -> None:
        """The free times and places as they stand are the new base (after a failure's statuses)."""
        self.base_len = len(self.schedule)
        self.base_at, self.base_loc = self.free_at.copy(), self.free_loc.copy()

    def open_entries(self, s: int) -> list[int]:
        """Positions in the schedule of the objects a plan for steps from ``s`` may re-plan: no
        member has taken it up, or can have by step s, and no kept task of a member follows it.

        An agent takes up its next task the step it is free (search over, last carry
        delivered); that task and everything before it stays, for every member, so every kept
        entry executes exactly as planned. Take-over sweeps and entries before the last failure
        stay. Computed from the schedule alone: every agent finds the same positions."""
        sched = self.schedule
        kept = set(range(self.base_len))
        own: dict[int, list[int]] = {}
        for pos in range(self.base_len, len(sched)):
            e = sched[pos]
            if isinstance(e, Sweep) or e.start <= s:
                kept.add(pos)
            for j in e.agents:
                own.setdefault(j, []).append(pos)
        for j, mine in own.items():
            i = self.team.index(j)
            free = max(int(self.lengths[i]), int(self.base_at[i]))
            for pos in mine:
                if free > s:
                    break
                kept.add(pos)  # done, under way, or taken up by step s
                free = max(free, sched[pos].finish)
        changed = True
        while changed:  # a kept task keeps every earlier task of each of its members
            changed = False
            for mine in own.values():
                last = max((k for k, pos in enumerate(mine) if pos in kept), default=0)
                for pos in mine[:last]:  # (none kept: none before it either)
                    if pos not in kept:
                        kept.add(pos)
                        changed = True
        return [pos for pos in range(len(sched)) if pos not in kept]

    def reopen(self, positions: Sequence[int]) -> list[int]:
        """Take the entries at ``positions`` out of the schedule (their objects, in schedule
        order) and move every agent's free time and place back to its last kept entry."""
        drop = set(positions)
        objects = [self.schedule[p].object for p in sorted(drop)]  # type: ignore[union-attr]
        self.schedule[:] = [e for p, e in enumerate(self.schedule) if p not in drop]
        self.free_at, self.free_loc = self.base_at.copy(), self.base_loc.copy()
        for e in self.schedule[self.base_len :]:
            members = [self.team.index(j) for j in e.agents]
            self.free_at[members] = e.finish
            if isinstance(e, Sweep):
                self.free_loc[members] = e.path[-1]
            else:
                self.free_loc[members] = self.objects[e.object].destination
        return objects

    def predict_makespan(self, t: int, agents: Sequence[int]) -> int:
        """When the last of ``agents`` is home, if the schedule as it stands is all there is."""
        cost, loc = self.costs(t)
        bases = np.array(self.team.bases, dtype=np.int64).reshape(-1, 2)
        home = arrival_np(cost, np.abs(loc - bases).sum(axis=1), self.team.period_array())
        return int(np.max(home[[self.team.index(j) for j in agents]]))

    @property
    def assignments(self) -> list[Assignment]:
        """The global schedule's objects (without take-over sweeps), in scheduling order."""
        return [a for a in self.schedule if isinstance(a, Assignment)]


class QueuedMessages:
    """What every shared-schedule comm module (CCP's, NCP's) does with the messages it queues for
    the agent's next step, and the trigger it reports."""

    _outbox: list[AgentMessage]
    policy: CoordinationPolicy

    @property
    def trigger(self) -> str:
        return self.policy.name

    def pending(self) -> bool:
        """Messages queued for the next step (a selection, an update, a negotiation move)."""
        return bool(self._outbox)

    def drain(self) -> list[AgentMessage]:
        out, self._outbox = self._outbox, []
        return out
