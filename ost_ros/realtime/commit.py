"""What a robot may commit, in one place (ROS-free, no I/O).

A robot *commits* step s when it promises that nothing more it sends is stamped ≤ s: its
watermark (:class:`~ost_ros.realtime.stamps.Speaker`), which every peer's batch s waits for. It
may do so once every event of time ≤ s is handled; :class:`CommitRule` says when that is. The
runtime (:class:`~ost_ros.realtime.agent.RealtimeAgent`) sets its inputs as things happen and
asks it before it commits; nothing else decides.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

EPS = 1e-9
NO_LIMIT = 1 << 62  # (no base limit: a step no run reaches)


@dataclass(frozen=True)
class Gate:
    """A carry waits for the batches up to ``batch`` to be known (CCP's improved planner: a
    re-plan in them could still move it); ``step``: the step whose decision it holds (None: the
    gate needs that step itself, and holds no commitment)."""

    batch: int
    step: int | None


@dataclass
class CommitRule:
    """What a robot may commit up to.

    At time ``now`` it may commit the smallest of

    1. ``floor(now)``: its clock has passed it;
    2. ``floor(base_known)``: every event of its base up to there is in — an agent node learns
       that from its base's clock; in process there is no limit unless the run gives its bases a
       lag or puts them across a network;
    3. the step before the first decision ``due`` and not taken yet, when its base is across a
       network (``remote``): that decision is taken as of its due time;
    4. the step before ``gate.step``: a carry gated in step g is decided again in g once the
       batches up to its gate are known, so the decision of g may still change;

    and nothing while a decision asked for is still to come (``asked``): the commitment waits
    (``deferred``) and is made once that decision is taken.

    It is *held* — its caller calls again once more of its base's events are in — while a
    status waits for them (``status_wait``, about a carry it is ``unsure`` of), or while its
    base's events keep its commitment below something due by now that someone waits for (a
    watermark wanted, a batch).
    """

    remote: bool = False  # its base is across a network (an agent node)
    base_known: float = math.inf  # its base's events are in up to here
    due: set[float] = field(default_factory=set)  # times a decision is due at, not taken yet
    asked: float | None = None  # a decision asked for (when), its answer still to come
    deferred: float | None = None  # the time to commit once that decision is taken
    gate: Gate | None = None
    unsure: bool = False  # a carry whose lift its base may not have told of yet
    status_wait: float | None = None  # its status is of then: it waits for its base's events up to it

    def base_limit(self) -> int:
        """The highest step its base's events allow (a message stamped above it carries no
        higher watermark)."""
        return math.floor(self.base_known + EPS) if math.isfinite(self.base_known) else NO_LIMIT

    def due_by(self, now: float) -> list[float]:
        """The decisions due by ``now`` and not taken yet (their times)."""
        return [d for d in self.due if d <= now + EPS]

    def limit(self, now: float) -> int:
        """The step it may commit at ``now`` (no decision asked for is to come: :meth:`defer`)."""
        c = math.floor(now + EPS)
        if self.gate is not None and self.gate.step is not None and c <= self.gate.step:
            c = self.gate.step - 1
        if self.remote:
            due = self.due_by(now)
            if due:
                c = min(c, math.ceil(min(due) - EPS) - 1)
        return min(c, self.base_limit())

    def defer(self, now: float) -> None:
        """A decision asked for is still to come: commit as of ``now`` once it is taken."""
        self.deferred = now if self.deferred is None else max(self.deferred, now)

    def held(self, now: float, committed: int, waited_for: Iterable[int | None]) -> bool:
        """Whether its base's events hold its commitment back while someone waits for it:
        ``committed`` is its watermark, ``waited_for`` the stamps someone waits for (the
        smallest watermark wanted, the next batch due; None: none)."""
        if self.status_wait is not None and self.unsure:
            return True
        if self.base_known >= math.floor(now + EPS):
            return False
        return any(t is not None and committed < t <= now + EPS for t in waited_for)

    def status_ready(self, t: float) -> bool:
        """Its base's events are in up to ``t``: whether a status waiting for them can say now."""
        return self.status_wait is not None and t >= self.status_wait - EPS
