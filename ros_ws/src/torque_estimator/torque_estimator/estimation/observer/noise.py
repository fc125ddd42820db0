"""What the observer's gains follow from: the sensors' noise figures and the load's process model.

The filter is a Kalman filter, so its gains follow from the covariances, all taken from the
rig file's ``sensors:`` section (:class:`NoiseFigures.from_rig`), not tuned:

* current: σ_i² + lsb_i²/12 (Hall noise + the ADC step as uniform quantisation);
* tacho: σ_t² + lsb_t²/12 (noise, and the drive tacho's ADC step ``tacho_drive_lsb``); the
  commutator ripple (relative amplitude r, periodic in the worm angle) is not noise: the
  streaming observer identifies its phase (two extra states, prior variance r²/2 each;
  :class:`~torque_estimator.estimation.observer.kalman.LoadObserver`). Left as noise it would
  add (r·ω)²/2 (:meth:`NoiseFigures.tacho_total`);
* encoder: lsb_θ²/12 with lsb_θ = 2π/(ppr·decoding), and the floor of the count corrected by
  +lsb_θ/2.

Quantisation is treated as white (true when the signal moves by many steps per sample or is
dithered by noise; at a few rad/s the encoder error is correlated).

Load process (:class:`LoadProcess`): the load is piecewise constant (the load motors hold
set-points for seconds and change them in steps) with a slow drift between steps. The drift is
a random walk whose rms change over one second is ``drift_fraction`` (default 1 %) of the load
motors' maximum torque, q = (0.01·τ_max)²/1 s; it sets the steady bandwidth (hence the steady
noise). Steps are not smeared into q (that would be a random walk fast enough to follow a step
in a few ms and ~20 % of the range of noise); the step detector finds them (``glr``), at the
false-alarm rate and over the window set here.

Units SI. No ROS; numpy + scipy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from worm_model.physics.parameters import Rig


@dataclass(frozen=True)
class NoiseFigures:
    """Measurement noise variances of the drive channel, from the rig file (module docstring).

    Attributes:
        current_var [A²]: σ_i² + lsb_i²/12.
        tacho_var [(rad/s)²]: σ_t² + lsb_t²/12 (the speed-independent part).
        tacho_ripple [1]: relative ripple amplitude r; adds (r ω)²/2.
        theta_var [rad²]: lsb_θ²/12.
        theta_offset [rad]: lsb_θ/2, added to the floored encoder angle.
    """

    current_var: float
    tacho_var: float
    tacho_ripple: float
    theta_var: float
    theta_offset: float

    @classmethod
    def from_rig(cls, rig: Rig) -> "NoiseFigures":
        s = rig.sensors
        theta_lsb = 2.0 * math.pi / (s.encoder_pulses_per_rev * s.encoder_decoding)
        return cls(current_var=s.current_noise_std ** 2 + s.current_lsb ** 2 / 12.0,
                   tacho_var=s.tacho_noise_std ** 2 + s.tacho_drive_lsb ** 2 / 12.0,
                   tacho_ripple=s.tacho_ripple, theta_var=theta_lsb ** 2 / 12.0, theta_offset=theta_lsb / 2.0)

    def tacho_total(self, omega: float) -> float:
        """Tacho variance [(rad/s)²] at worm speed ω [rad/s], ripple included."""
        return self.tacho_var + 0.5 * (self.tacho_ripple * omega) ** 2

    def measurement_covariance(self, omega: float) -> np.ndarray:
        """R for the measurement vector (θ, ω, i) (ripple as noise unless tacho_ripple is 0)."""
        return np.diag([self.theta_var, self.tacho_total(omega), self.current_var])

    def without_ripple(self) -> "NoiseFigures":
        """The figures once the ripple is identified (what the streaming observer is left with)."""
        return replace(self, tacho_ripple=0.0)


@dataclass(frozen=True)
class LoadProcess:
    """The load model the gains follow from (module docstring).

    Attributes:
        drift_fraction: rms change of τ_d over ``drift_time`` between steps, as a fraction of
            Rig.max_load_torque (default 1 % per second).
        drift_time [s].
        false_alarm: probability per sample of a false jump detection (Bonferroni bound).
        window: onsets [samples] the step detector looks back over.
        back_emf_std: prior relative std of the back-EMF constant, δ in L di/dt = V − R i −
            K_e(1 + δ) ω (δ is a state of the observer). Default 0.05: the ±5 % tolerance of a
            motor constant; 5 % of the 8 V back-EMF at 150 rad/s is 0.4 V, which, taken as
            exact, the filter would read as ~0.19 N m of load.
        back_emf_drift [1/√s]: random walk of δ (magnet temperature, −0.2 %/K); default 0.001.
    """

    drift_fraction: float = 0.01
    drift_time: float = 1.0
    false_alarm: float = 1e-4
    window: int = 25
    back_emf_std: float = 0.05
    back_emf_drift: float = 0.001

    def intensity(self, rig: Rig) -> float:
        """q [(N·m)²/s] of the random walk of τ_d."""
        return (self.drift_fraction * rig.max_load_torque) ** 2 / self.drift_time

    def threshold(self) -> float:
        """h: the step detector's statistic above which a jump is declared (χ²₁ at false_alarm / window)."""
        # imported at first use: scipy.stats takes ~0.4 s to import, paid at start by every executable
        from scipy.stats import chi2

        return float(chi2.isf(self.false_alarm / max(self.window, 1), 1))


__all__ = ["LoadProcess", "NoiseFigures"]
