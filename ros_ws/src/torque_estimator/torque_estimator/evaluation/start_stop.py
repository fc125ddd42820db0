"""start_stop: the momentum observer on the only real transient data there is, the T-RO 2021 drive's start-stop runs.

    python -m torque_estimator.evaluation.start_stop      (make evaluate prints its lines after the real drive's)

The data: worm_model/data/tro2021/driveNo3/start_stop/{10,200}.csv (SOURCE.md: standstill, about
-10 (-200) rpm of the motor, stop, +10 (+200) rpm, stop; 500 rows 40 ms apart of EPOS-averaged
velocity and torque), a 0.096 kg mass on a 20 mm pulley throughout: 18.84 mN m on the gear,
lifted by + rotation (docs/real-data.md). No voltage, no angle: what the momentum observer is for.

Each file goes through the momentum observer as ``estimate`` runs it (LiveEstimator, the registry's
defaults, the rig file worm_model/data/tro2021_worm_rig.yaml: their geometry and fitted
frictions), fed the current and the speed only: the export has no position channel, and the
reader's angle (the velocity integrated) is no encoder.

Per move (the samples at more than half its top speed): the mean estimate and its error in % of
the load, the estimate at the move's end, the share of samples flagged AMBIGUOUS (the drive
self-locks at every speed: mu 0.12 > cos(phi_n) tan(lambda) = 0.047, so the load that asks for a
given torque has two candidates, one per flank), the measured motor torque over the move's second
half against the torque the rig file's model asks to move 18.84 mN m at that speed (a steady
estimate is the load that explains the measured torque: their difference through the load's
leverage on the torque is its error) and the steady-state export's torque at the same nominal
speed (docs/real-data.md's points), and the estimate held over the standstill that follows.

Each file is streamed twice through one estimator (PASSES): as recorded (the drive starts
lowering from an unknown load), then the same samples again, as if the run were repeated with the
estimator left running (the second lowering starts from the first lifting's estimate). The lines:

    start_stop: file=<f> pass=<1|2> move=<lifting|lowering> rpm=<x> mean_mNm=<x> error_pct=<x>
        end_mNm=<x> ambiguous_pct=<x> torque_mNm=<x> model_torque_mNm=<x> steady_torque_mNm=<x> held_mNm=<x>

(one line each). Loads on the gear shaft [mN m], + opposing + rotation; motor torques [mN m].
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser
from worm_model.physics.parameters import ParameterError, load_rig
from worm_model.rig_data.epos import EposSettings
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import RigDataError

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.observer.static_map import StaticLoadMap
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.evaluation.real_drive import LOAD, read_points, rig_file

#: the two exports, slow first
FILES = ("10.csv", "200.csv")
#: times each file is streamed through one estimator (module docstring)
PASSES = 2
#: a sample belongs to a move when its speed has the move's sign and is above this fraction of the move's top speed
MOVING = 0.5


def data_folder() -> Path:
    """worm_model's data/tro2021/driveNo3/start_stop (installed package data)."""
    import worm_model  # noqa: PLC0415 - only to find its data

    return Path(worm_model.__file__).resolve().parent / "data" / "tro2021" / "driveNo3" / "start_stop"


@dataclass(frozen=True)
class Move:
    """One move of one pass over one file (module docstring); torques [N m], speed [rpm of the motor]."""

    file: str
    passed: int  # 1: the file as recorded, 2: streamed again after it
    move: str  # "lifting" (+ rotation) or "lowering"
    rpm: float
    mean: float
    end: float
    ambiguous: float  # [1] share of the move's samples flagged AMBIGUOUS
    torque: float  # measured motor torque, mean over the move's second half
    model_torque: float  # the motor torque the model asks to move LOAD at the move's mean speed
    steady_torque: float  # the steady-state export's mean motor torque at the same nominal speed
    held: float  # the estimate at the end of the standstill that follows

    @property
    def error_pct(self) -> float:
        return 100.0 * (self.mean - LOAD) / LOAD

    def line(self) -> str:
        return (f"start_stop: file={self.file} pass={self.passed} move={self.move} rpm={self.rpm:.0f} "
                f"mean_mNm={1e3 * self.mean:.2f} error_pct={self.error_pct:.1f} end_mNm={1e3 * self.end:.2f} "
                f"ambiguous_pct={100 * self.ambiguous:.0f} torque_mNm={1e3 * self.torque:.3f} "
                f"model_torque_mNm={1e3 * self.model_torque:.3f} steady_torque_mNm={1e3 * self.steady_torque:.3f} "
                f"held_mNm={1e3 * self.held:.2f}")


def run_file(path: Path, steady: dict[int, float], rig_path: Path | None = None) -> list[Move]:
    """Stream one export PASSES times through one momentum observer (module docstring); the moves in time order.
    ``steady``: the steady-state exports' mean motor torque [N m] by nominal rpm (signed)."""
    rig_path = rig_path or rig_file()
    rig = load_rig(rig_path)
    built = build_estimator(EstimatorSettings("momentum", rig_file=str(rig_path)))
    data = read_rig_data(path, epos=EposSettings(load_torque=LOAD, nominal_current=rig.drive_motor.rated_current))
    live = built.live(data.sample_period)
    smap = StaticLoadMap(rig)
    motor = rig.drive_motor
    omega, current = data.omega_worm, data.current_drive
    n = len(data)
    moves = []
    for passed in range(1, PASSES + 1):
        torque, flags = np.empty(n), np.zeros(n, dtype=np.int64)
        for k in range(n):  # current and speed only: no voltage, no angle
            est = live.update(float(omega[k]), float(current[k]))
            torque[k], flags[k] = est.torque, est.flags
        for sign in (-1.0, 1.0):
            idx = np.flatnonzero(sign * omega > MOVING * float(np.max(sign * omega)))
            second = idx[len(idx) // 2:]
            speed = float(np.mean(omega[second]))
            rpm = float(np.mean(omega[idx])) * 30.0 / np.pi
            asked = float(smap.mesh(speed, LOAD)[0]) + motor.viscous_drag * speed
            after = np.arange(idx[-1] + 1, n)
            stopped = after[omega[after] == 0.0]
            moving_again = after[(after > stopped[0]) & (omega[after] != 0.0)] if stopped.size else after[:0]
            rest_end = (moving_again[0] - 1) if moving_again.size else n - 1
            nominal = int(sign * min(steady, key=lambda r: abs(abs(r) - abs(rpm))))
            moves.append(Move(path.name, passed, "lifting" if sign > 0 else "lowering", rpm,
                              float(np.mean(torque[idx])), float(torque[idx[-1]]),
                              float(np.mean(flags[idx] & int(EstimateFlags.AMBIGUOUS) > 0)),
                              float(np.mean(motor.torque_constant * current[second])), asked,
                              steady.get(nominal, float("nan")),
                              float(torque[rest_end]) if stopped.size else float("nan")))
    return sorted(moves, key=lambda m: (m.passed, m.move == "lifting"))  # each pass lowers first


def run(folder: Path | None = None) -> list[Move]:
    """Every move of both exports (FILES), slow file first."""
    folder = folder or data_folder()
    steady = {p.rpm: p.torque for p in read_points()[0]}
    return [m for name in FILES for m in run_file(folder / name, steady)]


def build_parser() -> argparse.ArgumentParser:
    return Parser(prog="start_stop", description=__doc__.split("\n\n")[0],
                  epilog="\n\n".join(__doc__.split("\n\n")[1:]), formatter_class=argparse.RawDescriptionHelpFormatter)


def main(argv: list[str] | None = None) -> int:
    def go() -> int:
        build_parser().parse_args(argv)
        print("\n".join(m.line() for m in run()))
        return 0

    return run_tool("start_stop", go, (ParameterError, RigDataError))


__all__ = ["FILES", "MOVING", "PASSES", "Move", "data_folder", "main", "run", "run_file"]


if __name__ == "__main__":
    raise SystemExit(main())
