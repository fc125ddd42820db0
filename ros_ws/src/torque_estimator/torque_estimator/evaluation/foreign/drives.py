"""Three example worm drives: their catalogue numbers and their hidden truth.

Each drive is a frozen :class:`ForeignDrive`. Its ``catalogue`` holds what a user reads off a gear catalogue and
a motor datasheet, under the names of the datasheet tool's options (``--ratio`` -> ``ratio``; see
:func:`datasheet_args`)::

    ratio, starts, hand, lead_angle_deg, pressure_angle_deg,
    worm_diameter_mm  (foreign30, lift40)  or  centre_distance_mm  (big50),
    torque_constant [N m/A], resistance [ohm], rotor_inertia_gcm2 [g cm^2], inductance_mh [mH],
    rated_current [A], max_voltage [V]

Everything else is the hidden truth a user does not know and an identification has to find: the tooth
friction law, the motor's and the output supports' drags, the worm's and the output's inertias, and the
sensors. The catalogue's own numbers are true as printed (the simulated motor has exactly the datasheet's K_t,
R, L and rotor inertia; the gear set exactly the catalogue's geometry).

Pitch radii follow from the catalogue (speed ratio i = n / Z_g = r_w tan(lambda) / r_g, centre distance
a = r_w + r_g): from the worm's pitch diameter d_w, r_w = d_w / 2 and r_g = r_w tan(lambda) / i; from the
centre distance, r_g = a / (1 + i / tan(lambda)) and r_w = a - r_g.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

GCM2 = 1e-7
"""1 g cm^2 in kg m^2."""


@dataclass(frozen=True)
class ForeignDrive:
    """One worm drive: catalogue numbers plus the hidden truth, SI units (angles in rad)."""

    name: str
    catalogue: dict[str, Any] = field(hash=False)
    """What a user types into a datasheet tool (keys: the module docstring)."""
    # --- gear set (from the catalogue) ---
    starts: int
    teeth: int
    worm_pitch_radius: float  # r_w [m]
    gear_pitch_radius: float  # r_g [m]
    lead_angle: float  # lambda [rad]
    normal_pressure_angle: float  # phi_n [rad]
    # --- tooth friction: mu(v_s) = mu_k + mu_s exp(-v_s / v_st), v_s the sliding speed [m/s] ---
    mu_k: float
    mu_s: float
    v_st: float  # [m/s]
    # --- motor (catalogue) ---
    torque_constant: float  # K_t [N m/A] (= K_e [V s/rad])
    resistance: float  # R [ohm]
    inductance: float  # L [H]
    rotor_inertia: float  # [kg m^2]
    supply: float  # [V], the voltage is clamped to +-supply
    rated_current: float  # [A]
    # --- hidden mechanics ---
    worm_inertia: float  # worm, its shaft and the coupling [kg m^2]
    gear_inertia: float  # gear, output shaft and whatever rigid mass the load has [kg m^2]
    motor_viscous: float  # b [N m s/rad] on the worm shaft
    motor_coulomb: float  # c [N m] on the worm shaft (static = kinetic)
    gear_coulomb: float  # c_g [N m], output supports
    gear_viscous: float  # b_g [N m s/rad] on the gear speed
    gear_coulomb_rise: float  # extra Coulomb drag at standstill [N m], decaying as exp(-|omega_g| / gear_rise_speed)
    gear_rise_speed: float  # [rad/s] of the gear
    # --- sensors and sampling ---
    sample_rate: float  # [Hz]
    substeps: int  # integration steps per sample
    counts_per_rev: int  # worm encoder counts per turn (quadrature counts)
    speed_source: str  # "encoder" (differences of the quantised angle) or "tacho" (true speed + noise)
    speed_average: int  # encoder speed: the angle difference over this many samples
    tacho_noise: float  # [rad/s] standard deviation (speed_source "tacho")
    current_noise: float  # [A] standard deviation of the current sensor's white noise
    current_lsb: float  # [A] current quantisation step (0: none)
    voltage_noise: float  # [V] standard deviation on the reported mean voltage (0: exact)
    # --- what the profiles and the speed controller use ---
    load_scale: float  # [N m] typical output load: excitation loads span -0.5..1.5 x this
    speed_bandwidth: float = 60.0  # [rad/s] closed-loop bandwidth of the PI speed controller

    @property
    def ratio(self) -> float:
        """Speed ratio i = omega_gear / omega_worm = n / Z_g (< 1)."""
        return self.starts / self.teeth

    @property
    def self_locking(self) -> bool:
        """The mesh self-locks while sliding (mu_k > cos(phi_n) tan(lambda)), and so also at standstill."""
        return self.mu_k > math.cos(self.normal_pressure_angle) * math.tan(self.lead_angle)

    @property
    def self_locking_at_rest(self) -> bool:
        """The mesh self-locks at standstill (static mu = mu_k + mu_s > cos(phi_n) tan(lambda))."""
        return self.mu_k + self.mu_s > math.cos(self.normal_pressure_angle) * math.tan(self.lead_angle)

    @property
    def no_load_speed(self) -> float:
        """supply / K_e [rad/s]."""
        return self.supply / self.torque_constant

    def truth(self) -> dict[str, float]:
        """The hidden parameters (SI), by name, for comparing with what an identification finds."""
        return {name: float(getattr(self, name)) for name in (
            "mu_k", "mu_s", "v_st", "worm_inertia", "gear_inertia", "motor_viscous", "motor_coulomb",
            "gear_coulomb", "gear_viscous", "gear_coulomb_rise", "gear_rise_speed", "worm_pitch_radius",
            "gear_pitch_radius", "lead_angle", "normal_pressure_angle")}


def pitch_radii(catalogue: dict[str, Any]) -> tuple[float, float]:
    """(r_w, r_g) [m] from the catalogue's ratio, starts, lead angle and d_w or a (module docstring)."""
    i = catalogue["starts"] / (catalogue["ratio"] * catalogue["starts"])
    tan_lead = math.tan(math.radians(catalogue["lead_angle_deg"]))
    if "centre_distance_mm" in catalogue:
        a = catalogue["centre_distance_mm"] * 1e-3
        r_g = a / (1.0 + i / tan_lead)
        return a - r_g, r_g
    r_w = catalogue["worm_diameter_mm"] * 1e-3 / 2.0
    return r_w, r_w * tan_lead / i


def datasheet_args(drive: ForeignDrive) -> list[str]:
    """The catalogue as command-line options (``--ratio 30 --starts 1 ...``), in the catalogue's order."""
    args: list[str] = []
    for key, value in drive.catalogue.items():
        args += [f"--{key.replace('_', '-')}", str(value)]
    return args


def _drive(name: str, catalogue: dict[str, Any], **truth: Any) -> ForeignDrive:
    r_w, r_g = pitch_radii(catalogue)
    return ForeignDrive(
        name=name, catalogue=catalogue, starts=catalogue["starts"],
        teeth=round(catalogue["ratio"] * catalogue["starts"]), worm_pitch_radius=r_w, gear_pitch_radius=r_g,
        lead_angle=math.radians(catalogue["lead_angle_deg"]),
        normal_pressure_angle=math.radians(catalogue["pressure_angle_deg"]),
        torque_constant=catalogue["torque_constant"], resistance=catalogue["resistance"],
        inductance=catalogue["inductance_mh"] * 1e-3, rotor_inertia=catalogue["rotor_inertia_gcm2"] * GCM2,
        supply=catalogue["max_voltage"], rated_current=catalogue["rated_current"], **truth)


FOREIGN30 = _drive(
    "foreign30",
    {"ratio": 30, "starts": 1, "hand": "right", "worm_diameter_mm": 13.0, "lead_angle_deg": 6.87,
     "pressure_angle_deg": 20.0, "torque_constant": 0.052, "resistance": 1.9, "rotor_inertia_gcm2": 35.0,
     "inductance_mh": 1.2, "rated_current": 3.0, "max_voltage": 24.0},
    # back-drivable: mu 0.06 < cos(20 deg) tan(6.87 deg) = 0.113
    mu_k=0.06, mu_s=0.0, v_st=0.01,
    worm_inertia=5.0 * GCM2, gear_inertia=2e-3,
    motor_viscous=2e-5, motor_coulomb=3e-3,
    gear_coulomb=0.02, gear_viscous=0.0, gear_coulomb_rise=0.0, gear_rise_speed=0.1,
    sample_rate=1000.0, substeps=10, counts_per_rev=2000, speed_source="encoder", speed_average=1,
    tacho_noise=0.0, current_noise=4e-3, current_lsb=0.0, voltage_noise=0.0,
    load_scale=1.0,
)
"""30:1, one start, d_w 13 mm: back-drivable, constant mu, speed from a 2000-count encoder, 1 kHz."""

LIFT40 = _drive(
    "lift40",
    {"ratio": 40, "starts": 1, "hand": "right", "worm_diameter_mm": 16.0, "lead_angle_deg": 3.5,
     "pressure_angle_deg": 20.0, "torque_constant": 0.03, "resistance": 1.2, "rotor_inertia_gcm2": 20.0,
     "inductance_mh": 0.5, "rated_current": 4.0, "max_voltage": 24.0},
    # self-locking: mu >= 0.08 > cos(20 deg) tan(3.5 deg) = 0.0575; rising to 0.12 at standstill
    mu_k=0.08, mu_s=0.04, v_st=0.01,
    # a steel worm of 16 mm pitch diameter and ~40 mm face with its shaft and coupling: ~25 g cm^2
    worm_inertia=25.0 * GCM2, gear_inertia=5e-3,
    motor_viscous=1e-5, motor_coulomb=2e-3,
    gear_coulomb=0.05, gear_viscous=0.0, gear_coulomb_rise=0.04, gear_rise_speed=0.1,
    sample_rate=500.0, substeps=20, counts_per_rev=1024, speed_source="tacho", speed_average=1,
    tacho_noise=0.3, current_noise=10e-3, current_lsb=5e-3, voltage_noise=0.0,
    load_scale=0.8, speed_bandwidth=150.0,  # a stiffer speed loop against low-speed stick-slip
)
"""40:1 self-locking lift / pan-tilt drive: Stribeck-like mu, tacho speed, quantised current, 500 Hz."""

BIG50 = _drive(
    "big50",
    {"ratio": 50, "starts": 1, "hand": "right", "centre_distance_mm": 63.0, "lead_angle_deg": 5.2,
     "pressure_angle_deg": 20.0, "torque_constant": 0.12, "resistance": 0.6, "rotor_inertia_gcm2": 250.0,
     "inductance_mh": 2.0, "rated_current": 8.0, "max_voltage": 48.0},
    # back-drivable: mu 0.045 < cos(20 deg) tan(5.2 deg) = 0.0855
    mu_k=0.045, mu_s=0.0, v_st=0.01,
    # a steel worm of ~23 mm pitch diameter and ~60 mm face with its shaft: ~150 g cm^2
    worm_inertia=150.0 * GCM2, gear_inertia=0.05,
    motor_viscous=8e-5, motor_coulomb=0.015,
    gear_coulomb=0.3, gear_viscous=0.02, gear_coulomb_rise=0.0, gear_rise_speed=0.1,
    sample_rate=1000.0, substeps=10, counts_per_rev=4096, speed_source="encoder", speed_average=4,
    tacho_noise=0.0, current_noise=20e-3, current_lsb=0.0, voltage_noise=0.0,
    load_scale=15.0,
)
"""50:1 industrial size, a = 63 mm: back-drivable, 4096-count encoder speed averaged over 4 samples, 1 kHz."""

DRIVES: dict[str, ForeignDrive] = {d.name: d for d in (FOREIGN30, LIFT40, BIG50)}
"""The drives by name."""
