"""The held-out split: interleaved time blocks, a share held out and never fitted, guards at every edge."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worm_model.physics.parameters import Rig
from worm_model.residuals.model import Signals
from worm_model.residuals.settings import Settings


@dataclass
class Split:
    """Boolean masks over the samples; train and held_out never overlap."""

    train: np.ndarray
    held_out: np.ndarray
    block: np.ndarray  # block index per sample (global over runs)

    def __post_init__(self) -> None:
        assert not np.any(self.train & self.held_out)


def make_split(signals: Signals, settings: Settings, finite: np.ndarray | None = None, rig: Rig | None = None
               ) -> Split:
    """Interleaved block split: of consecutive blocks, a share ``holdout_fraction`` is held out.

    Block j (counted over all runs) is held out when floor((j + 1) f) > floor(j f): the
    held-out blocks are spread evenly over the record, so both sets see every part of
    the experiment (and slow drift).  Samples within ``guard_seconds`` of a block edge,
    slower than ``min_speed`` (None: the ``rig``'s own, Settings.for_rig), or not finite (``finite`` mask)
    are in neither set.

    Raises:
        ValueError: ``min_speed`` left to a rig and no rig given.
    """
    if settings.min_speed is None:
        if rig is None:
            raise ValueError("make_split: min_speed is the rig's (Settings.for_rig): give the rig")
        settings = settings.for_rig(rig)
    n = len(signals)
    block = np.zeros(n, dtype=int)
    edge_distance = np.zeros(n)
    offset = 0
    for r in np.unique(signals.run):
        idx = np.flatnonzero(signals.run == r)
        t = signals.t[idx] - signals.t[idx][0]
        local = np.floor(t / settings.block_seconds).astype(int)
        block[idx] = local + offset
        start = local * settings.block_seconds
        end = np.minimum(start + settings.block_seconds, t[-1])
        edge_distance[idx] = np.minimum(t - start, end - t)
        offset += int(local.max()) + 1
    f = settings.holdout_fraction
    held = np.floor((block + 1) * f) > np.floor(block * f)
    usable = (edge_distance >= settings.guard_seconds) & (np.abs(signals.omega) >= settings.min_speed)
    if finite is not None:
        usable &= finite
    return Split(train=usable & ~held, held_out=usable & held, block=block)


