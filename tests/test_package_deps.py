"""Every ament_python package declares (as rosdep keys in package.xml) what its code imports, and nothing else.

The imports are read with ast from the sources (module level and inside
functions): package code against <exec_depend>, the package's test/ against
<exec_depend> + <test_depend>. A module with no rosdep key (PyPI-only) or one
left out on purpose (a cycle) must be named in a comment of that package.xml
instead. In the other direction every declared key must be imported somewhere
in the package, so a dependency dropped from the code does not linger.
"""
from __future__ import annotations

import ast
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "ros_ws" / "src"
PACKAGES = ("worm_model", "worm_rig_driver", "torque_estimator")
#: top-level module -> rosdep key (ROS packages: their own name), as on a stock ROS install
KEYS = {
    "numpy": "python3-numpy", "scipy": "python3-scipy", "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib", "tqdm": "python3-tqdm", "ruamel": "python3-ruamel.yaml",
    "rosbags": "python3-rosbags-pip", "serial": "python3-serial", "mcap_ros2": "mcap-ros2-support",
    "pytest": "python3-pytest",
    # PyPI-only, without a rosdep key: documented in a package.xml comment instead
    "mcap": None, "zstandard": None,
    **{name: name for name in ("rclpy", "rcl_interfaces", "std_msgs", "sensor_msgs", "diagnostic_msgs",
                               "builtin_interfaces", "ament_index_python", "geometry_msgs", *PACKAGES, "worm_msgs")},
}


def imported_modules(root: Path) -> dict[str, set[Path]]:
    """Top-level module names imported by the .py files under root -> the files importing them."""
    found: dict[str, set[Path]] = {}
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                found.setdefault(name.split(".")[0], set()).add(path)
    return found


#: modules of the test trees themselves (worm_model/test/fixtures, on sys.path through its conftest.py)
TEST_FIXTURES = ("fixtures",)


def third_party(found: dict[str, set[Path]], package: str) -> dict[str, set[Path]]:
    return {m: files for m, files in found.items()
            if m not in sys.stdlib_module_names and m not in ("__future__", "setuptools", package, *TEST_FIXTURES)}


def manifest(package: str) -> tuple[set[str], set[str], str]:
    """(exec keys, test keys, the text of all comments) of the package's package.xml."""
    path = SRC / package / "package.xml"
    root = ET.parse(path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))).getroot()
    deps = {tag: {e.text.strip() for e in root.iter(tag)} for tag in ("exec_depend", "depend", "test_depend")}
    comments = " ".join(e.text for e in root.iter() if e.tag is ET.Comment)
    return deps["exec_depend"] | deps["depend"], deps["test_depend"] | deps["depend"], comments


def key_of(module: str, where: set[Path]) -> str | None:
    assert module in KEYS, f"{module} (imported by {sorted(map(str, where))}) has no rosdep key in KEYS: add one"
    return KEYS[module]


@pytest.mark.parametrize("package", PACKAGES)
def test_every_import_is_declared(package: str) -> None:
    exec_keys, test_keys, comments = manifest(package)
    code = third_party(imported_modules(SRC / package / package), package)
    tests = third_party(imported_modules(SRC / package / "test"), package)
    for modules, allowed, kind in ((code, exec_keys, "exec_depend"), (tests, exec_keys | test_keys, "test_depend")):
        for module, where in sorted(modules.items()):
            key = key_of(module, where)
            if key in allowed:
                continue
            # not declared: acceptable only when the package.xml says why (no key, or a cycle)
            assert module in comments, (f"{package}/package.xml: {module} (imported by "
                                        f"{sorted(str(p.relative_to(SRC)) for p in where)}) needs <{kind}>{key}"
                                        f"</{kind}> or a comment saying why not")


@pytest.mark.parametrize("package", PACKAGES)
def test_every_declared_dependency_is_imported(package: str) -> None:
    exec_keys, test_keys, _comments = manifest(package)
    code = {key_of(m, f) for m, f in third_party(imported_modules(SRC / package / package), package).items()}
    tests = {key_of(m, f) for m, f in third_party(imported_modules(SRC / package / "test"), package).items()}
    assert exec_keys - code == set(), f"{package}/package.xml declares exec_depend the code never imports"
    assert test_keys - exec_keys - tests == set(), f"{package}/package.xml declares test_depend no test imports"


def test_both_distributions_pin_the_same_python_dependencies() -> None:
    """requirements-jazzy.lock differs from requirements.lock in ROS only (CI once ran Jazzy without
    hypothesis and failed collecting the property tests). Jazzy's rosidl adds pybind11."""
    root = SRC.parents[1]

    def pins(name: str) -> set[str]:
        lines = (root / name).read_text(encoding="utf-8").splitlines()
        return {line for line in lines if line and not line.startswith(("#", "ros-"))}

    kilted, jazzy = pins("requirements.lock"), pins("requirements-jazzy.lock")
    assert kilted - jazzy == set(), "pinned for Kilted only"
    assert jazzy - kilted <= {"pybind11==3.1.0"}, "pinned for Jazzy only"
