"""Each package's errors in one module, and bad input keyed on one class.

Every exception class of the project is defined in its package's ``errors.py``; each is either a
worm_model.errors.InputError (bad input: a tool ends with one line and exit 2) or one of the few that are not
(the rig's bytes, the firmware harness, a live graph's state), and run_tool treats the two kinds apart with no
list of its own.
"""
from __future__ import annotations

import ast
import builtins
import importlib
import inspect
from pathlib import Path

import pytest

from worm_model.cli.errors import EXIT_BAD_INPUT, run_tool
from worm_model.errors import InputError

SRC = Path(__file__).resolve().parents[1] / "ros_ws" / "src"
PACKAGES = ("worm_model", "worm_rig_driver", "torque_estimator")
#: errors that are not the user's input: the rig's bytes, the firmware harness, a live graph's state, what is
#: installed
NOT_INPUT = {"CodecError", "CobsError", "FeedforwardUnavailable", "FilError", "LiveRigError", "RealDataMissing"}


def _errors() -> list[type[BaseException]]:
    out = []
    for package in PACKAGES:
        module = importlib.import_module(f"{package}.errors")
        out += [c for _n, c in inspect.getmembers(module, inspect.isclass)
                if issubclass(c, BaseException) and c.__module__ == module.__name__]
    return out


ERRORS = _errors()


def test_no_exception_class_outside_the_errors_modules() -> None:
    """A class deriving from a built-in exception or from one of the project's errors lives in errors.py (a private
    one, ``_Name``, is a module's own control flow and never leaves it)."""
    bases = {name for name in dir(builtins) if isinstance(getattr(builtins, name), type)
             and issubclass(getattr(builtins, name), BaseException)} | {c.__name__ for c in ERRORS}
    offenders = []
    for package in PACKAGES:
        for path in (SRC / package / package).rglob("*.py"):
            if path.name == "errors.py" and path.parent.name == package:
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.ClassDef) and not node.name.startswith("_") and any(
                        (b.id if isinstance(b, ast.Name) else b.attr if isinstance(b, ast.Attribute) else "") in bases
                        for b in node.bases):
                    offenders.append(f"{path.relative_to(SRC)}: {node.name}")
    assert offenders == [], offenders


def test_each_error_is_input_or_named_as_not() -> None:
    names = {c.__name__ for c in ERRORS}
    assert NOT_INPUT <= names
    assert len(names) == len(ERRORS), "one name, one class"
    assert {c.__name__ for c in ERRORS if not issubclass(c, InputError)} == NOT_INPUT


@pytest.mark.parametrize("error", ERRORS, ids=lambda c: c.__name__)
def test_run_tool_keys_exit_2_on_input_error_alone(error: type[BaseException], capsys) -> None:
    def main() -> int:
        err = error.__new__(error)
        Exception.__init__(err, "somewhere: something wrong")
        raise err

    code = run_tool("tool", main)
    err = capsys.readouterr().err
    if issubclass(error, InputError):
        assert (code, err) == (EXIT_BAD_INPUT, "tool: somewhere: something wrong\n")
    else:
        assert code == 1 and "internal error" in err


def test_input_error_with_and_without_a_place() -> None:
    assert str(InputError("--rig", "no such file")) == "--rig: no such file"
    assert InputError("--rig", "no such file").where == "--rig"
    whole = InputError("a.yaml: gearbox.ratio: must be > 0")
    assert (whole.where, whole.what, str(whole)) == ("", "a.yaml: gearbox.ratio: must be > 0",
                                                     "a.yaml: gearbox.ratio: must be > 0")


def _handled(node: ast.expr | None) -> list[str]:
    if isinstance(node, ast.Tuple):
        return [name for element in node.elts for name in _handled(element)]
    return [node.id] if isinstance(node, ast.Name) else [node.attr] if isinstance(node, ast.Attribute) else []


def test_no_handler_shadowed_by_a_base_before_it() -> None:
    """In a try, ``except InputError`` before ``except RigDataError`` would take the file's error with the wrong
    ``where``: a subclass's handler comes before its base's."""
    classes = {name: kind for name, kind in vars(builtins).items()
               if isinstance(kind, type) and issubclass(kind, BaseException)}
    classes.update({c.__name__: c for c in ERRORS})
    shadowed = []
    for path in [*SRC.rglob("*.py"), *SRC.parent.parent.joinpath("tests").rglob("*.py")]:
        if "install" in path.parts or "build" in path.parts:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Try):
                continue
            seen: list[str] = []
            for handler in node.handlers:
                names = [n for n in _handled(handler.type) if n in classes]
                shadowed += [f"{path.name}:{handler.lineno}: {n} after {s}" for n in names for s in seen
                             if classes[n] is not classes[s] and issubclass(classes[n], classes[s])]
                seen += names
    assert shadowed == [], shadowed
