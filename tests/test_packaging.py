"""The package metadata installs what the product imports: every third-party top-level import of
the product packages (and of the launch files), lazy ones inside functions included, is declared
in setup.py's ``install_requires`` by its PyPI name and in package.xml by its rosdep key — or, for
the few libraries rosdep has no key for, named in package.xml's ``pypi:`` comment. Nothing is
declared that nothing imports."""

import ast
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("ost_ros", "ost_msgs_py", "world_node", "agent_node")

# import name -> (PyPI distribution, rosdep key). Keys checked against rosdistro's rosdep
# database (rosdep/python.yaml); None where it has none (then package.xml's pypi: comment names
# the distribution). mcap: only the pip key mcap-ros2-support, a library the product does not use.
LIBRARIES: dict[str, tuple[str, str | None]] = {
    "numpy": ("numpy", "python3-numpy"),
    "scipy": ("scipy", "python3-scipy"),
    "yaml": ("PyYAML", "python3-yaml"),
    "shapely": ("shapely", "python3-shapely"),
    "matplotlib": ("matplotlib", "python3-matplotlib"),
    "PIL": ("pillow", "python3-pil"),
    "tqdm": ("tqdm", "python3-tqdm"),
    "cryptography": ("cryptography", "python3-cryptography"),
    "mcap": ("mcap", None),
    "foxglove": ("foxglove-sdk", None),
    "imageio_ffmpeg": ("imageio-ffmpeg", None),
}
# Optional: imported only by a feature that says so (studies on a Dask cluster, --cluster); in
# setup.py's extras_require and named in package.xml's pypi: comment.
EXTRAS: dict[str, str] = {"dask": "dask", "distributed": "distributed"}
# ROS packages: package.xml only (from the ROS install or the ros-* wheels; ost_msgs is built here)
ROS = {
    "rclpy",
    "ost_msgs",
    "builtin_interfaces",
    "geometry_msgs",
    "rcl_interfaces",
    "rosgraph_msgs",
    "std_msgs",
    "visualization_msgs",
    "launch",
    "launch_ros",
}


def product_files() -> list[Path]:
    files = [f for pkg in PACKAGES for f in (REPO / pkg).rglob("*.py")]
    return files + sorted((REPO / "launch").glob("*.py"))


def third_party_imports() -> dict[str, str]:
    """Top-level module -> one file importing it, for every non-stdlib, non-product import."""
    found: dict[str, str] = {}
    for path in product_files():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in PACKAGES:
                    found.setdefault(top, str(path.relative_to(REPO)))
    return found


def install_requires() -> set[str]:
    """The distribution names of setup.py's install_requires (version bounds dropped)."""
    tree = ast.parse((REPO / "setup.py").read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "setup")
    value = next(k.value for k in call.keywords if k.arg == "install_requires")
    assert isinstance(value, ast.List)
    return {re.split(r"[<>=!~ ;\[]", ast.literal_eval(e))[0] for e in value.elts}


def package_xml() -> tuple[set[str], set[str]]:
    """(exec_depend keys, distributions named in the pypi: comment) of package.xml."""
    text = (REPO / "package.xml").read_text()
    keys = {e.text or "" for e in ET.fromstring(text).iter("exec_depend")}
    comment = re.search(r"pypi:([^>]*?)-->", text)
    return keys, set(comment.group(1).split()) if comment else set()


def norm(dist: str) -> str:
    return re.sub(r"[-_.]+", "-", dist).lower()


def test_every_import_is_known_here():
    known = LIBRARIES.keys() | ROS | EXTRAS.keys()
    unknown = {m: f for m, f in third_party_imports().items() if m not in known}
    assert not unknown, f"map these imports to their PyPI name and rosdep key in this test: {unknown}"


def test_every_library_import_is_in_install_requires():
    declared = {norm(d) for d in install_requires()}
    missing = [
        f"{LIBRARIES[m][0]} (imported as {m} in {where})"
        for m, where in sorted(third_party_imports().items())
        if m in LIBRARIES and norm(LIBRARIES[m][0]) not in declared
    ]
    assert not missing, f"setup.py install_requires lacks {'; '.join(missing)}"


def extras_require() -> set[str]:
    """Every distribution of setup.py's extras_require (version bounds dropped)."""
    tree = ast.parse((REPO / "setup.py").read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "setup")
    value = ast.literal_eval(next(k.value for k in call.keywords if k.arg == "extras_require"))
    return {re.split(r"[<>=!~ ;\[]", d)[0] for ds in value.values() for d in ds}


def test_every_optional_import_is_an_extra():
    extras = {norm(d) for d in extras_require()}
    missing = [d for m, d in EXTRAS.items() if m in third_party_imports() and norm(d) not in extras]
    assert not missing, f"setup.py extras_require lacks {missing}"


def test_every_import_is_in_package_xml():
    keys, pypi = package_xml()
    missing = []
    for module, where in sorted(third_party_imports().items()):
        dist, key = LIBRARIES.get(module, (EXTRAS[module], None) if module in EXTRAS else (module, module))
        if key is None and dist not in pypi:
            missing.append(f"{dist} in its pypi: comment (no rosdep key; imported in {where})")
        elif key is not None and key not in keys:
            missing.append(f"<exec_depend>{key}</exec_depend> (imported as {module} in {where})")
    assert not missing, f"package.xml lacks {'; '.join(missing)}"


def test_nothing_declared_that_nothing_imports():
    imported = third_party_imports()
    dists = {norm(LIBRARIES[m][0]) for m in imported if m in LIBRARIES}
    assert {norm(d) for d in install_requires()} - dists == set(), "install_requires names an unused library"
    keys, pypi = package_xml()
    wanted = {LIBRARIES[m][1] for m in imported if m in LIBRARIES} | {m for m in imported if m in ROS}
    assert keys - wanted == set(), "package.xml has an exec_depend nothing imports"
    optional = {norm(d) for m, d in EXTRAS.items() if m in imported}
    assert {norm(d) for d in pypi} - dists - optional == set(), (
        "package.xml's pypi: comment names an unused library"
    )


def test_the_lock_pins_every_declared_library():
    pinned = {
        norm(line.split("==")[0])
        for line in (REPO / "requirements.lock").read_text().splitlines()
        if "==" in line and not line.startswith("#")
    }
    missing = sorted(d for d in install_requires() if norm(d) not in pinned)
    assert not missing, f"requirements.lock pins none of {missing}"


def pins(path: Path) -> dict[str, str]:
    out = {}
    for line in path.read_text().splitlines():
        if "==" in line and not line.startswith("#"):
            name, version = line.split("==")
            out[norm(name)] = version.strip()
    return out


def test_the_tools_lock_completes_requirements_lock():
    """tests/ros2_tools.lock (colcon, installed --no-deps by tests/ros2_tools.sh) pins only what
    requirements.lock lacks, and the two together satisfy every requirement of what it pins."""
    from importlib.metadata import PackageNotFoundError, requires, version

    from packaging.requirements import Requirement

    product, tools = pins(REPO / "requirements.lock"), pins(REPO / "tests" / "ros2_tools.lock")
    assert not set(product) & set(tools), "pinned in both lock files"
    both = product | tools
    unmet = []
    for dist, pinned in sorted(tools.items()):
        try:
            assert version(dist) == pinned, f"{dist} {version(dist)} installed, {pinned} pinned"
            wants = requires(dist) or []
        except PackageNotFoundError:
            raise AssertionError(
                f"{dist} is not installed: tests/ros2_tools.sh installs the tools lock"
            ) from None
        for text in wants:
            req = Requirement(text)
            if req.marker is not None and not req.marker.evaluate({"extra": ""}):
                continue
            have = both.get(norm(req.name))
            if have is None or not req.specifier.contains(have, prereleases=True):
                unmet.append(f"{dist} needs {req} (pinned: {have})")
    assert not unmet, "; ".join(unmet)
