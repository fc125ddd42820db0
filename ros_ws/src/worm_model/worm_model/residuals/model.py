"""The drive current the model predicts: the declared model (Eqs 28-30) plus effect channels.

Sign conventions (fixed frame, physics.md section 2): omega_worm [rad/s] and alpha_worm
[rad/s^2] + along the reference rotation; tau_load [N m] on the gear shaft, + opposes +
rotation; current [A] + drives + rotation.

Declared model (quasi-static Eq. 28 with its inertia term, and Eq. 30's motor side), in
the frame of motion sigma = sign(omega_worm):

    G   = sigma (tau_load + gear-side drag + tau_gear) + J_g i sigma alpha     mesh demand on the gear side
    s   = sign(G)  (+1 at 0)                                                   engaged flank
    T   = J_w sigma alpha + (r_w / r_g) K_s(mu, s) G                           Eq. 28 solved for T
    K_t i_true = b omega + c(omega) sigma + sigma T + tau_worm                 Eq. 30, drags of the drive motor
    i_measured = (1 + g) i_true + i_offset

with J_w, J_g the shafts' total inertias (rig.total_worm_inertia/total_gear_inertia) plus
the ``worm_inertia``/``gear_inertia`` channels, mu = mu_declared(omega) (1 + mu_relative) +
mu_add with mu_declared from friction.friction_coefficient, and gear-side drag the load
motors' declared drag (gear_side.gear_side_drag).

The *channels* ``mu`` (mu_add), ``mu_relative``, ``worm_torque`` (tau_worm, + opposes +
rotation), ``gear_torque`` (tau_gear, + opposes + rotation), ``worm_inertia``,
``gear_inertia``, ``current_gain`` (g) and ``current`` (i_offset) are zero in the declared
model; effects (worm_model.residuals.effects) add to them.  The
model is evaluated exactly (nonlinear in mu); :func:`sensitivities` gives the derivative
of the measured current with respect to each channel, which turns an effect's channel
shapes into its regressors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worm_model.physics.efficiency import flank_factor
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import gear_side_drag
from worm_model.physics.motor import coulomb_magnitude
from worm_model.physics.parameters import Rig
from worm_model.rig_data.schema import MeasuredData
from worm_model.physics.units import FloatArray

#: the channels an effect can add to: name -> unit
CHANNELS: dict[str, str] = {
    "mu": "1",
    "mu_relative": "1",
    "worm_torque": "N m",
    "gear_torque": "N m",
    "worm_inertia": "kg m^2",
    "gear_inertia": "kg m^2",
    "current_gain": "1",
    "current": "A",
}

#: default time constant [s] of the zero-phase low-pass used for the acceleration
ALPHA_TIME_CONSTANT = 0.005
#: default oil temperature [degC] at which the rig file's mu holds (a lab at 25 degC, the simulator's ambient)
REFERENCE_TEMPERATURE = 25.0


@dataclass
class Signals:
    """What the model needs per sample, SI units, arrays of shape (n,).

    theta_gear is worm-referenced (+ with + worm rotation); when the data has no gear
    encoder it is ratio * theta_worm.  temperature is None when not measured.
    transmission_error [rad at the gear] = ratio * theta_worm - theta_gear, the gear lagging
    the rigid-mesh position; None without a gear encoder, NaN where theta_gear is missing.
    reference_temperature [degC] is the oil temperature at which the declared model's mu holds.
    """

    t: FloatArray
    omega: FloatArray
    alpha: FloatArray
    theta_worm: FloatArray
    theta_gear: FloatArray
    tau_load: FloatArray
    run: np.ndarray
    temperature: FloatArray | None = None
    alpha_time_constant: float = ALPHA_TIME_CONSTANT  # [s] of the filter that made alpha
    transmission_error: FloatArray | None = None
    reference_temperature: float = REFERENCE_TEMPERATURE

    def __len__(self) -> int:
        return len(self.t)

    @property
    def sample_period(self) -> float:
        """Median sample period [s]."""
        return float(np.median(np.diff(self.t))) if len(self.t) > 1 else 1e-3

    def subset(self, index: np.ndarray) -> "Signals":
        return Signals(**{k: (v if v is None or np.ndim(v) == 0 else np.asarray(v)[index])
                          for k, v in vars(self).items()})


def zero_phase_derivative(t: FloatArray, x: FloatArray, run: np.ndarray,
                          time_constant: float = ALPHA_TIME_CONSTANT) -> FloatArray:
    """Low-passed derivative of x [unit/s], zero phase, restarted at every run.

    The offline counterpart of filters.FilteredDerivative: the same first-order low-pass
    (time constant [s]) before and after a central difference, but each run forward and
    backward (scipy filtfilt), so the derivative is not delayed against the current.
    """
    # imported at first use: scipy.signal takes ~0.4 s to import, paid at start by every executable
    from scipy.signal import filtfilt

    out = np.zeros(len(x))
    for r in np.unique(run):
        idx = np.flatnonzero(run == r)
        tr, xr = t[idx], x[idx]
        if len(idx) < 3:
            continue
        period = float(np.median(np.diff(tr)))
        blend = 1.0 if time_constant <= 0 else 1.0 - np.exp(-period / time_constant)
        b, a = [blend], [1.0, blend - 1.0]
        padlen = min(len(idx) - 1, int(10 * max(time_constant, period) / period))
        smooth = filtfilt(b, a, xr, padlen=padlen) if blend < 1.0 else xr
        d = np.gradient(smooth, tr)
        out[idx] = filtfilt(b, a, d, padlen=padlen) if blend < 1.0 else d
    return out


def prepare_signals(rig: Rig, data: MeasuredData, alpha_time_constant: float = ALPHA_TIME_CONSTANT,
                    reference_temperature: float = REFERENCE_TEMPERATURE) -> Signals:
    """Signals of a data set: acceleration from a zero-phase filtered derivative of omega_worm.

    With a gear encoder (``theta_gear``) the transmission error ratio * theta_worm - theta_gear
    [rad at the gear] is a second fitted signal (NaN where theta_gear is missing).
    """
    rigid = rig.gearbox.ratio * data.theta_worm
    measured = data.theta_gear
    theta_gear = measured if measured is not None else rigid
    if np.any(~np.isfinite(theta_gear)):  # optional column with holes: fall back to the worm encoder
        theta_gear = np.where(np.isfinite(theta_gear), theta_gear, rigid)
    return Signals(
        t=data.t, omega=data.omega_worm,
        alpha=zero_phase_derivative(data.t, data.omega_worm, data.run, alpha_time_constant),
        theta_worm=data.theta_worm, theta_gear=theta_gear, tau_load=data.tau_load, run=data.run,
        temperature=data.temperature, alpha_time_constant=alpha_time_constant,
        transmission_error=None if measured is None else rigid - measured,
        reference_temperature=float(reference_temperature),
    )


def ripple_response(rig: Rig, frequency: FloatArray, period: float,
                    alpha_time_constant: float = ALPHA_TIME_CONSTANT) -> np.ndarray:
    """How much of a torque ripple at the worm shaft the quasi-static residual shows (complex, 1 at DC).

    A torque x sin(Omega t) on the worm shaft of a voltage-driven PMDC motor (Eq. 29 with V
    held, rigid shaft of inertia J) moves the current by di = K_e x / ((L s + R) J s + K_t K_e)
    and the speed by dw = -x / (J s + K_t K_e / (L s + R)), s = j Omega.  The model removes
    J alpha / K_t with alpha taken from the *sampled* speed through the zero-phase filters
    of :func:`zero_phase_derivative` (|H_lp|^4 and a central difference j sin(Omega T)/T,
    both periodic in Omega, so a ripple above the Nyquist rate aliases as it does in the
    data).  The residual is then K_t di - J F dw per unit x: returned here, so that a
    ripple shape multiplied by it is the torque the quasi-static model sees.  Well below
    the electromechanical corner K_t K_e / (R J) it is 1; far above it the inertia absorbs
    the ripple and it tends to 0 (the current does not carry it).  Also a fair model under
    speed control slower than the ripple (the controller does not see it).

    Args:
        frequency: Omega [rad/s], signed (the ripple's order times the shaft speed).
        period: sample period T [s].
    """
    m = rig.drive_motor
    J = rig.total_worm_inertia
    s = 1j * np.asarray(frequency, dtype=float)
    Z = s * m.inductance + m.resistance
    dw = -1.0 / (s * J + m.torque_constant * m.back_emf_constant / Z)
    di = -m.back_emf_constant * dw / Z
    blend = 1.0 if alpha_time_constant <= 0 else 1.0 - np.exp(-period / alpha_time_constant)
    z = np.exp(1j * np.asarray(frequency, dtype=float) * period)
    lp = blend / (1.0 - (1.0 - blend) / z)
    seen = np.abs(lp) ** 4 * 1j * np.sin(np.asarray(frequency, dtype=float) * period) / period
    return m.torque_constant * di - J * seen * dw


@dataclass
class Channels:
    """Effect contributions, each a scalar or an (n,) array (see module docstring)."""

    mu: FloatArray | float = 0.0
    mu_relative: FloatArray | float = 0.0
    worm_torque: FloatArray | float = 0.0
    gear_torque: FloatArray | float = 0.0
    worm_inertia: FloatArray | float = 0.0
    gear_inertia: FloatArray | float = 0.0
    current_gain: FloatArray | float = 0.0
    current: FloatArray | float = 0.0

    def add(self, channel: str, value: FloatArray | float) -> None:
        setattr(self, channel, getattr(self, channel) + value)


@dataclass
class ModelState:
    """The model's intermediate quantities per sample (fixed frame unless noted)."""

    sigma: FloatArray  # sign of motion
    mu: FloatArray  # friction coefficient in force
    mu_declared: FloatArray  # the declared model's mu(omega)
    flank: FloatArray  # engaged flank s
    mesh_demand: FloatArray  # G [N m], frame of motion
    flank_factor: FloatArray  # K_s(mu)
    dk_dmu: FloatArray  # dK_s/dmu
    current_true: FloatArray  # i_true [A]
    current: FloatArray  # i_measured [A]
    gain: FloatArray  # 1 + g


def evaluate(rig: Rig, signals: Signals, channels: Channels | None = None) -> ModelState:
    """Model current for every sample (module docstring); never raises for bad samples (NaN out)."""
    ch = channels or Channels()
    gb, motor = rig.gearbox, rig.drive_motor
    w, a = signals.omega, signals.alpha
    sigma = np.where(w < 0.0, -1.0, 1.0)
    mu_declared = friction_coefficient(rig.friction, gb, w)
    mu = mu_declared * (1.0 + ch.mu_relative) + ch.mu
    jw = rig.total_worm_inertia + ch.worm_inertia
    jg = rig.total_gear_inertia + ch.gear_inertia
    gear_load = signals.tau_load + gear_side_drag(rig, w) + ch.gear_torque
    G = sigma * gear_load + jg * gb.ratio * sigma * a
    s = np.where(G >= 0.0, 1.0, -1.0)
    K = flank_factor(gb, mu, s)
    cphi, sl, cl = np.cos(gb.normal_pressure_angle), np.sin(gb.lead_angle), np.cos(gb.lead_angle)
    den = s * cphi * cl - mu * sl
    dk = (cl * den + sl * (s * cphi * sl + mu * cl)) / den**2  # d/dmu of (s c sl + mu cl)/(s c cl - mu sl)
    T = jw * sigma * a + gb.radius_ratio * K * G
    torque = motor.viscous_drag * w + coulomb_magnitude(motor, w) * sigma + sigma * T + ch.worm_torque
    i_true = torque / motor.torque_constant
    gain = 1.0 + np.asarray(ch.current_gain, dtype=float)
    current = gain * i_true + ch.current
    return ModelState(sigma=sigma, mu=np.broadcast_to(mu, w.shape), mu_declared=mu_declared, flank=s, mesh_demand=G,
                      flank_factor=K, dk_dmu=dk, current_true=i_true, current=current,
                      gain=np.broadcast_to(gain, w.shape))


def sensitivities(rig: Rig, signals: Signals, state: ModelState) -> dict[str, FloatArray]:
    """d i_measured / d channel per sample [A per channel unit], at the state's operating point."""
    gb, kt = rig.gearbox, rig.drive_motor.torque_constant
    g, s_, a = state.gain, state.sigma, signals.alpha
    k = gb.radius_ratio
    d_mu = g * s_ * k * state.dk_dmu * state.mesh_demand / kt
    return {
        "mu": d_mu,
        "mu_relative": d_mu * state.mu_declared,
        "worm_torque": g / kt * np.ones_like(a),
        "gear_torque": g * k * state.flank_factor / kt,
        "worm_inertia": g * a / kt,
        "gear_inertia": g * k * state.flank_factor * gb.ratio * a / kt,
        "current_gain": state.current_true,
        "current": np.ones_like(a),
    }
