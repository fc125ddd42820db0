"""Offered-QoS profiles made comparable, to warn when a bag's files and its metadata disagree.

rosbag2 stores them as YAML text, as policy numbers before Jazzy and as
policy names from Jazzy on; durations are left as stored. Used for warnings
only: the reader matches topics by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Final

from ruamel.yaml import YAML
from ruamel.yaml.error import YAMLError

__all__ = ['normalize_qos', 'qos_differs']

_POLICY_NAMES: Final[Mapping[str, Mapping[int, str]]] = {
    'history': {0: 'system_default', 1: 'keep_last', 2: 'keep_all', 3: 'unknown'},
    'reliability': {0: 'system_default', 1: 'reliable', 2: 'best_effort', 3: 'unknown',
                    4: 'best_available'},
    'durability': {0: 'system_default', 1: 'transient_local', 2: 'volatile', 3: 'unknown',
                   4: 'best_available'},
    'liveliness': {0: 'system_default', 1: 'automatic', 2: 'manual_by_node', 3: 'manual_by_topic',
                   4: 'unknown', 5: 'best_available'},
}


def normalize_qos(profiles: object) -> list[dict[str, Any]] | None:
    """Offered-QoS profiles (YAML text or parsed list) as comparable dicts; None if unparsable."""
    if isinstance(profiles, str):
        if not profiles.strip():
            return []
        try:
            profiles = YAML(typ='safe', pure=True).load(profiles)
        except YAMLError:
            return None
    if profiles is None:
        return []
    if not isinstance(profiles, list):
        return None
    out = []
    for profile in profiles:
        if not isinstance(profile, Mapping):
            return None
        item = dict(profile)
        for policy, names in _POLICY_NAMES.items():
            value = item.get(policy)
            if isinstance(value, int):
                item[policy] = names.get(value, str(value))
            elif isinstance(value, str):
                item[policy] = value.lower()
        out.append(item)
    return out


def qos_differs(a: object, b: object) -> bool:
    """Whether two offered-QoS texts describe different profiles (empty matches anything)."""
    qa, qb = normalize_qos(a), normalize_qos(b)
    if not qa or not qb:
        return False
    return qa != qb
