"""A discrete-event network for the in-process realtime run: a heap of timed events and a
broadcast whose copies each take ``latency`` steps plus a seeded draw from 0..``jitter`` more,
drawn per (message, receiver) — so copies of one message arrive at different times and messages
overtake each other.

Events at one time run in phase order: failures (``KILL``), the world's events (``WORLD``: goal
results, detections), agents' timers (``WAKE``: decisions, commitments), then deliveries
(``DELIVER``); within a phase, in the order they were scheduled. Nothing here knows what an
event means: :mod:`ost_ros.realtime.run` dispatches them.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

KILL, WORLD, WAKE, DELIVER = 0, 1, 2, 3


@dataclass(frozen=True)
class Latency:
    """``steps`` + U{0..``jitter``} per copy of a message (in steps)."""

    steps: float = 0
    jitter: float = 0

    def __post_init__(self) -> None:
        if self.steps < 0 or self.jitter < 0:
            raise ValueError(f"latency {self.steps}:{self.jitter}: both must be ≥ 0")


@dataclass
class EventQueue:
    """Timed events, popped in (time, phase, order) order."""

    _heap: list[tuple[float, int, int, Any]] = field(default_factory=list)
    _count: int = 0

    def push(self, time: float, phase: int, event: Any) -> None:
        self._count += 1
        heapq.heappush(self._heap, (time, phase, self._count, event))

    def pop(self) -> tuple[float, int, Any]:
        time, phase, _, event = heapq.heappop(self._heap)
        return time, phase, event

    def peek(self) -> float | None:
        return self._heap[0][0] if self._heap else None

    def __len__(self) -> int:
        return len(self._heap)


@dataclass(frozen=True)
class Split:
    """A partition: from step ``start`` for ``steps`` steps, copies between robots of different
    ``groups`` are held and delivered once it heals (their own delay after that) — or, ``lost``,
    never delivered (as DDS loses what a peer it dropped missed: the robots say it again when
    the peers are back, :meth:`~ost_ros.realtime.run._Run.heal`); robots in no group, and the
    membership monitor, reach everyone (its host, as the world's, stays reachable from every
    robot)."""

    groups: tuple[frozenset[int], ...]
    start: float
    steps: float
    lost: bool = False

    def __post_init__(self) -> None:
        if self.start < 0 or self.steps <= 0:
            raise ValueError(f"split from step {self.start} for {self.steps} steps")
        seen: set[int] = set()
        for g in self.groups:
            if seen & g:
                raise ValueError(f"split: robots {sorted(seen & g)} in two groups")
            seen |= g
        if len(self.groups) < 2:
            raise ValueError("split: at least two groups")

    def holds(self, sender: int | None, receiver: int, now: float) -> bool:
        if not self.start <= now < self.start + self.steps or sender is None:
            return False
        gs = next((g for g in self.groups if sender in g), None)
        gr = next((g for g in self.groups if receiver in g), None)
        return gs is not None and gr is not None and gs is not gr


def parse_split(text: str) -> tuple[tuple[frozenset[int], ...], int, int]:
    """GROUPS:T:S — robots by commas, groups by slashes (``0,1,2/3,4:100:50``): two groups or more,
    no robot in two, T ≥ 0, S ≥ 1 (what T and S count is the caller's: steps in process, sim
    time and wall seconds over DDS). A ValueError says what is wrong."""
    try:
        groups_text, t, s = text.split(":")
        groups = tuple(frozenset(int(x) for x in g.split(",")) for g in groups_text.split("/"))
        start, length = int(t), int(s)
    except ValueError:
        raise ValueError(f"expected GROUPS:T:S (e.g. 0,1,2/3,4:100:50), got {text!r}") from None
    if len(groups) < 2 or start < 0 or length < 1 or any(a < 0 for g in groups for a in g):
        raise ValueError(f"expected two groups or more, T ≥ 0, S ≥ 1, got {text!r}")
    if sum(len(g) for g in groups) != len(frozenset().union(*groups)):
        raise ValueError(f"a robot in two groups: {text!r}")
    return groups, start, length


@dataclass
class Network:
    """Broadcasts over seeded latencies into an :class:`EventQueue` (``splits``: partitions that
    hold copies between groups until they heal, or lose them)."""

    queue: EventQueue
    latency: Latency = Latency()
    seed: int = 0
    sent: int = 0  # copies scheduled
    splits: tuple[Split, ...] = ()
    held: int = 0  # copies a partition held
    lost: int = 0  # copies a partition lost
    _rng: np.random.Generator = field(init=False)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)

    def delay(self) -> float:
        """One copy's transit time (integer draws when the latency is integral)."""
        j = self.latency.jitter
        if j <= 0:
            return self.latency.steps
        if float(j).is_integer():
            return self.latency.steps + int(self._rng.integers(0, int(j) + 1))
        return self.latency.steps + float(self._rng.uniform(0, j))

    def send(self, now: float, payload: Any, receivers: Iterable[int]) -> None:
        """One copy of ``payload`` to each receiver, each with its own delay (after the heal, if
        a partition lies between them)."""
        sender = getattr(payload, "sender", None)
        for r in receivers:
            self.sent += 1
            at = now
            cut = [sp for sp in self.splits if sp.holds(sender, r, now)]
            if any(sp.lost for sp in cut):
                self.lost += 1
                continue
            for sp in cut:
                at = max(at, sp.start + sp.steps)
            if at > now:
                self.held += 1
            self.queue.push(at + self.delay(), DELIVER, (r, payload))
