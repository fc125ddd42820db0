"""LiveModel, model_node's (and the replay's) per-sample core: forces, flags, filter state."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from worm_msgs.msg import GearboxForces, RigSample

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.internal_forces import internal_forces
from worm_model.live.live_model import FIELDS, ForceFlags, LiveForces, LiveModel
from worm_model.physics.modes import Flank, Mode
from worm_model.physics.motor import shaft_torque
from worm_model.physics.parameters import load_rig

RIG = load_rig()
PERIOD = 1.0 / RIG.sensors.sample_rate_hz


@dataclass
class Sample:
    """The three RigSample fields LiveModel reads (a plain stand-in for replaying arrays)."""

    omega_worm: float
    current_drive: float
    tau_load: float


def quasi_static_current(omega: float, tau_load: float) -> float:
    """Drive current [A] that holds omega [rad/s] against tau_load [N m]: Eq. 28 (a_w = 0) plus the motor's drags."""
    mu = friction_coefficient(RIG.friction, RIG.gearbox, omega)
    t_mesh = float(reflected_input_torque(RIG.gearbox, mu, gear_side_load(RIG, tau_load, omega), omega))
    m = RIG.drive_motor
    return (t_mesh + m.viscous_drag * omega + m.coulomb_drag * math.copysign(1.0, omega)) / m.torque_constant


def test_flags_and_fields_are_those_of_the_message() -> None:
    assert int(ForceFlags.INVALID_INPUT) == GearboxForces.FLAG_INVALID_INPUT
    assert int(ForceFlags.STANDSTILL) == GearboxForces.FLAG_STANDSTILL
    assert int(ForceFlags.MU_OUT_OF_BOUND) == GearboxForces.FLAG_MU_OUT_OF_BOUND
    message_fields = [f for f in GearboxForces.get_fields_and_field_types() if f not in ("header", "seq")]
    assert list(FIELDS) == message_fields
    # every value fits its message field (the node passes them straight through)
    forces = LiveModel(RIG).update(RigSample(omega_worm=100.0, current_drive=0.5, tau_load=0.1))
    GearboxForces(**forces.as_dict())


@pytest.mark.parametrize("sigma", [1.0, -1.0])
def test_steady_resistive_sample_recovers_the_declared_friction(sigma: float) -> None:
    """Constant speed against a load: finite forces, flags 0, and μ the rig's friction law gave the current."""
    omega, tau_load = sigma * 100.0, sigma * 0.2  # the load opposes the motion
    current = quasi_static_current(omega, tau_load)
    model = LiveModel(RIG)
    for _ in range(20):
        f = model.update(RigSample(omega_worm=omega, current_drive=current, tau_load=tau_load))
    assert isinstance(f, LiveForces)
    assert all(math.isfinite(getattr(f, name)) for name in FIELDS)
    assert f.flags == 0
    assert f.mode == Mode.RESISTIVE and f.flank == Flank.DRIVING
    assert f.normal_force > 0 and f.friction_force > 0
    assert f.mu == pytest.approx(float(friction_coefficient(RIG.friction, RIG.gearbox, omega)), rel=1e-9)
    assert f.mu_max == RIG.gearbox.mu_engagement_max
    assert f.tau_load == tau_load
    assert f.tau_in == pytest.approx(float(shaft_torque(RIG.drive_motor, current, omega)), rel=1e-12)


@pytest.mark.parametrize("bad", ["omega_worm", "current_drive", "tau_load"])
@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_non_finite_input_is_flagged_invalid_with_nan_forces(bad: str, value: float) -> None:
    model = LiveModel(RIG)
    good = dict(omega_worm=100.0, current_drive=quasi_static_current(100.0, 0.2), tau_load=0.2)
    assert model.update(Sample(**good)).flags == 0
    f = model.update(Sample(**{**good, bad: value}))
    assert f.flags == ForceFlags.INVALID_INPUT  # and neither STANDSTILL nor MU_OUT_OF_BOUND on top
    assert math.isnan(f.normal_force) and math.isnan(f.mu)
    assert model.update(Sample(**good)).flags == 0  # the next good sample is fine again


def test_worm_at_rest_is_flagged_standstill() -> None:
    f = LiveModel(RIG).update(Sample(0.0, 0.3, 0.1))
    assert f.flags == ForceFlags.STANDSTILL  # no frame of motion: the forces are only the statics


def test_implausible_current_is_flagged_mu_out_of_bound() -> None:
    """Far less current than the load needs: μ < 0, an artefact of the inputs, flagged."""
    f = LiveModel(RIG).update(Sample(100.0, 0.1 * quasi_static_current(100.0, 0.2), 0.2))
    assert math.isfinite(f.mu) and not 0.0 <= f.mu <= f.mu_max
    assert f.flags == ForceFlags.MU_OUT_OF_BOUND


def ramp(n: int, slope: float, current: float = 0.8, tau_load: float = 0.15) -> list[Sample]:
    return [Sample(50.0 + slope * k * PERIOD, current, tau_load) for k in range(n)]


def test_acceleration_filter_state_is_carried_from_sample_to_sample() -> None:
    """On a speed ramp the forces include the inertia at the ramp's acceleration, learnt over past samples."""
    slope, tau = 200.0, 0.01  # [rad/s^2], [s]
    samples = ramp(int(30 * tau / PERIOD), slope)
    model = LiveModel(RIG, use_acceleration=True, acceleration_filter=tau)
    history = [model.update(s) for s in samples]
    last = samples[-1]
    tau_in = float(shaft_torque(RIG.drive_motor, last.current_drive, last.omega_worm))
    expected = internal_forces(RIG.gearbox, tau_in, gear_side_load(RIG, last.tau_load, last.omega_worm),
                               last.omega_worm, slope, worm_inertia=RIG.total_worm_inertia,
                               gear_inertia=RIG.total_gear_inertia)
    assert history[-1].normal_force == pytest.approx(float(expected.normal_force), rel=1e-6)
    assert history[-1].mu == pytest.approx(float(expected.mu), rel=1e-6)
    # the same last sample without that history (fresh filter, or quasi-static) gives other forces
    fresh = LiveModel(RIG, acceleration_filter=tau).update(last)
    quasi_static = LiveModel(RIG, use_acceleration=False, acceleration_filter=tau)
    for s in samples[:-1]:
        quasi_static.update(s)
    for other in (fresh, quasi_static.update(last)):
        assert abs(other.normal_force - history[-1].normal_force) > 1e-3 * history[-1].normal_force
        assert other.normal_force == pytest.approx(fresh.normal_force, rel=1e-12)  # both a_w = 0


def test_a_nan_speed_leaves_the_filter_state_as_it_was() -> None:
    samples = ramp(200, 300.0)
    a, b = LiveModel(RIG), LiveModel(RIG)
    out_a = [a.update(s) for s in samples]
    out_b = []
    for k, s in enumerate(samples):
        if k == 120:
            assert b.update(Sample(math.nan, s.current_drive, s.tau_load)).flags == ForceFlags.INVALID_INPUT
        out_b.append(b.update(s))
    assert out_b == out_a  # bit for bit: the NaN sample was skipped, nothing reset


def test_rig_sample_message_and_plain_object_give_the_same_forces() -> None:
    values = np.random.default_rng(3).normal([80.0, 0.6, 0.1], [5.0, 0.05, 0.02], size=(50, 3))
    a, b = LiveModel(RIG), LiveModel(RIG)
    for omega, current, tau_load in values:
        msg = RigSample(omega_worm=float(omega), current_drive=float(current), tau_load=float(tau_load))
        assert a.update(msg) == b.update(Sample(float(omega), float(current), float(tau_load)))
