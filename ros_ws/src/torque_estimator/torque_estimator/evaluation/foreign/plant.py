"""The simulator of a foreign worm drive: PMDC motor, worm shaft, mesh with friction, gear shaft, stick, sensors.

Written from textbook worm-gear mechanics, independently of the project's model (no project import).

Sign convention: + worm rotation is the reference; the gear turns with it, omega_gear = i omega_worm
(i = n / Z_g, the hand ignored); the load torque tau_load on the gear shaft is + when it opposes + worm rotation
(a load the motor lifts when turning +). SI units.

Mesh. The tooth-normal force N at the pitch point, inclined by the normal pressure angle phi_n and the lead
angle lambda, with the friction force mu N along the thread opposing the sliding. Resolving the forces on the
worm (tangential: torque about the worm axis) and on the gear (tangential: torque about the gear axis) and
eliminating N, the worm torque that makes a gear-side torque G flow through the mesh is

    driving flank (worm drives gear):  T_worm = (r_w / r_g) G K_+,
        K_+ = (cos phi_n sin lambda + mu cos lambda) / (cos phi_n cos lambda - mu sin lambda) = tan(lambda + rho')
    coast flank (gear drives worm):    T_worm = (r_w / r_g) G K_-,
        K_- = (cos phi_n sin lambda - mu cos lambda) / (cos phi_n cos lambda + mu sin lambda) = tan(lambda - rho')

with tan rho' = mu / cos phi_n. K_- < 0 (mu > cos phi_n tan lambda) is self-locking: the worm must drive even
while an aiding load is lowered. In the frame of motion (sigma = sign of the worm speed) the gear-side demand is

    G_m = sigma (tau_load + d_g(omega_g) + J_gear i alpha_worm)

(d_g the output supports' drag: Coulomb c_g sign(omega_g), a standstill rise c_gs exp(-|omega_g| / w_gs) on it,
and viscous b_g omega_g); the driving flank carries it when G_m >= 0, the coast flank when G_m < 0, and the worm
feels T_worm = sigma (r_w / r_g) K_flank G_m. The worm shaft:

    (J_rotor + J_worm) alpha = K_t i_a - b omega - c sign(omega) - T_worm

is linear in alpha per flank. Which flank is engaged does not depend on the guess: with
A = K_t i_a - b omega - c sigma and L_g = tau_load + d_g, G_m on either flank has the sign of
sigma (L_g J_ws + J_gear i A) / D_flank, D_flank = J_ws + (r_w / r_g) K_flank J_gear i (the effective inertia).
D_+ > 0 always; D_- can turn negative in a self-locking mesh with a heavy output at low sliding speed (a
Painleve-type paradox: no consistent sliding solution); the plant then jams the mesh (the worm stops, and
stays stopped until the motor breaks it free). The drives of ``drives`` keep D_- > 0.

Friction: mu(v_s) = mu_k + mu_s exp(-v_s / v_st), v_s = |omega_worm| r_w / cos(lambda) the sliding speed.

Standstill (stick). omega = 0 exactly is the stuck state: each step the plant asks, for sigma = +1 and -1, whether
the torques at rest (static friction mu_k + mu_s, the supports' standstill drag, the motor's Coulomb c) would
accelerate the worm in direction sigma; if neither, the shaft stays at rest. A speed crossing zero inside a step
stops the shaft there, and the next step decides. So a self-locking drive holds its load with the motor off and a
back-drivable one runs away under it.

PMDC motor: L di/dt = V - R i - K_e omega (K_e = K_t), integrated exactly over each step at constant omega;
the mechanics by semi-implicit Euler (angle by the trapezoid rule), ``substeps`` steps per sample, a step split
in 8 inside the Stribeck region of the friction (v_s < 5 v_st) where mu changes fast with speed.

Sampling, row k at t_k = k / sample_rate: the inputs (voltage, load) are held over (t_{k-1}, t_k] and reported on
row k; the states (current, angle) are the values at t_k. A PI speed controller (plus feedforward K_e omega_ref)
computes, from row k's reported speed, the voltage of the next interval (one sample of delay, like a real drive).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from torque_estimator.evaluation.foreign.drives import ForeignDrive

SPEED, OPEN, VOLTAGE = 0, 1, 2
"""Drive modes of a profile sample: PI speed control, motor open circuit (no current), a fixed voltage."""
FINE_SPLIT = 8
"""Steps inside the Stribeck region are split in this many."""


# ------------------------------------------------------------------------------------------------------------
# the quasi-static relations (also what the tests check the simulation against)

def mesh_factors(drive: ForeignDrive, mu: float) -> tuple[float, float]:
    """(K_+, K_-): worm torque per gear-side torque, times r_g / r_w, on the driving and the coast flank."""
    cp, sl, cl = math.cos(drive.normal_pressure_angle), math.sin(drive.lead_angle), math.cos(drive.lead_angle)
    return (cp * sl + mu * cl) / (cp * cl - mu * sl), (cp * sl - mu * cl) / (cp * cl + mu * sl)


def friction_coefficient(drive: ForeignDrive, omega_worm: float) -> float:
    """mu at the sliding speed of this worm speed."""
    v_s = abs(omega_worm) * drive.worm_pitch_radius / math.cos(drive.lead_angle)
    return drive.mu_k + drive.mu_s * math.exp(-v_s / drive.v_st)


def gear_drag(drive: ForeignDrive, omega_worm: float) -> float:
    """Output supports' drag torque [N m] (+ opposes + rotation) at a worm speed != 0."""
    omega_g = drive.ratio * omega_worm
    coulomb = drive.gear_coulomb + drive.gear_coulomb_rise * math.exp(-abs(omega_g) / drive.gear_rise_speed)
    return math.copysign(coulomb, omega_g) + drive.gear_viscous * omega_g


def worm_load_torque(drive: ForeignDrive, omega_worm: float, tau_load: float) -> float:
    """Quasi-static mesh torque on the worm [N m] at a held speed != 0 and load (flank by the sign of G_m)."""
    sigma = 1.0 if omega_worm > 0 else -1.0
    g_m = sigma * (tau_load + gear_drag(drive, omega_worm))
    k_plus, k_minus = mesh_factors(drive, friction_coefficient(drive, omega_worm))
    q = drive.worm_pitch_radius / drive.gear_pitch_radius
    return sigma * q * (k_plus if g_m >= 0 else k_minus) * g_m


def steady_current(drive: ForeignDrive, omega_worm: float, tau_load: float) -> float:
    """Armature current [A] at a held speed != 0 and load: K_t i = b omega + c sign(omega) + T_worm."""
    torque = drive.motor_viscous * omega_worm + math.copysign(drive.motor_coulomb, omega_worm) \
        + worm_load_torque(drive, omega_worm, tau_load)
    return torque / drive.torque_constant


def driving_inertia(drive: ForeignDrive) -> float:
    """Worm-side inertia on the driving flank at mu_k: J_rotor + J_worm + (r_w / r_g) K_+ J_gear i [kg m^2]."""
    k_plus, _ = mesh_factors(drive, drive.mu_k)
    q = drive.worm_pitch_radius / drive.gear_pitch_radius
    return drive.rotor_inertia + drive.worm_inertia + q * k_plus * drive.gear_inertia * drive.ratio


def coast_inertia_min(drive: ForeignDrive) -> float:
    """The smallest coast-flank effective inertia D_- (at standstill friction) [kg m^2]; <= 0: the mesh can jam."""
    _, k_minus = mesh_factors(drive, drive.mu_k + drive.mu_s)
    q = drive.worm_pitch_radius / drive.gear_pitch_radius
    return drive.rotor_inertia + drive.worm_inertia + q * k_minus * drive.gear_inertia * drive.ratio


def pi_gains(drive: ForeignDrive) -> tuple[float, float]:
    """(k_p [V s/rad], k_i [V/rad]) of the speed PI: the mechanical pole cancelled, bandwidth speed_bandwidth."""
    ke = drive.torque_constant
    tau_m = drive.resistance * driving_inertia(drive) / (drive.torque_constant * ke)
    k_p = drive.speed_bandwidth * tau_m * ke
    return k_p, k_p / tau_m


# ------------------------------------------------------------------------------------------------------------
# profiles and recordings

@dataclass
class Profile:
    """What happens to the drive, one entry per sample (row k: the inputs over (t_{k-1}, t_k]).

    ``speed_ref`` [rad/s] is the PI's set-point (mode SPEED), ``voltage`` [V] the applied voltage (mode
    VOLTAGE), ``load`` [N m] the imposed output torque (+ opposes + rotation), ``mode`` SPEED / OPEN / VOLTAGE.
    """

    speed_ref: np.ndarray
    load: np.ndarray
    mode: np.ndarray
    voltage: np.ndarray
    name: str = ""

    def __post_init__(self) -> None:
        n = len(self.load)
        self.speed_ref = np.asarray(self.speed_ref, dtype=float)
        self.load = np.asarray(self.load, dtype=float)
        self.mode = np.asarray(self.mode, dtype=int)
        self.voltage = np.asarray(self.voltage, dtype=float)
        if any(len(a) != n for a in (self.speed_ref, self.mode, self.voltage)) or n < 1:
            raise ValueError("profile arrays must have one equal, non-zero length")

    @classmethod
    def speed(cls, speed_ref: np.ndarray, load: np.ndarray, name: str = "") -> Profile:
        """A speed-controlled profile."""
        n = len(load)
        return cls(np.asarray(speed_ref, dtype=float), load, np.full(n, SPEED), np.zeros(n), name)

    def __len__(self) -> int:
        return len(self.load)


@dataclass
class Recording:
    """A simulated recording: the ``worm_rig_data`` columns, and the truth behind them (arrays of n samples)."""

    drive: str
    profile: str
    seed: int | tuple[int, ...]
    t: np.ndarray
    current_drive: np.ndarray  # measured [A]
    omega_worm: np.ndarray  # reported [rad/s] (encoder differences or tacho)
    theta_worm: np.ndarray  # encoder [rad], quantised, unwrapped
    tau_load: np.ndarray  # imposed load [N m]
    voltage_drive: np.ndarray  # mean voltage over the period ending at t [V]
    # --- truth ---
    current_true: np.ndarray
    omega_true: np.ndarray
    theta_true: np.ndarray
    speed_ref: np.ndarray
    mode: np.ndarray
    flank: np.ndarray  # engaged flank at t: +1 driving, -1 coast, 0 at rest
    mu: np.ndarray  # tooth friction coefficient at t
    jams: int  # mesh jams (no consistent sliding solution), 0 for the drives of ``drives``

    COLUMNS = ("t", "current_drive", "omega_worm", "theta_worm", "tau_load", "voltage_drive")

    def __len__(self) -> int:
        return len(self.t)


def simulate(drive: ForeignDrive, profile: Profile, seed: int | tuple[int, ...] = 0) -> Recording:
    """Run the drive through the profile; sensor noise from ``numpy.random.default_rng(seed)``.

    Starts at rest (current 0, speed 0) at a random encoder phase. Deterministic given the seed.
    """
    n = len(profile)
    fs = float(drive.sample_rate)
    ts = 1.0 / fs
    m = int(drive.substeps)
    dt = ts / m

    rng = np.random.default_rng(seed)
    cur_noise = rng.normal(0.0, drive.current_noise, n).tolist() if drive.current_noise > 0 else [0.0] * n
    tacho_noise = rng.normal(0.0, drive.tacho_noise, n).tolist() if drive.tacho_noise > 0 else [0.0] * n
    volt_noise = rng.normal(0.0, drive.voltage_noise, n).tolist() if drive.voltage_noise > 0 else [0.0] * n
    enc_step = 2.0 * math.pi / drive.counts_per_rev
    theta = float(rng.uniform(0.0, 1.0)) * enc_step

    # constants as plain floats (the inner loop runs millions of times)
    kt = ke = float(drive.torque_constant)
    res, ind = float(drive.resistance), float(drive.inductance)
    vmax = float(drive.supply)
    jws = float(drive.rotor_inertia + drive.worm_inertia)
    i_r = float(drive.ratio)
    jg_i = float(drive.gear_inertia) * i_r
    q = float(drive.worm_pitch_radius / drive.gear_pitch_radius)
    b, c = float(drive.motor_viscous), float(drive.motor_coulomb)
    c_g, b_g = float(drive.gear_coulomb), float(drive.gear_viscous)
    c_gs, w_gs = float(drive.gear_coulomb_rise), float(drive.gear_rise_speed)
    mu_k, mu_s, v_st = float(drive.mu_k), float(drive.mu_s), float(drive.v_st)
    cp = math.cos(drive.normal_pressure_angle)
    sl, cl = math.sin(drive.lead_angle), math.cos(drive.lead_angle)
    vs_per_w = float(drive.worm_pitch_radius) / cl  # sliding speed per worm speed
    fine_below = 5.0 * v_st / vs_per_w if mu_s > 0 else -1.0  # |omega| below which the step is split
    kp_const, km_const = mesh_factors(drive, mu_k)
    decay = math.exp(-res * dt / ind)
    k_p, k_i = pi_gains(drive)
    encoder_speed = drive.speed_source == "encoder"
    if drive.speed_source not in ("encoder", "tacho"):
        raise ValueError(f"speed_source {drive.speed_source!r}: 'encoder' or 'tacho'")
    avg = max(1, int(drive.speed_average))
    lsb = float(drive.current_lsb)

    jams = 0

    def accel(sig: float, w: float, tm: float, tl: float) -> tuple[float, int]:
        """(alpha, flank) of the worm moving in direction sig at speed w; flank 0: the mesh jams."""
        aw = w if w >= 0.0 else -w
        if mu_s > 0.0:
            mu = mu_k + mu_s * math.exp(-aw * vs_per_w / v_st)
            kpl = (cp * sl + mu * cl) / (cp * cl - mu * sl)
            kmi = (cp * sl - mu * cl) / (cp * cl + mu * sl)
        else:
            kpl, kmi = kp_const, km_const
        dg = c_g + c_gs * math.exp(-aw * i_r / w_gs) if c_gs > 0.0 else c_g
        lg = tl + sig * dg + b_g * i_r * w
        a = tm - b * w - sig * c
        if sig * (lg * jws + jg_i * a) >= 0.0:  # driving flank
            return (a - q * kpl * lg) / (jws + q * kpl * jg_i), 1
        d_minus = jws + q * kmi * jg_i
        if d_minus <= 0.0:
            return 0.0, 0
        return (a - q * kmi * lg) / d_minus, -1

    def mech(w: float, th: float, tm: float, tl: float, h: float) -> tuple[float, float, int]:
        """One mechanical step of length h: (omega, theta, flank) after it."""
        nonlocal jams
        if w == 0.0:  # at rest: does it break free, and which way?
            ap, fp = accel(1.0, 0.0, tm, tl)
            am, fm = accel(-1.0, 0.0, tm, tl)
            up = fp != 0 and ap > 0.0
            down = fm != 0 and am < 0.0
            if up and down:
                up = ap > -am
                down = not up
            if up:
                w_new, fl = ap * h, fp
            elif down:
                w_new, fl = am * h, fm
            else:
                return 0.0, th, 0
            return w_new, th + 0.5 * h * w_new, fl
        sig = 1.0 if w > 0.0 else -1.0
        alpha, fl = accel(sig, w, tm, tl)
        if fl == 0:
            jams += 1
            return 0.0, th, 0
        w_new = w + alpha * h
        if w_new * sig <= 0.0:  # crosses zero inside the step: it stops there, the next step decides
            w_new = 0.0
        return w_new, th + 0.5 * h * (w + w_new), fl

    mode = profile.mode.tolist()
    ref = profile.speed_ref.tolist()
    load = profile.load.tolist()
    vcmd = profile.voltage.tolist()

    out_t = [k / fs for k in range(n)]
    out_i, out_w, out_th, out_v = [0.0] * n, [0.0] * n, [0.0] * n, [0.0] * n
    tr_i, tr_w, tr_th, tr_fl, tr_mu = [0.0] * n, [0.0] * n, [0.0] * n, [0] * n, [0.0] * n

    cur, w, integ = 0.0, 0.0, 0.0
    fl = 0
    counts: list[int] = [0] * n

    def measure(k: int, v_mean: float) -> float:
        """Fill row k from the state; returns the reported speed."""
        x = cur + cur_noise[k]
        if lsb > 0.0:
            x = round(round(x / lsb) * lsb, 12)
        out_i[k] = x
        cnt = math.floor(theta / enc_step)
        counts[k] = cnt
        out_th[k] = cnt * enc_step
        if encoder_speed:
            span = min(avg, k)
            wm = (out_th[k] - out_th[k - span]) / (span * ts) if span > 0 else 0.0
        else:
            wm = w + tacho_noise[k]
        out_w[k] = wm
        out_v[k] = v_mean + volt_noise[k] if k > 0 else 0.0
        tr_i[k], tr_w[k], tr_th[k], tr_fl[k] = cur, w, theta, fl
        tr_mu[k] = mu_k + mu_s * math.exp(-abs(w) * vs_per_w / v_st) if mu_s > 0.0 else mu_k
        return wm

    w_meas = measure(0, 0.0)
    for k in range(1, n):
        md, tl = mode[k], load[k]
        if md == SPEED:
            r = ref[k]
            e = r - w_meas
            integ_new = integ + e * ts
            u = ke * r + k_p * e + k_i * integ_new
            if u > vmax:
                u = vmax
                if e < 0.0:
                    integ = integ_new
            elif u < -vmax:
                u = -vmax
                if e > 0.0:
                    integ = integ_new
            else:
                integ = integ_new
        else:
            integ = 0.0
            u = vcmd[k] if md == VOLTAGE else 0.0
            u = vmax if u > vmax else -vmax if u < -vmax else u
        open_circuit = md == OPEN
        v_sum = 0.0
        for _ in range(m):
            if open_circuit:
                cur = 0.0
            else:
                i_ss = (u - ke * w) / res
                cur = i_ss + (cur - i_ss) * decay
            tm = kt * cur
            if -fine_below < w < fine_below:
                h = dt / FINE_SPLIT
                for _ in range(FINE_SPLIT):
                    w, theta, fl = mech(w, theta, tm, tl, h)
            else:
                w, theta, fl = mech(w, theta, tm, tl, dt)
            if open_circuit:
                v_sum += ke * w
        w_meas = measure(k, v_sum / m if open_circuit else u)

    return Recording(
        drive=drive.name, profile=profile.name, seed=seed,
        t=np.array(out_t), current_drive=np.array(out_i), omega_worm=np.array(out_w), theta_worm=np.array(out_th),
        tau_load=profile.load.copy(), voltage_drive=np.array(out_v),
        current_true=np.array(tr_i), omega_true=np.array(tr_w), theta_true=np.array(tr_th),
        speed_ref=profile.speed_ref.copy(), mode=profile.mode.copy(), flank=np.array(tr_fl, dtype=int),
        mu=np.array(tr_mu), jams=jams)
