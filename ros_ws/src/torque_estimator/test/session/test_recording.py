"""The identification journal: a run stopped at any instant resumes with the segments it finished."""
from __future__ import annotations

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig

from torque_estimator.identification.excitation import default_excitation
from torque_estimator.session.recording import RESUME_GAP, ExcitationRun, Journal, journal_paths, run_settings
from torque_estimator.errors import JournalError

RIG = load_rig()
TIMELINE = default_excitation(RIG, 12.0)


def _feed(run: ExcitationRun, samples: int) -> None:
    for _ in range(samples):
        target = run.setpoints()
        if target is None:
            return
        run.add({"current_drive": 0.2, "omega_worm": target[0], "theta_worm": 1.0, "tau_load": target[1],
                 "voltage_drive": 3.0, "theta_gear": 0.03, "current_load": 0.1})


def test_interrupted_run_resumes_with_the_finished_segments(tmp_path) -> None:
    out = tmp_path / "rig.yaml"
    settings = run_settings(TIMELINE, {}, "live")
    run = ExcitationRun(TIMELINE, Journal.open(out, settings, resume=False), 1e-3)
    first_two = int(run.lengths[:2].sum())
    _feed(run, first_two + 5)  # two segments and part of the third
    assert run.journal.segments_done == 2
    with pytest.raises(JournalError, match="--resume"):
        Journal.open(out, settings, resume=False)
    with pytest.raises(JournalError, match=r"other settings: settings\.(\w+\.)*\w+ is .+ there, .+ now"):
        Journal.open(out, run_settings(default_excitation(RIG, 5.0), {}, "live"), resume=True)
    journal = Journal.open(out, settings, resume=True)  # "the process died": the half segment is dropped
    assert journal.segments_done == 2 and journal.rows == first_two and journal.resumed == 1
    run = ExcitationRun(TIMELINE, journal, 1e-3)
    assert run.setpoints() == pytest.approx(TIMELINE[2].at(0.0))
    _feed(run, 10**6)
    assert run.finished
    data = journal.data("test")
    assert len(data) == run.total_samples
    assert len(np.unique(data.run)) == 2  # the resumed part is a new run
    gap = np.max(np.diff(data.t))
    assert gap == pytest.approx(RESUME_GAP + 1e-3)
    journal.remove()
    assert not any(p.exists() for p in journal_paths(out))


def test_samples_with_a_nan_channel_are_skipped_but_count(tmp_path) -> None:
    run = ExcitationRun(TIMELINE, Journal(run_settings(TIMELINE, {}, "test")), 1e-3)
    run.add({"current_drive": float("nan"), "omega_worm": 1.0, "theta_worm": 0.0, "tau_load": 0.0})
    assert run.skipped_samples == 1 and run.samples_done == 1
