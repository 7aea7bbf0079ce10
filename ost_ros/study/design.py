"""The experimental design of the paper's §5, and the quick subset."""

from __future__ import annotations

from dataclasses import dataclass

from ost_ros import protocols
from ost_ros.model import Grid, Scenario
from ost_ros.scenario import build_scenario, generate_objects

GRID = Grid(500, 200)
NMAX = 10
PAPER = "ccp"  # the protocol the paper studies at every N and over the CI sweep (Figs 9–11, Table 3)


@dataclass(frozen=True)
class Variant:
    """One protocol setting run on a scenario. ``ci`` is an int, or "M" for CI = M."""

    protocol: str
    ci: int | str | None = None

    @property
    def label(self) -> str:
        name = self.protocol.upper()
        return name if self.ci is None else f"{name} CI={self.ci}"


def compared() -> list[Variant]:
    """Every protocol of the registry as the study compares them at the compare sizes: those
    without coordination triggers (HCP) first, then each with triggers at CI=1 and CI=M."""
    specs = sorted(protocols.REGISTRY.values(), key=lambda s: s.capabilities.triggers)
    return [
        v
        for s in specs
        for v in (
            [Variant(s.name, 1), Variant(s.name, "M")] if s.capabilities.triggers else [Variant(s.name)]
        )
    ]


@dataclass(frozen=True)
class Task:
    """All variants run on one object set with one team size (they share the scenario)."""

    agents: int
    objects: int
    set: int
    seed: int  # of the object set
    variants: tuple[Variant, ...]
    study_seed: int = 1  # the design's seed the object set comes from

    @property
    def weight(self) -> float:
        """Rough relative cost, to start the heavy tasks first."""
        stepped = any(protocols.get(v.protocol).team_comm is None for v in self.variants)
        return (1 + self.objects) * (self.agents if stepped else 0.05 * len(self.variants))


@dataclass(frozen=True)
class Design:
    agents: tuple[int, ...] = (10, 20, 30, 40, 50)
    objects: tuple[int, ...] = (1, 10, 20, 30, 40, 50, 100, 200)
    sets: int = 10
    cis: tuple[int, ...] = (1, 10, 20, 30, 40, 50, 100, 200)
    compare_agents: tuple[int, ...] = (10, 50)  # Figs 7–10: HCP vs CCP, the CI sweep
    seed: int = 1
    # Further seeds run with Table 3's variants only (CCP CI=1 and CI=M at every N): the spread
    # of each Table 3 cell over independent object sets.
    table3_seeds: tuple[int, ...] = ()

    @classmethod
    def quick(cls, seed: int = 1) -> Design:
        return cls(agents=(10, 20, 50), objects=(1, 10, 50, 100), sets=2, cis=(1, 10, 50, 100), seed=seed)

    @property
    def seeds(self) -> tuple[int, ...]:
        """Every seed of the design: its own first, then the further Table 3 seeds."""
        return (self.seed, *(s for s in self.table3_seeds if s != self.seed))

    def object_seed(self, m: int, s: int, seed: int | None = None) -> int:
        """Seed of object set s for M objects: the same set for every N (as in the paper)."""
        return (self.seed if seed is None else seed) * 1_000_000 + m * 1000 + s

    def tasks(self) -> list[Task]:
        out = []
        for n in self.agents:
            for m in self.objects:
                variants = [Variant(PAPER, 1), Variant(PAPER, "M")]
                if n in self.compare_agents:
                    # every other protocol of the registry (ours beside the paper's HCP)
                    variants.extend(v for v in compared() if v.protocol != PAPER)
                    variants.extend(Variant(PAPER, c) for c in self.cis if c != 1)
                for s in range(self.sets):
                    out.append(Task(n, m, s, self.object_seed(m, s), tuple(variants), self.seed))
                for seed in self.seeds[1:]:
                    t3 = (Variant(PAPER, 1), Variant(PAPER, "M"))
                    out.extend(
                        Task(n, m, s, self.object_seed(m, s, seed), t3, seed) for s in range(self.sets)
                    )
        return sorted(out, key=lambda t: -t.weight)


def scenario_of(task: Task) -> Scenario:
    objects = generate_objects(task.objects, task.seed, GRID, NMAX)
    return build_scenario(GRID, objects, n_agents=task.agents, nmax=NMAX)
