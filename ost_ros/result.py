"""The outcome of a run, as printed by ``ost sim`` and published by the world node."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class AgentRecord:
    """Per-agent accounting. ``cost`` is the step the agent was back at base for good (its
    finishing time; the paper's cost of an operation model is the maximum over agents)."""

    id: int
    finished: int | None = None
    idle: int = 0  # steps spent waiting (for a group, or for a schedule) before finishing
    carry: int = 0  # steps spent carrying an object
    search: int = 0  # moves along its sweep
    travel: int = 0  # other moves: to objects and back to base

    @property
    def cost(self) -> int | None:
        return self.finished

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "cost": self.cost,
            "idle": self.idle,
            "carry": self.carry,
            "search": self.search,
            "travel": self.travel,
        }


@dataclass
class ObjectRecord:
    id: int
    agents: tuple[int, ...]  # the group that carried it
    start: int | None  # step the carrying began (the group was complete)
    delivered: int | None  # step it reached its destination

    def to_dict(self) -> dict[str, Any]:
        return {"id": self.id, "agents": list(self.agents), "start": self.start, "delivered": self.delivered}


@dataclass
class RunResult:
    makespan: int | None  # step the last agent was back at base (None if incomplete)
    last_delivery: int  # step the last object reached its destination
    completed: bool
    steps: int
    agents: list[AgentRecord]
    objects: list[ObjectRecord]
    rejections: list[str] = field(default_factory=list)
    protocol: str = "ccp"
    trigger: str = ""
    predicted_makespan: int | None = None
    coordinations: int = 0
    messages: int = 0
    agreement: bool = True  # every agent ended with the same global schedule
    warnings: list[str] = field(default_factory=list)
    found: dict[int, int] = field(default_factory=dict)  # object id -> step it was found
    schedule: list = field(default_factory=list)  # planned Assignments, in order
    error: str | None = None
    lower_bound: int | None = None  # a makespan no run of the scenario can beat (ost_ros.bounds)
    failures: list = field(default_factory=list)  # [{"agent", "step"}]: robots that failed

    def to_dict(self) -> dict[str, Any]:
        objects = []
        for o in self.objects:
            d = o.to_dict()
            d["found"] = self.found.get(o.id)
            objects.append(d)
        return {
            "makespan": self.makespan,
            "last_delivery": self.last_delivery,
            "completed": self.completed,
            "protocol": self.protocol,
            "trigger": self.trigger,
            "predicted_makespan": self.predicted_makespan,
            "lower_bound": self.lower_bound,
            "steps": self.steps,
            "coordinations": self.coordinations,
            "messages": self.messages,
            "agreement": self.agreement,
            "agents": [a.to_dict() for a in self.agents],
            "objects": objects,
            "schedule": [
                {"object": a.object, "agents": list(a.agents), "start": a.start, "finish": a.finish}
                for a in self.schedule
            ],
            "rejections": self.rejections,
            "warnings": self.warnings,
            "failures": self.failures,
            "error": self.error,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> RunResult:
        """The inverse of :meth:`to_dict` (reads a result file of ``ost sim --json`` or a run)."""
        from ost_ros.coordination import Assignment

        return cls(
            makespan=d["makespan"],
            last_delivery=d["last_delivery"],
            completed=d["completed"],
            steps=d["steps"],
            agents=[
                AgentRecord(a["id"], a["cost"], a["idle"], a["carry"], a["search"], a["travel"])
                for a in d["agents"]
            ],
            objects=[
                ObjectRecord(o["id"], tuple(o["agents"]), o["start"], o["delivered"]) for o in d["objects"]
            ],
            rejections=d["rejections"],
            protocol=d["protocol"],
            trigger=d["trigger"],
            predicted_makespan=d["predicted_makespan"],
            coordinations=d["coordinations"],
            messages=d["messages"],
            agreement=d["agreement"],
            warnings=d["warnings"],
            found={o["id"]: o["found"] for o in d["objects"] if o.get("found") is not None},
            schedule=[
                Assignment(s["object"], tuple(s["agents"]), s["start"], s["finish"]) for s in d["schedule"]
            ],
            error=d["error"],
            lower_bound=d.get("lower_bound"),
            failures=d.get("failures", []),
        )

    def summary(self) -> str:
        """Human-readable report: headline figures, then one line per agent."""
        lines = []
        status = "completed" if self.completed else f"NOT completed ({self.error or 'step limit'})"
        lines.append(f"protocol {self.protocol} ({self.trigger}): {status}")
        lines.append(f"makespan        {self.makespan}")
        if self.predicted_makespan is not None:
            lines.append(f"predicted       {self.predicted_makespan}")
        if self.lower_bound is not None:
            ratio = (
                f" (makespan/bound {self.makespan / self.lower_bound:.3f})"
                if (self.makespan and self.lower_bound)
                else ""
            )
            lines.append(f"lower bound     {self.lower_bound}{ratio}")
        lines.append(f"last delivery   {self.last_delivery}")
        lines.append(
            f"objects         {sum(o.delivered is not None for o in self.objects)}"
            f"/{len(self.objects)} delivered"
        )
        lines.append(f"coordinations   {self.coordinations}   messages {self.messages}")
        for f in self.failures:
            lines.append(f"failed          agent {f['agent']} in step {f['step']}")
        if self.rejections:
            lines.append(f"rejected actions {len(self.rejections)} (first: {self.rejections[0]})")
        if self.warnings:
            lines.append(f"warnings        {len(self.warnings)} (first: {self.warnings[0]})")
        lines.append("")
        lines.append(f"{'agent':>5} {'cost':>8} {'idle':>8} {'carry':>8} {'search':>8} {'travel':>8}")
        for a in self.agents:
            lines.append(f"{a.id:>5} {a.cost!s:>8} {a.idle:>8} {a.carry:>8} {a.search:>8} {a.travel:>8}")
        return "\n".join(lines)


def world_result(
    agents: list[AgentRecord],
    objects: list[ObjectRecord],
    *,
    done: bool,
    left: list[int],
    required: dict[int, int],
    failed: dict[int, int],
    steps: int,
    rejections: list[str],
    **extra: Any,
) -> RunResult:
    """The result of a world's record (the lockstep world's and the realtime bases' alike):
    ``agents`` and ``objects`` as recorded, ``done`` (every object the survivors can carry is
    delivered, every survivor home), ``left`` the objects too heavy for the survivors
    (``required``: object → n_i), ``failed`` agent → the step it failed in."""
    finished = [r.finished for r in agents if r.id not in failed and r.finished is not None]
    delivered = [o.delivered for o in objects if o.delivered is not None]
    result = RunResult(
        makespan=max(finished) if done and finished else None,
        last_delivery=max(delivered, default=0),
        completed=done and not left,
        steps=steps,
        agents=agents,
        objects=objects,
        rejections=list(rejections),
        failures=[{"agent": a, "step": t} for a, t in sorted(failed.items())],
        **extra,
    )
    if done and left:
        need = max(required[i] for i in left)
        result.error = (
            f"{len(left)} of {len(objects)} objects cannot be delivered: objects "
            f"{left} need up to {need} robots and {len(agents) - len(failed)} survive (agents "
            f"{sorted(failed)} failed)"
        )
    return result
