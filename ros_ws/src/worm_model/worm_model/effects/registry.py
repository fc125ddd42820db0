"""The registry of effects: each declared once, by name, and the faces that implement it.

A :class:`Declaration` is what every side agrees on: the name, a one-line summary and the parameters
(unit, default, range, meaning). A *face* is one side's implementation of a declared effect, found by
the side in its own view of the registry (:class:`Face`): the simulator's forward hooks
(``worm_rig_driver.sim.effects``, face ``"simulator"``) and the residual analysis's regressors
(``worm_model.residuals.effects``, face ``"residuals"``). A face knows nothing the declaration holds:
it reads the name's parameters, units and defaults from here.

Adding an effect is one call, :func:`register` (the declaration and its faces); the built-in effects are
declared in :mod:`worm_model.effects.vocabulary` and each side attaches its face with :func:`implement`
where it writes it. A view lists the effects in the order they were declared, so every side lists them
alike (the vocabulary's order: physics.md section 9, then the PWM, then the aging effects).
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from worm_model.effects.parameters import Parameter


@dataclass(frozen=True)
class Declaration:
    """One effect, as every side knows it: name, summary, parameters (each in its declared unit)."""

    name: str
    summary: str
    parameters: Mapping[str, Parameter] = field(default_factory=dict)

    def defaults(self) -> dict[str, float]:
        """Every parameter at its default, in its declared unit."""
        return {key: float(p.default) for key, p in self.parameters.items()}

    def default(self, key: str) -> float:
        """One parameter's default, in its declared unit."""
        return float(self.parameters[key].default)


_DECLARED: dict[str, Declaration] = {}
_FACES: dict[str, dict[str, Any]] = {}


def declare(declaration: Declaration) -> Declaration:
    """Add an effect to the vocabulary (its name must be new)."""
    if declaration.name in _DECLARED:
        raise ValueError(f"effect {declaration.name!r} is declared already")
    _DECLARED[declaration.name] = declaration
    return declaration


def implement(face: str, name: str, implementation: Any) -> Any:
    """Attach one side's implementation (``face``: "simulator", "residuals", ...) of the declared effect ``name``."""
    if name not in _DECLARED:
        raise ValueError(f"effect {name!r} is not declared (worm_model.effects.vocabulary)")
    _FACES.setdefault(face, {})[name] = implementation
    return implementation


def register(declaration: Declaration, **faces: Any) -> Declaration:
    """Declare an effect and attach its faces (face name -> implementation) in one call."""
    declare(declaration)
    for face, implementation in faces.items():
        implement(face, declaration.name, implementation)
    return declaration


def unregister(name: str) -> None:
    """Take a registered effect out again, with every face of it (a test's toy effect)."""
    _DECLARED.pop(name, None)
    for implementations in _FACES.values():
        implementations.pop(name, None)


class _View(Mapping[str, Any]):
    """A live, read-only view of the registry: what a side sees now, in the vocabulary's order."""

    def _get(self, name: str) -> Any:
        raise NotImplementedError

    def __getitem__(self, name: str) -> Any:
        found = self._get(name)
        if found is None:
            raise KeyError(name)
        return found

    def __iter__(self) -> Iterator[str]:
        return iter([name for name in list(_DECLARED) if self._get(name) is not None])

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({list(self)})"


class Vocabulary(_View):
    """name -> :class:`Declaration`, for every declared effect."""

    def _get(self, name: str) -> Declaration | None:
        return _DECLARED.get(name)


class Face(_View):
    """name -> one side's implementation, for every declared effect that side implements."""

    def __init__(self, face: str) -> None:
        self.face = face

    def _get(self, name: str) -> Any:
        return _FACES.get(self.face, {}).get(name) if name in _DECLARED else None


#: every declared effect: name -> Declaration
VOCABULARY = Vocabulary()

__all__ = ["VOCABULARY", "Declaration", "Face", "Vocabulary", "declare", "implement", "register", "unregister"]
