"""Scenario files (YAML): strict loading and validation, writing, and the paper's random generator.

File format::

    grid: {width: 500, height: 200}
    partition: [5, 2]            # optional: Table 2 / closest aspect ratio by default
    agents:                      # optional: one per subarea, based at its sweep start
      - {id: 0, base: [0, 1]}    # optional period: 2 = moves one cell every 2 steps;
                                 # forbidden: [[x0, y0, x1, y1]] (never searched by it, see
                                 # ost negotiate partition); sweep: [[x, y], ...] (its own
                                 # sweep waypoints instead of its subarea's; all agents or none)
    objects:
      - {id: 0, location: [12, 7], destination: [300, 150], required: 3}
    nmax: 10                     # optional: defaults to the largest ``required``

Every problem is reported as :class:`ScenarioError` naming the field, e.g.
``objects[3].location: [510, 4] is off the 500x200 grid``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ost_ros import validate as v
from ost_ros.model import DEFAULT_NMAX, AgentSpec, Grid, ObjectSpec, Scenario, Subarea
from ost_ros.partition import choose_partition, subareas
from ost_ros.validate import FieldError
from ost_ros.yamlload import safe_load

TOP_KEYS = ("grid", "partition", "agents", "objects", "nmax")


class ScenarioError(FieldError):
    """An invalid scenario; the message names the offending field."""


# ----------------------------------------------------------------------------- building


# The largest grid a run can hold: sweeps (agents, engines, the bound) are kept cell by cell, about
# 11 bytes per grid cell in all (10 000 x 10 000: 1.1 GB peak, 47 s for ost sim; README).
MAX_CELLS = 10**9


def build_scenario(
    grid: Grid,
    objects: list[ObjectSpec] | tuple[ObjectSpec, ...],
    *,
    n_agents: int | None = None,
    partition: tuple[int, int] | None = None,
    agents: list[AgentSpec] | None = None,
    nmax: int | None = None,
) -> Scenario:
    """Assemble and validate a scenario. The team comes from ``agents``, else ``partition``,
    else ``n_agents`` (with the default partition); default bases are the subareas' sweep starts."""
    if grid.width < 1 or grid.height < 1:
        raise ScenarioError(f"grid: size must be positive, got {grid.width}x{grid.height}")
    if grid.cells > MAX_CELLS:
        raise ScenarioError(
            f"grid: {grid.width}x{grid.height} has {grid.cells:,} cells, more than the {MAX_CELLS:,} a "
            "run can hold (every robot's sweep is kept cell by cell, so memory grows with the area)"
        )
    count = _team_size(agents, partition, n_agents)
    partition, areas = _partition(grid, count, partition)
    if agents is None:
        agents = [AgentSpec(k, areas[k].start) for k in range(count)]
    agents = sorted(agents, key=lambda a: a.id)
    _check_agents(grid, agents)
    if any(a.sweep for a in agents):
        _check_coverage(grid, agents, areas)
    objects = sorted(objects, key=lambda o: o.id)
    largest = max((o.required for o in objects), default=1)
    nmax = largest if nmax is None else nmax
    if nmax < 1:
        raise ScenarioError(f"nmax: must be at least 1, got {nmax}")
    if nmax > count:
        raise ScenarioError(f"nmax: {nmax} exceeds the team of {count} agents (the task cannot be completed)")
    _check_objects(grid, objects, nmax)
    return Scenario(
        grid=grid,
        partition=(partition[0], partition[1]),
        agents=tuple(agents),
        objects=tuple(objects),
        nmax=nmax,
        subareas=areas,
    )


def _team_size(
    agents: list[AgentSpec] | None, partition: tuple[int, int] | None, n_agents: int | None
) -> int:
    if agents is not None:
        count = len(agents)
    elif partition is not None:
        count = partition[0] * partition[1]
    elif n_agents is not None:
        count = n_agents
    else:
        raise ScenarioError("agents: missing (give an agents list or a partition)")
    if count < 1:
        raise ScenarioError("agents: the team needs at least one agent")
    return count


def _partition(
    grid: Grid, count: int, partition: tuple[int, int] | None
) -> tuple[tuple[int, int], tuple[Subarea, ...]]:
    """The m×n partition (the default one for ``count`` agents if not given) and its subareas."""
    if partition is None:
        try:
            partition = choose_partition(count, grid)
        except ValueError as exc:
            raise ScenarioError(f"partition: {exc}") from None
    if partition[0] < 1 or partition[1] < 1:
        raise ScenarioError(f"partition: sizes must be positive, got {list(partition)}")
    if partition[0] * partition[1] != count:
        raise ScenarioError(
            f"partition: {partition[0]}x{partition[1]} has "
            f"{partition[0] * partition[1]} subareas for {count} agents"
        )
    try:
        return partition, tuple(subareas(grid, partition))
    except ValueError as exc:
        raise ScenarioError(f"partition: {exc}") from None


def _check_agents(grid: Grid, agents: list[AgentSpec]) -> None:
    seen: set[int] = set()
    for k, a in enumerate(agents):
        if a.id in seen:
            raise ScenarioError(f"agents[{k}].id: duplicate id {a.id}")
        seen.add(a.id)
        if not grid.contains(a.base):
            raise ScenarioError(
                f"agents[{k}].base: {list(a.base)} is off the {grid.width}x{grid.height} grid"
            )
        if not isinstance(a.period, int) or a.period < 1:
            raise ScenarioError(f"agents[{k}].period: must be an integer >= 1, got {a.period!r}")
        for i, c in enumerate(a.sweep):
            if not grid.contains(c):
                raise ScenarioError(
                    f"agents[{k}].sweep[{i}]: {list(c)} is off the {grid.width}x{grid.height} grid"
                )
        for i, (x0, y0, x1, y1) in enumerate(a.forbidden):
            if not (0 <= x0 <= x1 < grid.width and 0 <= y0 <= y1 < grid.height):
                raise ScenarioError(
                    f"agents[{k}].forbidden[{i}]: {[x0, y0, x1, y1]} must satisfy "
                    f"0 <= x0 <= x1 < {grid.width} and 0 <= y0 <= y1 < {grid.height}"
                )


def _check_objects(grid: Grid, objects: list[ObjectSpec], nmax: int) -> None:
    ids: set[int] = set()
    for k, o in enumerate(objects):
        where = f"objects[{k}]"
        if o.id in ids:
            raise ScenarioError(f"{where}.id: duplicate id {o.id}")
        ids.add(o.id)
        for name in ("location", "destination"):
            cell = getattr(o, name)
            if not grid.contains(cell):
                raise ScenarioError(
                    f"{where}.{name}: {list(cell)} is off the {grid.width}x{grid.height} grid"
                )
        if o.location == o.destination:
            raise ScenarioError(f"{where}.destination: equals its location {list(o.location)}")
        if not 1 <= o.required <= nmax:
            raise ScenarioError(f"{where}.required: {o.required} is outside 1..nmax={nmax}")


def _check_coverage(grid: Grid, agents: list[AgentSpec], areas) -> None:
    """Own sweeps (all agents or none) must together sense every cell, or objects go unfound."""
    import numpy as np

    from ost_ros.search import agent_plan, route

    missing = [k for k, a in enumerate(agents) if not a.sweep]
    if missing:
        raise ScenarioError(f"agents[{missing[0]}].sweep: missing (give every agent a sweep, or none)")
    seen = np.zeros((grid.height + 2, grid.width + 2), dtype=bool)  # padded: 3x3 at the edges
    for area, a in zip(areas, agents):
        cells = np.array(route(agent_plan(area, a.base, a.sweep)), dtype=np.int64).reshape(-1, 2)
        for dx in (0, 1, 2):
            for dy in (0, 1, 2):
                seen[cells[:, 1] + dy, cells[:, 0] + dx] = True
    gap = np.argwhere(~seen[1:-1, 1:-1])
    if len(gap):
        y, x = gap[0]
        raise ScenarioError(f"agents: cell ({x}, {y}) is sensed by no agent's sweep ({len(gap)} such cells)")


def with_team(scenario: Scenario, n_agents: int) -> Scenario:
    """The same objects with a new team of ``n_agents`` (default partition and bases)."""
    return build_scenario(scenario.grid, scenario.objects, n_agents=n_agents, nmax=scenario.nmax)


# ----------------------------------------------------------------------------- parsing


def scenario_from_dict(data: Any) -> Scenario:
    """Validate a parsed YAML/JSON document and build the scenario."""
    try:
        return _scenario_from_dict(data)
    except ScenarioError:
        raise
    except FieldError as exc:
        raise ScenarioError(str(exc)) from None


def _scenario_from_dict(data: Any) -> Scenario:
    if data is None:
        raise ScenarioError("scenario: the file is empty")
    data = v.mapping(data, "scenario", TOP_KEYS, ("objects",))
    g = v.mapping(data.get("grid", {}), "grid", ("width", "height"))
    grid = Grid(
        v.integer(g.get("width", Grid.width), "grid.width", 1),
        v.integer(g.get("height", Grid.height), "grid.height", 1),
    )
    partition = None
    if "partition" in data:
        p = data["partition"]
        if not isinstance(p, (list, tuple)) or len(p) != 2:
            raise ScenarioError(f"partition: expected [m, n], got {p!r}")
        partition = (v.integer(p[0], "partition[0]", 1), v.integer(p[1], "partition[1]", 1))
    agents = None
    if "agents" in data:
        agents = []
        for k, a in enumerate(v.listing(data["agents"], "agents")):
            a = v.mapping(a, f"agents[{k}]", ("id", "base", "period", "sweep", "forbidden"), ("id",))
            aid = v.integer(a["id"], f"agents[{k}].id", 0)
            base = v.cell(a["base"], f"agents[{k}].base") if "base" in a else None
            period = v.integer(a["period"], f"agents[{k}].period", 1) if "period" in a else 1
            sweep = tuple(
                v.cell(c, f"agents[{k}].sweep[{i}]")
                for i, c in enumerate(v.listing(a.get("sweep", []), f"agents[{k}].sweep"))
            )
            zones = []
            for i, z in enumerate(v.listing(a.get("forbidden", []), f"agents[{k}].forbidden")):
                where = f"agents[{k}].forbidden[{i}]"
                if not isinstance(z, list) or len(z) != 4:
                    raise ScenarioError(f"{where}: expected [x0, y0, x1, y1], got {z!r}")
                zones.append(tuple(v.integer(c, where, 0) for c in z))
            agents.append((aid, base, period, sweep, tuple(zones)))
    objects = []
    for k, o in enumerate(v.listing(data["objects"], "objects")):
        o = v.mapping(
            o,
            f"objects[{k}]",
            ("id", "location", "destination", "required"),
            ("id", "location", "destination", "required"),
        )
        objects.append(
            ObjectSpec(
                v.integer(o["id"], f"objects[{k}].id", 0),
                v.cell(o["location"], f"objects[{k}].location"),
                v.cell(o["destination"], f"objects[{k}].destination"),
                v.integer(o["required"], f"objects[{k}].required", 1),
            )
        )
    nmax = v.integer(data["nmax"], "nmax", 1) if "nmax" in data else None
    if agents is not None and any(a[1] is None for a in agents):
        # Agents without a base get their subarea's start cell: needs the partition first.
        if not agents:
            raise ScenarioError("agents: the team needs at least one agent")
        default = build_scenario(grid, [], n_agents=len(agents), partition=partition)
        order = sorted(range(len(agents)), key=lambda k: agents[k][0])
        bases = {agents[k][0]: default.subareas[rank].start for rank, k in enumerate(order)}
        agents = [(aid, base if base is not None else bases[aid], *rest) for aid, base, *rest in agents]  # type: ignore[misc]
    team = None if agents is None else [AgentSpec(*a) for a in agents]  # type: ignore[arg-type]
    return build_scenario(grid, objects, partition=partition, agents=team, nmax=nmax)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file (YAML or JSON)."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ScenarioError(f"{path}: no such file") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read ({exc.__class__.__name__})") from None
    return parse_scenario(text, str(path))


def parse_scenario(text: str, where: str) -> Scenario:
    """Validate a scenario document (YAML or JSON text); errors start with ``where``."""
    try:
        data = safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "malformed YAML"
        raise ScenarioError(f"{where}: invalid YAML{at}: {problem}") from None
    try:
        return scenario_from_dict(data)
    except ScenarioError as exc:
        raise ScenarioError(f"{where}: {exc}") from None


# ----------------------------------------------------------------------------- writing


def scenario_to_dict(scenario: Scenario) -> dict:
    return {
        "grid": {"width": scenario.grid.width, "height": scenario.grid.height},
        "partition": list(scenario.partition),
        "agents": [
            {
                "id": a.id,
                "base": list(a.base),
                **({"period": a.period} if a.period != 1 else {}),
                **({"forbidden": [list(z) for z in a.forbidden]} if a.forbidden else {}),
                **({"sweep": [list(c) for c in a.sweep]} if a.sweep else {}),
            }
            for a in scenario.agents
        ],
        "objects": [
            {
                "id": o.id,
                "location": list(o.location),
                "destination": list(o.destination),
                "required": o.required,
            }
            for o in scenario.objects
        ],
        "nmax": scenario.nmax,
    }


def dump_scenario(scenario: Scenario) -> str:
    """YAML text with one line per agent and per object (diff-friendly, readable)."""
    d = scenario_to_dict(scenario)

    def flow(item: dict) -> str:
        return yaml.safe_dump(item, default_flow_style=True, sort_keys=False, width=1 << 16).strip()

    lines = [f"grid: {flow(d['grid'])}", f"partition: {flow(d['partition'])}", "agents:"]
    lines += [f"  - {flow(a)}" for a in d["agents"]]
    lines.append("objects:" if d["objects"] else "objects: []")
    lines += [f"  - {flow(o)}" for o in d["objects"]]
    lines.append(f"nmax: {d['nmax']}")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- generation


def generate_objects(
    n_objects: int, seed: int, grid: Grid = Grid(), nmax: int = DEFAULT_NMAX
) -> list[ObjectSpec]:
    """The paper's random object set: distinct uniform locations, uniform destinations (never the
    object's own cell), n_i uniform in 1..nmax; sorted by (x, y) of location, id = that rank."""
    if n_objects < 0:
        raise ScenarioError(f"objects: count must be non-negative, got {n_objects}")
    if n_objects > grid.cells:
        raise ScenarioError(
            f"objects: {n_objects} distinct locations do not fit a {grid.width}x{grid.height} grid"
        )
    if nmax < 1:
        raise ScenarioError(f"nmax: must be at least 1, got {nmax}")
    if grid.cells < 2 and n_objects:
        raise ScenarioError("grid: a 1-cell grid has no destination distinct from a location")
    rng = np.random.default_rng(seed)
    loc = rng.choice(grid.cells, size=n_objects, replace=False)
    dest = rng.integers(0, grid.cells, size=n_objects)
    while np.any(same := dest == loc):
        dest[same] = rng.integers(0, grid.cells, size=int(same.sum()))
    req = rng.integers(1, nmax + 1, size=n_objects)
    lx, ly = loc % grid.width, loc // grid.width
    order = np.lexsort((ly, lx))  # sort by x, then y
    return [
        ObjectSpec(
            rank,
            (int(lx[i]), int(ly[i])),
            (int(dest[i] % grid.width), int(dest[i] // grid.width)),
            int(req[i]),
        )
        for rank, i in enumerate(order)
    ]


def generate_scenario(
    n_agents: int, n_objects: int, seed: int, grid: Grid = Grid(), nmax: int = DEFAULT_NMAX
) -> Scenario:
    """A random scenario as in the paper's §5.1; the objects depend on the seed only, not on N."""
    objects = generate_objects(n_objects, seed, grid, nmax)
    return build_scenario(grid, objects, n_agents=n_agents, nmax=nmax)
