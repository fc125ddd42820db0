"""The layout says the architecture: one folder per concern, dependencies one way, no import cycles.

Read from the sources with ast (module level and inside functions, TYPE_CHECKING
blocks included), so a deferred import that only hides a cycle is still a cycle.
"""
from __future__ import annotations

import ast
import configparser
import re
from collections import defaultdict
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "ros_ws" / "src"
#: lower packages first: each may import only the ones before it
PACKAGES = ("worm_model", "worm_rig_driver", "torque_estimator")
#: where rclpy may be imported: the ROS shells (a module in nodes/ or ros/, or one named *_node.py)
ROS_SHELL = re.compile(r"\.(nodes|ros)(\.|$)|_node$")


def modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in (SRC / package / package).rglob("*.py"):
            parts = path.relative_to(SRC / package).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            found[name] = path
    return found


MODULES = modules()


def imports(path: Path) -> set[str]:
    """Project modules (or packages) imported by one file, relative imports resolved."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}: relative import (the project uses absolute imports)"
            names = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in MODULES else node.module
                     for a in node.names]
        else:
            continue
        out |= {name for name in names if name.split(".")[0] in PACKAGES}
    return out


GRAPH = {name: imports(path) for name, path in MODULES.items()}


def concern(module: str) -> str:
    """``pkg.subpackage`` for a module in a subpackage, ``pkg`` for one at the package's top."""
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 2 or MODULES[module].name == "__init__.py" and len(parts) == 2 \
        else parts[0]


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one node (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges.get(v, ()):
            if w == v:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_every_import_resolves_to_a_project_module() -> None:
    missing = {(m, t) for m, targets in GRAPH.items() for t in targets if t not in MODULES}
    assert not missing, f"imports of modules that do not exist: {sorted(missing)}"


def test_no_module_import_cycles() -> None:
    assert cycles(GRAPH) == []


def test_no_cycles_between_concerns() -> None:
    edges: dict[str, set[str]] = defaultdict(set)
    for module, targets in GRAPH.items():
        edges[concern(module)] |= {concern(t) for t in targets} - {concern(module)}
    assert cycles(edges) == []


@pytest.mark.parametrize("package", PACKAGES)
def test_packages_import_only_the_ones_below(package: str) -> None:
    above = set(PACKAGES[PACKAGES.index(package) + 1:])
    upward = {(m, t) for m, targets in GRAPH.items() if m.split(".")[0] == package
              for t in targets if t.split(".")[0] in above}
    assert not upward, f"{package} imports packages above it: {sorted(upward)}"


def test_rclpy_only_in_the_ros_shells() -> None:
    offenders = []
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        uses = any(isinstance(n, ast.Import) and any(a.name.split(".")[0] == "rclpy" for a in n.names)
                   or isinstance(n, ast.ImportFrom) and (n.module or "").split(".")[0] == "rclpy"
                   for n in ast.walk(tree))
        if uses and not ROS_SHELL.search(name):
            offenders.append(name)
    assert offenders == [], "rclpy outside nodes/, ros/ and *_node modules (the cores stay plain Python)"


@pytest.mark.parametrize("package", PACKAGES)
def test_every_package_and_concern_opens_with_a_map(package: str) -> None:
    root = SRC / package / package
    top = ast.get_docstring(ast.parse((root / "__init__.py").read_text(encoding="utf-8"))) or ""
    folders = sorted(p.parent for p in root.glob("*/__init__.py"))
    assert folders, f"{package} has no subpackages"
    assert not [p for p in root.glob("*.py") if p.name not in ("__init__.py", "errors.py")], \
        f"{package}: modules at the top level beside the concern folders (errors.py, its errors, aside)"
    assert (root / "errors.py").is_file() and "``errors``" in top, \
        f"{package}: its errors in one module, errors.py, named in its map"
    for folder in folders:
        assert f"``{folder.name}``" in top, f"{package}/__init__.py's map does not name {folder.name}/"
        doc = ast.get_docstring(ast.parse((folder / "__init__.py").read_text(encoding="utf-8")))
        assert doc, f"{folder}/__init__.py has no docstring saying what the folder holds"
    assert "Read first" in top, f"{package}/__init__.py does not say which module a newcomer reads first"


@pytest.mark.parametrize("package", PACKAGES)
def test_tests_mirror_the_layout(package: str) -> None:
    """Every folder of a package's test/ is a concern folder of worm_model or of the package itself."""
    concerns = {p.parent.name for pkg in (package, "worm_model") for p in (SRC / pkg / pkg).glob("*/__init__.py")}
    folders = {p.parent.name for p in (SRC / package / "test").rglob("test_*.py")}
    assert folders <= concerns, f"{package}/test folders with no concern of that name: {sorted(folders - concerns)}"
    assert not list((SRC / package / "test").glob("test_*.py")), f"{package}/test: tests outside a concern folder"


@pytest.mark.parametrize("package", PACKAGES)
def test_every_console_script_names_an_existing_function(package: str) -> None:
    text = (SRC / package / "setup.py").read_text(encoding="utf-8")
    scripts = re.findall(r'"(\w+) = ([\w.]+):(\w+)"', text)
    assert scripts, f"{package}/setup.py declares no console_scripts"
    for exe, module, function in scripts:
        assert module in MODULES, f"{package}: {exe} -> {module}, which does not exist"
        tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
        assert any(isinstance(n, ast.FunctionDef) and n.name == function for n in tree.body), \
            f"{package}: {exe} -> {module}:{function}, no such function"
    config = configparser.ConfigParser()
    config.read(SRC / package / "setup.cfg")
    assert config["install"]["install_scripts"] == f"$base/lib/{package}"  # where `ros2 run` looks


@pytest.mark.parametrize("package", PACKAGES)
def test_every_module_is_named_in_its_folders_map(package: str) -> None:
    """A newcomer opening a folder's ``__init__.py`` learns every module in it: each is named as ``name``."""
    unnamed = []
    for init in sorted((SRC / package / package).rglob("__init__.py")):
        if init.parent == SRC / package / package:
            continue  # the package's top map names its folders (test_every_package_and_concern_opens_with_a_map)
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8"))) or ""
        for module in sorted(init.parent.glob("*.py")):
            if module.name != "__init__.py" and f"``{module.stem}``" not in doc:
                unnamed.append(str(module.relative_to(SRC)))
    assert unnamed == [], "modules their folder's __init__.py does not name as ``module``: " + ", ".join(unnamed)


def _folders(package: str) -> list[str]:
    """The package's concern folders, nested ones as ``parent/child``."""
    root = SRC / package / package
    return sorted(str(init.parent.relative_to(root)) for init in root.rglob("__init__.py") if init.parent != root)


@pytest.mark.parametrize("package", PACKAGES)
def test_every_folder_is_named_in_design_md(package: str) -> None:
    """docs/design.md's layout block names each of the package's folders as ``name/`` on the package's lines (a
    nested folder by its own name), as the package's own map does (test_every_package_and_concern_opens_with_a_map)."""
    layout = (SRC.parents[1] / "docs" / "design.md").read_text(encoding="utf-8").split("\n## Layout", 1)[1]
    block = layout.split("```", 2)[1]
    lines = block.splitlines()
    start = next(k for k, line in enumerate(lines) if line.startswith(f"{package}/"))
    end = next((k for k in range(start + 1, len(lines)) if lines[k][:1] not in ("", " ")), len(lines))
    ours = "\n".join(lines[start:end])
    unnamed_design = [f for f in _folders(package) if f"{f.split('/')[-1]}/" not in ours]
    assert unnamed_design == [], f"docs/design.md's layout does not name under {package}/: {unnamed_design}"


def test_no_merge_conflict_markers() -> None:
    """No file of the project holds a merge's conflict markers (they once sat inside a package map)."""
    root = SRC.parents[1]
    marked = []
    for path in [*root.glob("*.md"), *(root / "docs").rglob("*.md"), *root.glob("Makefile"), *SRC.rglob("*"),
                 *(root / "tests").rglob("*.py"), *(root / "bench").rglob("*.py"), *(root / "tools").rglob("*")]:
        if not path.is_file() or path.suffix in (".png", ".pyc", ".db3", ".mcap", ".hex", ".elf", ".o"):
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        if re.search(r"^(<{7} |>{7} |={7}$)", text, re.M):
            marked.append(str(path.relative_to(root)))
    assert marked == [], f"merge conflict markers in: {marked}"
