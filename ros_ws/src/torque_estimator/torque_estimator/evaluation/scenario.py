"""Scripted experiments: a timeline of worm-speed set-points and load torques (no ROS)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Segment:
    """Hold a worm speed [rad/s] against a load torque [N m] (positive opposing + rotation) for duration [s]."""

    duration: float
    speed: float
    load: float
    label: str


#: Load steps into all three modes, both directions (the rig's tau_sw is ~0.008 N m, see gear_side).
DEMO_SCENARIO = (
    Segment(2.0, 150.0, 0.0, "no load"),
    Segment(2.0, 150.0, 0.20, "resistive"),
    Segment(2.0, 150.0, -0.004, "pseudo-resistive"),
    Segment(2.0, 150.0, -0.20, "assistive"),
    Segment(2.0, -150.0, -0.20, "reverse, resistive"),
    Segment(2.0, -150.0, 0.20, "reverse, assistive"),
)


def segment_starts(scenario) -> np.ndarray:
    """Start time [s] of each segment from the scenario's start."""
    return np.concatenate(([0.0], np.cumsum([s.duration for s in scenario])[:-1]))


def segment_at(scenario, t: float) -> int | None:
    """Index of the segment running at time t [s], None after the end."""
    starts = segment_starts(scenario)
    if t >= starts[-1] + scenario[-1].duration:
        return None
    return int(np.searchsorted(starts, t, side="right") - 1)
