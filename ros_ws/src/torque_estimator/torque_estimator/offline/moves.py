"""The moves of a logged run, each scored: how ``estimate`` reads a start-stop run.

A *move* is a stretch of the log where the worm turns one way, clear of standstill
(worm_model.physics.resolution.standstill_speed, the rig's own speed noise): it ends where the
speed's sign changes or the worm stands for a stop (estimation.branches.STOP_TIME and STOP_SAMPLES,
as the estimators tell a stop from a sample of noise near zero). A move is scored over its *cruise*: its samples above
CRUISE of its top speed, past its first SETTLE seconds (the estimate finds the load, the speed
loop brings the worm up to speed). Per move: the mean trusted estimate (no flag: what the
standard outputs carry as a load) against the mean tau_load the log records over the same
samples, the trusted share of the cruise, and the largest error of one trusted estimate.

A move of a self-locking drive carrying a hanging load is *lifting* when the load opposes the
motion (sigma tau_load > 0, sigma the speed's sign: the driving flank) and *lowering* when it aids it.
Units SI; errors in % of a span the caller gives (estimate: the log's load range, or its one load).
No ROS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worm_model.rig_data.schema import MeasuredData

from torque_estimator.estimation.branches import STOP_SAMPLES, STOP_TIME

#: a move's cruise: its samples above this share of its top speed
CRUISE = 0.5
#: [s] left out at a move's start
SETTLE = 0.5
#: a move shorter than this many of SETTLE is no move to score (a reversal's pass, a jog)
MIN_LENGTH = 2.0


@dataclass(frozen=True)
class Move:
    """One scored move (module docstring); loads [N m], speed [rad/s], errors in % of ``span``."""

    first: int  # the move's first and last sample (indices into the log)
    last: int
    speed: float  # mean worm speed over the cruise
    estimate: float  # mean trusted estimate over the cruise (NaN: none trusted)
    load: float  # mean tau_load over the same samples (NaN: the log has none)
    trusted: float  # [1] share of the cruise's samples trusted
    worst: float  # [N m] the largest |estimate - tau_load| of one trusted sample
    cruise: np.ndarray  # the cruise's sample indices

    @property
    def samples(self) -> int:
        return len(self.cruise)

    @property
    def direction(self) -> int:
        return 1 if self.speed > 0 else -1

    @property
    def kind(self) -> str:
        """"lifting" when the load opposes the motion, "lowering" when it aids it, "" with no load recorded."""
        if not math.isfinite(self.load) or self.load == 0.0:
            return ""
        return "lifting" if self.direction * self.load > 0 else "lowering"

    def error(self) -> float:
        """[N m] mean trusted estimate - mean load."""
        return self.estimate - self.load

    def line(self, prog: str, number: int, t: np.ndarray, span: float) -> str:
        """One line of ``estimate``'s report."""
        pct = 100.0 * self.error() / span
        worst = 100.0 * self.worst / span
        what = f" ({self.kind})" if self.kind else ""
        return (f"{prog}: move {number}{what}: {t[self.first]:.2f}..{t[self.last]:.2f} s at {self.speed:+.4g} rad/s, "
                f"load {self.load:+.5g} N m, mean trusted estimate {self.estimate:+.5g} N m ({pct:+.2f} %), "
                f"trusted {100.0 * self.trusted:.0f} %, worst {worst:.1f} %")


def segments(omega: np.ndarray, t: np.ndarray, run: np.ndarray, standstill: float) -> list[tuple[int, int]]:
    """(first, last) sample indices of each move (module docstring): one speed sign clear of ``standstill`` [rad/s],
    within one run; a standstill shorter than a stop inside it does not end it."""
    sign = np.where(omega > standstill, 1, np.where(omega < -standstill, -1, 0))
    sign = np.where(np.isfinite(omega), sign, 0)
    moving = np.flatnonzero(sign)
    out: list[tuple[int, int]] = []
    for k in moving.tolist():
        if out:
            first, last = out[-1]
            gap = k - last - 1
            if (sign[k] == sign[first] and run[k] == run[first]
                    and (gap < STOP_SAMPLES or t[k] - t[last] < STOP_TIME)):
                out[-1] = (first, k)
                continue
        out.append((k, k))
    return out


def score_moves(data: MeasuredData, torque: np.ndarray, trusted: np.ndarray, standstill: float) -> list[Move]:
    """The log's moves (module docstring), each lasting MIN_LENGTH x SETTLE, scored; ``torque`` [N m] the estimate
    per sample, ``trusted`` its no-flag mask, ``standstill`` [rad/s] the rig's (resolution.standstill_speed)."""
    reference = data.tau_load if data.tau_load is not None else np.full(len(data), np.nan)
    out = []
    for first, last in segments(data.omega_worm, data.t, data.run, standstill):
        if data.t[last] - data.t[first] < MIN_LENGTH * SETTLE:
            continue
        span = np.arange(first, last + 1)
        speed = np.abs(data.omega_worm[span])
        cruise = span[(speed > CRUISE * float(np.max(speed))) & (data.t[span] >= data.t[first] + SETTLE)]
        if len(cruise) == 0:
            continue
        ok = cruise[trusted[cruise] & np.isfinite(torque[cruise])]
        load = float(np.mean(reference[cruise])) if np.isfinite(reference[cruise]).all() else math.nan
        estimate = float(np.mean(torque[ok])) if len(ok) else math.nan
        worst = float(np.max(np.abs(torque[ok] - reference[ok]))) if len(ok) and math.isfinite(load) else math.nan
        out.append(Move(first, last, float(np.mean(data.omega_worm[cruise])), estimate, load,
                        len(ok) / len(cruise), worst, cruise))
    return out


__all__ = ["CRUISE", "MIN_LENGTH", "Move", "SETTLE", "score_moves", "segments"]
