"""Calibration runs: steady-state detection, the journal, resuming, the point-by-point (live) core."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.simulated_rig import SimulatedRig
from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.database import POINT_COLUMNS, load_database, save_database
from torque_estimator.calibration.journal import CalibrationJournal, default_journal_path
from torque_estimator.errors import JournalError
from torque_estimator.calibration.live import PointByPoint, live_settings
from torque_estimator.calibration.operating_points import SteadyStateCriterion, SteadyStateDetector
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController

RIG = load_rig()
PERIOD = 1.0 / RIG.sensors.sample_rate_hz
CRITERION = SteadyStateCriterion(window=0.2, settle_time=0.3, timeout=2.0)  # short: fast tests
GRID = CalibrationGrid.paper(RIG, n_speeds=2, n_torques=3, speed_min=60.0, speed_max=240.0)  # 4 x 3 points


def _assert_same_points(a, b) -> None:
    for name in POINT_COLUMNS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    np.testing.assert_array_equal(a.speed_setpoints, b.speed_setpoints)
    np.testing.assert_array_equal(a.torque_setpoints, b.torque_setpoints)
    assert a.steady_state == b.steady_state and a.rig == b.rig


def _assert_spreads_kept(db, criterion: SteadyStateCriterion) -> None:
    for name in ("omega_std", "current_std", "tau_std"):
        spread = getattr(db, name)
        assert np.all(np.isfinite(spread)) and np.all(spread > 0), name
    np.testing.assert_array_equal(db.samples, round(criterion.window / PERIOD))


# --- the steady-state detector ----------------------------------------------------------------------

def test_detector_keeps_the_first_steady_window_and_its_spread() -> None:
    rng = np.random.default_rng(3)
    window = round(CRITERION.window / PERIOD)
    first_check = round(CRITERION.settle_time / PERIOD) + window
    detector = SteadyStateDetector(CRITERION, PERIOD, [100.0, -50.0])
    stream = []
    while not detector.finished:
        sample = (np.array([100.0, -50.0]) + rng.normal(0, 0.5, 2), 1.0 + rng.normal(0, 0.02, 2),
                  np.array([0.1, -0.1]) + rng.normal(0, 0.003, 2))
        stream.append(sample)
        detector.add(*sample)
    # steady from the start: done at the first multiple of the window after settle + window
    first = int(np.ceil(first_check / window) * window)
    assert detector.count == first and detector.settled.all()
    last = np.array([np.stack(channel) for channel in zip(*stream[-window:])])  # (3, window, 2)
    result = detector.result([0.1, -0.1])
    np.testing.assert_allclose(result.omega_worm, last[0].mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(result.current_std, last[1].std(axis=0), rtol=1e-12)
    np.testing.assert_allclose(result.tau_load, last[2].mean(axis=0), rtol=1e-12)
    np.testing.assert_array_equal(result.samples, window)


def test_detector_gives_up_at_the_timeout_with_the_last_window() -> None:
    detector = SteadyStateDetector(CRITERION, PERIOD, [100.0, 100.0])
    k = 0
    while not detector.finished:
        k += 1
        # point 0 steady; point 1's current keeps drifting (1 A/s: 0.1 A between the window's halves)
        detector.add(np.array([100.0, 100.0]), np.array([1.0, 1.0 + k * PERIOD]), np.zeros(2))
    # point 0 settled at the first check, so the run went on to the timeout for point 1 only
    assert detector.count == round(CRITERION.timeout / PERIOD)
    np.testing.assert_array_equal(detector.settled, [True, False])
    result = detector.result([0.0, 0.0])
    window = round(CRITERION.window / PERIOD)
    expected = 1.0 + PERIOD * np.arange(k - window + 1, k + 1)
    assert result.current_drive[1] == pytest.approx(expected.mean(), rel=1e-12)
    with pytest.raises(RuntimeError):
        detector.add(np.zeros(2), np.zeros(2), np.zeros(2))


def test_detector_with_a_timeout_before_the_first_window_still_takes_one() -> None:
    short = replace(CRITERION, timeout=0.1)  # shorter than settle_time + window
    detector = SteadyStateDetector(short, PERIOD, [100.0])
    while not detector.finished:
        detector.add(np.array([10.0]), np.array([1.0]), np.array([0.0]))  # far from the set-point
    assert not detector.settled[0] and detector.result([0.0]).omega_worm[0] == 10.0


# --- batch path: resume after an interruption -------------------------------------------------------

def _interrupt_at(fraction: float):
    """A progress callback that raises KeyboardInterrupt (what Ctrl-C raises) once more than
    `fraction` of the points is done: in the middle of the batch after the one that reached it."""
    def progress(done: float) -> None:
        if done > fraction:
            raise KeyboardInterrupt
    return progress


def test_interrupted_batch_calibration_resumes_to_the_same_points(tmp_path: Path) -> None:
    reference = calibrate_simulated(RIG, GRID, seed=5, criterion=CRITERION, batch_size=3)
    _assert_spreads_kept(reference, CRITERION)
    assert not reference.steady_state["unsettled_points"]

    journal = tmp_path / "cal.json.partial"
    with pytest.raises(KeyboardInterrupt):  # Ctrl-C in the third batch of four
        calibrate_simulated(RIG, GRID, seed=5, criterion=CRITERION, batch_size=3, journal=journal,
                            progress=_interrupt_at(0.5))
    partial = CalibrationJournal.load(journal, 12)
    assert sorted(partial.points) == list(range(6))

    measured: list[float] = []
    resumed = calibrate_simulated(RIG, GRID, seed=5, criterion=CRITERION, batch_size=3, journal=journal,
                                  resume=True, progress=measured.append)
    assert measured[0] >= 0.5  # the first two batches were not measured again
    _assert_same_points(resumed, reference)
    assert "resumed 1 time(s)" in resumed.notes
    save_database(resumed, tmp_path / "cal.json")
    _assert_same_points(load_database(tmp_path / "cal.json"), reference)


def test_a_journal_is_neither_overwritten_nor_resumed_under_other_settings(tmp_path: Path) -> None:
    journal = tmp_path / "cal.json.partial"
    with pytest.raises(KeyboardInterrupt):
        calibrate_simulated(RIG, GRID, seed=5, criterion=CRITERION, batch_size=3, journal=journal,
                            progress=_interrupt_at(0.25))
    with pytest.raises(JournalError, match="--resume"):
        calibrate_simulated(RIG, GRID, seed=5, criterion=CRITERION, batch_size=3, journal=journal)
    with pytest.raises(JournalError, match=r"settings\.seed is 5 there, 6 now"):
        calibrate_simulated(RIG, GRID, seed=6, criterion=CRITERION, batch_size=3, journal=journal, resume=True)
    other_grid = CalibrationGrid.paper(RIG, n_speeds=2, n_torques=3, speed_min=60.0, speed_max=250.0)
    with pytest.raises(JournalError, match=r"settings\.grid\.speed_setpoints"):
        calibrate_simulated(RIG, other_grid, seed=5, criterion=CRITERION, batch_size=3, journal=journal,
                            resume=True)
    doc = json.loads(journal.read_text())
    doc["points"]["plan_index"][0] = 99
    journal.write_text(json.dumps(doc))
    with pytest.raises(JournalError, match=r"points\.plan_index.*row 0: 99"):
        CalibrationJournal.load(journal, 12)


_CALIBRATE_ARGS = ["--quiet", "--speeds", "2", "--torques", "3", "--speed-min", "60", "--speed-max", "240",
                   "--window", "0.2", "--settle-time", "0.3", "--timeout", "2", "--seed", "5", "--batch-size", "1"]

# The calibrate CLI, whose journal stops growing at HOLD_AT points until a signal ends the process: the run
# waits for the test's interruption, so an idle machine cannot finish the 12 points before it arrives.
_HELD_CALIBRATE = """
import sys, time
from pathlib import Path
import torque_estimator.calibration.calibrate as cli
from torque_estimator.calibration.journal import CalibrationJournal
hold_at, journal, argv = int(sys.argv[1]), Path(sys.argv[2]), sys.argv[3:]
simulate = cli.calibrate_simulated
def held(*args, progress=None, **kwargs):
    def report(fraction):
        if progress is not None:
            progress(fraction)
        if journal.exists() and len(CalibrationJournal.load(journal, 12).points) >= hold_at:
            while True:
                time.sleep(0.05)
    return simulate(*args, progress=report, **kwargs)
cli.calibrate_simulated = held
sys.exit(cli.main(argv))
"""


def _calibrate_cli(out: Path, *extra: str, hold_at: int | None = None) -> list[str]:
    """The command line of calibrate; with ``hold_at`` it waits for a signal once its journal holds that many."""
    args = ["--out", str(out), *_CALIBRATE_ARGS, *extra]
    if hold_at is None:
        return [sys.executable, "-m", "torque_estimator.calibration.calibrate", *args]
    return [sys.executable, "-c", _HELD_CALIBRATE, str(hold_at), str(default_journal_path(out)), *args]


def _wait_for_points(journal: Path, more_than: int, proc: subprocess.Popen, timeout: float = 60.0) -> int:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            count = len(json.loads(journal.read_text())["points"]["plan_index"])
        except (OSError, ValueError):
            count = 0
        if count > more_than:
            return count
        assert proc.poll() is None, f"calibrate exited early ({proc.returncode})"
        time.sleep(0.01)
    raise AssertionError(f"journal {journal} did not grow beyond {more_than} points")


def test_cli_interrupted_by_ctrl_c_and_killed_resumes_to_the_uninterrupted_database(tmp_path: Path) -> None:
    out = tmp_path / "cal.json"
    journal = default_journal_path(out)
    env = dict(os.environ)

    # Ctrl-C: exit 130, the journal kept, the way forward printed
    proc = subprocess.Popen(_calibrate_cli(out, hold_at=3), env=env, stderr=subprocess.PIPE, text=True)
    _wait_for_points(journal, 0, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "--resume" in err and not out.exists()
    after_ctrl_c = CalibrationJournal.load(journal, 12).points
    assert 0 < len(after_ctrl_c) < 12

    # resumed, then SIGKILLed (no clean-up at all): the journal still holds whole points
    proc = subprocess.Popen(_calibrate_cli(out, "--resume", hold_at=len(after_ctrl_c) + 3), env=env,
                            stderr=subprocess.PIPE, text=True)
    _wait_for_points(journal, len(after_ctrl_c), proc)
    proc.kill()
    proc.communicate(timeout=30)
    after_kill = CalibrationJournal.load(journal, 12).points
    assert len(after_ctrl_c) < len(after_kill) < 12
    assert all(after_kill[i] == p for i, p in after_ctrl_c.items())  # kept, not measured again

    done = subprocess.run(_calibrate_cli(out, "--resume"), env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert out.exists() and not journal.exists()
    db = load_database(out)
    assert "resumed 2 time(s)" in db.notes
    reference = calibrate_simulated(RIG, GRID, seed=5, criterion=CRITERION, batch_size=1)
    _assert_same_points(db, reference)
    _assert_spreads_kept(db, CRITERION)


# --- the live path's core, fed by an in-process simulated rig ---------------------------------------

def _drive(run: PointByPoint, sim: SimulatedRig, nan_every: int = 0, stop_after: int | None = None) -> int:
    """What calibration_node does over DDS, in-process: command each point, then feed samples."""
    controller = SpeedController(RIG, DEFAULT_GAINS)
    finished = 0
    k = 0
    while (point := run.current) is not None and finished != stop_after:
        sim.command(load_torque=point.torque)
        run.start()
        while run.current == point:
            m = sim.sample()
            k += 1
            omega = np.nan if nan_every and k % nan_every == 0 else float(m.omega_worm[0])
            finished += run.add(omega, float(m.current_drive[0]), float(m.tau_load[0]))
            sim.command(voltage_drive=controller.update(PERIOD, point.speed, m.omega_worm).voltage)
    return finished


def test_point_by_point_measures_the_grid_like_the_batch_path_and_resumes(tmp_path: Path) -> None:
    journal_path = tmp_path / "live.json.partial"
    settings = live_settings(GRID, RIG, CRITERION)
    sim = SimulatedRig(RIG, n=1, seed=11)
    run = PointByPoint(GRID, CalibrationJournal.open(journal_path, settings, 12, resume=False), CRITERION, PERIOD)
    assert _drive(run, sim, nan_every=97, stop_after=5) == 5
    assert run.skipped_samples > 0  # NaN samples are skipped, not averaged
    assert sorted(CalibrationJournal.load(journal_path, 12).points) == list(range(5))

    # a new process would start from the journal: only the 7 missing points are measured
    journal = CalibrationJournal.open(journal_path, settings, 12, resume=True)
    run = PointByPoint(GRID, journal, CRITERION, PERIOD)
    assert run.current.plan_index == 5
    assert _drive(run, sim) == 7
    db = run.database(RIG)

    speeds, torques, index = GRID.points()
    np.testing.assert_array_equal(db.setpoint_index, index)
    assert not db.steady_state["unsettled_points"]
    _assert_spreads_kept(db, CRITERION)
    allowed = CRITERION.speed_tolerance * np.abs(speeds) + CRITERION.speed_floor
    assert np.all(np.abs(db.omega_worm - speeds) <= allowed)
    # the same map as the batch path: currents and torques agree within the points' noise
    batch = calibrate_simulated(RIG, GRID, seed=5, criterion=CRITERION)
    for name, spread in (("current_drive", "current_std"), ("tau_load", "tau_std")):
        error = np.abs(getattr(db, name) - getattr(batch, name))
        noise = np.hypot(getattr(db, spread), getattr(batch, spread)) / np.sqrt(db.samples)
        assert np.all(error < 8 * noise), f"{name}: {error / noise}"
    np.testing.assert_allclose(db.tau_load, torques, atol=5 * float(np.max(db.tau_std)) / np.sqrt(200))
