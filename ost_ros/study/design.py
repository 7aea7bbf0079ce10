"""The experimental design of the paper's §5, and the quick subset."""
from __future__ import annotations

from dataclasses import dataclass

from ost_ros.model import Grid
from ost_ros.scenario import build_scenario, generate_objects

GRID = Grid(500, 200)
NMAX = 10


@dataclass(frozen=True)
class Variant:
    """One protocol setting run on a scenario. ``ci`` is an int, or "M" for CI = M."""

    protocol: str
    ci: int | str | None = None

    @property
    def label(self) -> str:
        return "HCP" if self.protocol == "hcp" else f"{self.protocol.upper()} CI={self.ci}"


@dataclass(frozen=True)
class Task:
    """All variants run on one object set with one team size (they share the scenario)."""

    agents: int
    objects: int
    set: int
    seed: int
    variants: tuple[Variant, ...]

    @property
    def weight(self) -> float:
        """Rough relative cost, to start the heavy tasks first."""
        hcp = any(v.protocol == "hcp" for v in self.variants)
        return (1 + self.objects) * (self.agents if hcp else 0.05 * len(self.variants))


@dataclass(frozen=True)
class Design:
    agents: tuple[int, ...] = (10, 20, 30, 40, 50)
    objects: tuple[int, ...] = (1, 10, 20, 30, 40, 50, 100, 200)
    sets: int = 10
    cis: tuple[int, ...] = (1, 10, 20, 30, 40, 50, 100, 200)
    compare_agents: tuple[int, ...] = (10, 50)   # Figs 7–10: HCP vs CCP, the CI sweep
    seed: int = 1

    @classmethod
    def quick(cls, seed: int = 1) -> "Design":
        return cls(agents=(10, 20, 50), objects=(1, 10, 50, 100), sets=2, cis=(1, 10, 50, 100),
                   seed=seed)

    def object_seed(self, m: int, s: int) -> int:
        """Seed of object set s for M objects: the same set for every N (as in the paper)."""
        return self.seed * 1_000_000 + m * 1000 + s

    def tasks(self) -> list[Task]:
        out = []
        for n in self.agents:
            for m in self.objects:
                variants = [Variant("ccp", 1), Variant("ccp", "M")]
                if n in self.compare_agents:
                    variants.append(Variant("hcp"))
                    # NCP (negotiated allocation, not in the paper) as a third curve
                    variants.extend((Variant("ncp", 1), Variant("ncp", "M")))
                    variants.extend(Variant("ccp", c) for c in self.cis if c != 1)
                for s in range(self.sets):
                    out.append(Task(n, m, s, self.object_seed(m, s), tuple(variants)))
        return sorted(out, key=lambda t: -t.weight)


def scenario_of(task: Task):
    objects = generate_objects(task.objects, task.seed, GRID, NMAX)
    return build_scenario(GRID, objects, n_agents=task.agents, nmax=NMAX)
