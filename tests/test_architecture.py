"""The layout's promises (docs/architecture.md, "Layers"):

- every import goes to the same layer or a lower one — core ← messages ← node common ← nodes ←
  commands — and no node package imports another;
- no import cycles, neither between modules nor between packages (an import inside a function
  counts: it only hides the cycle; so does a module imported by name);
- the core imports and runs without ROS.
"""

import ast
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("ost_ros", "ost_msgs_py", "world_node", "agent_node")

# The layers, lowest first, each with the module prefixes that belong to it; a module belongs to
# the layer of its longest matching prefix. A module may import from its own layer and the
# layers before it, never from a later one.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    # ROS-free: model, world, protocols, engines, the lockstep runtimes, study, ...
    ("core", ("ost_ros",)),
    # the ROS interfaces and what is tied to them: wire conversion, signing, recordings
    ("messages", ("ost_msgs_py",)),
    # what the nodes share: topics and QoS, signing checks, parameters, a node process's life
    ("node common", ("ost_ros.node",)),
    ("nodes", ("agent_node", "world_node")),
    # the `ost` CLI (ost up: the bring-up of a run)
    ("commands", ("ost_ros.commands", "ost_ros.cli", "ost_ros.__main__")),
)
ORDER = " ← ".join(name for name, _ in LAYERS)
NODE_PACKAGES = ("agent_node", "world_node")


def modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for f in (REPO / pkg).rglob("*.py"):
            parts = list(f.relative_to(REPO).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = f
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the product modules it imports, at any depth of its code (and by name)."""
    mods = modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for name, path in mods.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                # `from pkg import sub` imports the submodule when there is one
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in mods:
                targets = [node.value]  # a module imported by name (importlib)
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != name:
                    graph[name].add(t)
    return graph


def within(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def layer(module: str) -> int:
    """The index in LAYERS of the module's layer (its longest matching prefix)."""
    best, level = -1, -1
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if within(module, p) and len(p) > best:
                best, level = len(p), i
    assert level >= 0, f"{module}: in no layer (add its prefix to LAYERS)"
    return level


def violations(graph: dict[str, set[str]]) -> list[str]:
    """Every import that breaks a layer rule, said with the rule it breaks."""
    out = []
    for a, targets in sorted(graph.items()):
        for b in sorted(targets):
            la, lb = layer(a), layer(b)
            if lb > la:
                allowed = ", ".join(name for name, _ in LAYERS[: la + 1])
                out.append(
                    f"{a} ({LAYERS[la][0]}) imports {b} ({LAYERS[lb][0]}): a {LAYERS[la][0]} module "
                    f"may import only {allowed} (layers {ORDER})"
                )
            elif LAYERS[la][0] == LAYERS[lb][0] == "nodes" and a.split(".")[0] != b.split(".")[0]:
                out.append(
                    f"{a} imports {b}: no node package imports another (shared code goes to ost_ros.node)"
                )
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one member (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10_000)
    for v in graph:
        if v not in index:
            visit(v)
    return out


def collapsed(graph: dict[str, set[str]], unit) -> dict[str, set[str]]:
    """The graph between units (``unit(module)``: the package a module counts as)."""
    out: dict[str, set[str]] = {unit(m): set() for m in graph}
    for a, targets in graph.items():
        out[unit(a)] |= {unit(b) for b in targets if unit(b) != unit(a)}
    return out


def top_package(module: str) -> str:
    """The product's packages as the layers cut them: ``ost_ros`` (the core), ``ost_ros.node``,
    ``ost_ros.commands`` (with the CLI), ``ost_msgs_py``, ``agent_node``, ``world_node``."""
    name, prefixes = LAYERS[layer(module)]
    if name == "commands":
        return "ost_ros.commands"
    return next(p for p in prefixes if within(module, p)) if name != "nodes" else module.split(".")[0]


def sub_package(module: str) -> str:
    """Inside the core: each sub-package of ``ost_ros`` (``ost_ros.protocols``,
    ``ost_ros.engines``, ...) is one unit; a module directly in ``ost_ros`` is its own."""
    parts = module.split(".")
    if LAYERS[layer(module)][0] != "core" or len(parts) < 2:
        return top_package(module)
    top = REPO / "ost_ros" / parts[1]
    return ".".join(parts[:2]) if top.is_dir() else module


def test_every_import_keeps_to_the_layers():
    assert violations(import_graph()) == []


def test_the_layer_rule_catches_what_it_should():
    bad = {
        "ost_ros.model": {"ost_msgs_py.wire"},  # core → messages
        "ost_msgs_py.auth": {"ost_ros.node.transport"},  # messages → node common
        "ost_ros.node.run": {"world_node.world_node"},  # node common → nodes
        "world_node.world_node": {"agent_node.agent_node", "ost_ros.cli"},  # sideways, → commands
        "ost_ros.cli": {"world_node.world_node", "ost_ros.node.run"},  # commands may
        "agent_node.agent_node": {"ost_ros.node.run", "ost_msgs_py.wire", "ost_ros.protocols"},
    }
    found = violations(bad)
    assert len(found) == 5, found
    assert found[0].startswith("ost_msgs_py.auth (messages) imports ost_ros.node.transport (node common)")
    assert "no node package imports another" in found[-2] and "(commands)" in found[-1]


def test_no_import_cycles():
    assert cycles(import_graph()) == []


def test_no_package_cycles():
    graph = import_graph()
    assert cycles(collapsed(graph, top_package)) == []
    assert cycles(collapsed(graph, sub_package)) == []


def test_the_core_imports_no_ros():
    core = [m for m in import_graph() if LAYERS[layer(m)][0] == "core"]
    code = (
        "import sys, importlib\n"
        f"for m in {core!r}:\n"
        "    importlib.import_module(m)\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rosidl_runtime_py', "
        "'std_msgs', 'ost_msgs', 'ost_msgs_py', 'agent_node', 'world_node') or m.startswith("
        "('ost_ros.node', 'ost_ros.commands')))\n"
        "print(bad)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True)
    assert out.stdout.strip() == "[]"
