"""Rig time of the two roads to an estimator: the paper's grid held live vs one identification run.

Prints:
  calibration_rig_time: <s> s        a live calibration of the 17 x 16 x 2 grid: per point, the rig time until its
                                     steady window is kept, summed (a live rig measures one point after the other;
                                     simulated rig, bundled parameters, no effects)
  identification_rig_time: <s> s     the default excitation of `identify` (every sample is used)
  identification_fit_time: <s> s     wall time of identify's fit of that record (simulated rig, every default effect on)
"""
from __future__ import annotations

import sys
import time

from worm_model.physics.parameters import load_rig

from torque_estimator.calibration.batch import CalibrationGrid
from torque_estimator.evaluation.identified import effects_all, live_grid_rig_time
from torque_estimator.identification.excitation import default_excitation, total_duration
from torque_estimator.identification.fit import identify
from torque_estimator.identification.simulated import record_on_simulator


def main() -> int:
    rig = load_rig()
    print("[identify_bench] live grid rig time (simulated, side by side)", file=sys.stderr, flush=True)
    print(f"calibration_rig_time: {live_grid_rig_time(rig, CalibrationGrid.paper(rig)):.0f} s", flush=True)
    timeline = default_excitation(rig)
    print(f"identification_rig_time: {total_duration(timeline):.1f} s", flush=True)
    data = record_on_simulator(rig, timeline, effects=effects_all(), seed=3)
    start = time.perf_counter()
    identify(data, None)
    print(f"identification_fit_time: {time.perf_counter() - start:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
