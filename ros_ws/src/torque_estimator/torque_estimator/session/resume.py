"""The resume rule of every resumable journal (a calibration's points, an excitation's samples).

A run stopped part-way leaves its journal. Started again, it continues that journal only when the user asks for it
(``--resume``: otherwise the journal would be overwritten) and only when the run's settings are the journal's
(otherwise the points would mix two experiments); the refusal names the first setting that differs and both its
values, so the user can repeat the interrupted command's options or delete the journal. Settings compare as JSON
gives them back (tuples as lists, numpy as Python numbers).
"""
from __future__ import annotations

import json
from typing import Any

import numpy as np


def normalised(value: Any) -> Any:
    """The value as JSON gives it back (tuples -> lists, numpy -> Python), for comparing settings."""
    return json.loads(json.dumps(value, default=_json_default))


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


def first_difference(old: Any, new: Any, where: str = "settings") -> str | None:
    """Dotted path of the first place two JSON values differ (keys in sorted order), None if equal."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in sorted(set(old) | set(new)):
            if key not in old or key not in new:
                return f"{where}.{key}"
            found = first_difference(old[key], new[key], f"{where}.{key}")
            if found:
                return found
        return None
    return None if old == new else where


def lookup(doc: Any, dotted: str) -> Any:
    """The value at a dotted path of first_difference ("(absent)" where a key is missing)."""
    for key in dotted.split(".")[1:]:
        doc = doc.get(key, "(absent)") if isinstance(doc, dict) else "(absent)"
    return doc


def settings_problem(stored: Any, wanted: Any) -> str | None:
    """Why a journal taken with ``stored`` settings may not be continued with ``wanted`` ones (both as
    :func:`normalised` gives them), None if it may: the first differing setting and its two values."""
    differs = first_difference(stored, wanted)
    if differs is None:
        return None
    return f"{differs} is {lookup(stored, differs)!r} there, {lookup(wanted, differs)!r} now"


__all__ = ["first_difference", "lookup", "normalised", "settings_problem"]
