"""offline.moves: a log cut into moves (one speed sign clear of standstill, a stop or a reversal between them),
each scored over its cruise, as `estimate` reports a start-stop run."""
from __future__ import annotations

import math

import numpy as np

from worm_model.rig_data.schema import MeasuredData

from torque_estimator.estimation.branches import STOP_SAMPLES
from torque_estimator.offline.moves import CRUISE, SETTLE, score_moves, segments

PERIOD = 0.04  # [s] an EPOS export's
STILL = 0.5  # [rad/s] the standstill band


def log(omega: np.ndarray, tau_load: float = 0.02) -> MeasuredData:
    n = len(omega)
    return MeasuredData(t=np.arange(n) * PERIOD, theta_worm=np.cumsum(omega) * PERIOD, omega_worm=omega,
                        current_drive=np.zeros(n), tau_load=np.full(n, tau_load))


def start_stop() -> np.ndarray:
    """1 s standing, 3 s at -10 rad/s, 1 s standing, 3 s at +10 rad/s, 1 s standing (ramps of 0.2 s)."""
    parts = [np.zeros(25), np.linspace(0, -10, 5), np.full(70, -10.0), np.linspace(-10, 0, 5), np.zeros(25),
             np.linspace(0, 10, 5), np.full(70, 10.0), np.linspace(10, 0, 5), np.zeros(25)]
    return np.concatenate(parts)


def test_a_start_stop_run_is_two_moves_lowering_then_lifting() -> None:
    omega = start_stop()
    data = log(omega)
    torque = np.where(omega < 0, 0.021, 0.019)
    moves = score_moves(data, torque, np.ones(len(omega), dtype=bool), STILL)
    assert [m.kind for m in moves] == ["lowering", "lifting"]  # + load: opposes + rotation, aids - rotation
    lowering, lifting = moves
    assert math.isclose(lowering.estimate, 0.021) and math.isclose(lifting.estimate, 0.019)
    assert math.isclose(lowering.error(), 0.001, abs_tol=1e-12) and lowering.trusted == 1.0
    # the cruise: above CRUISE of the top speed, past the move's first SETTLE seconds
    first = lowering.first
    assert data.t[lowering.cruise[0]] >= data.t[first] + SETTLE - 1e-9
    assert np.all(np.abs(omega[lowering.cruise]) > CRUISE * 10.0)


def test_the_trusted_share_and_the_worst_sample() -> None:
    omega = start_stop()
    torque = np.full(len(omega), 0.02)
    trusted = np.ones(len(omega), dtype=bool)
    torque[40] = 0.05  # one bad sample in the lowering cruise, untrusted
    trusted[40] = False
    torque[41] = 0.03  # and one trusted but off
    lowering = score_moves(log(omega), torque, trusted, STILL)[0]
    assert math.isclose(lowering.trusted, 1.0 - 1.0 / lowering.samples)
    assert math.isclose(lowering.worst, 0.01)


def test_a_noisy_sample_inside_the_band_does_not_end_a_move_but_a_stop_does() -> None:
    omega = start_stop()
    omega[50:50 + STOP_SAMPLES - 1] = 0.0  # shorter than a stop: one move still
    assert len(segments(omega, np.arange(len(omega)) * PERIOD, np.zeros(len(omega), dtype=int), STILL)) == 2
    omega[50:50 + STOP_SAMPLES + 2] = 0.0  # a stop (STOP_SAMPLES and STOP_TIME): two moves there
    assert len(segments(omega, np.arange(len(omega)) * PERIOD, np.zeros(len(omega), dtype=int), STILL)) == 3


def test_a_reversal_ends_a_move_and_a_jog_is_none() -> None:
    omega = np.concatenate([np.full(50, -5.0), np.full(50, 5.0), np.zeros(10), np.full(10, 5.0)])
    moves = score_moves(log(omega), np.zeros(len(omega)), np.ones(len(omega), dtype=bool), STILL)
    assert [m.direction for m in moves] == [-1, 1]  # the last 0.4 s jog is shorter than 2 x SETTLE: no move


def test_no_load_recorded_no_kind() -> None:
    data = log(start_stop())
    bare = MeasuredData(**{c: getattr(data, c) for c in data.names if c != "tau_load"},
                        tau_load=np.full(len(data), np.nan))
    moves = score_moves(bare, np.full(len(data), 0.02), np.ones(len(data), dtype=bool), STILL)
    assert len(moves) == 2 and all(m.kind == "" and math.isnan(m.load) for m in moves)
