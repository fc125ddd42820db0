"""The vocabulary: every effect the model lacks (physics.md section 9), the PWM and the gearbox's aging, declared once.

Each declaration is a name, a one-line summary and the parameters, each with its unit, default, range
check and meaning (the default's reason: ``assumption:`` or a source). The simulator's hooks
(worm_rig_driver.sim.effects), the residual analysis's regressors (worm_model.residuals.effects), the
``worm_rig_effects`` file (worm_model.effects.file_format) and the health monitor's thermal model
(worm_model.health.settings) read them from here; a side's formulas are its own (the registry's docstring).

Conventions of the parameters: SI units (angles in rad, temperatures in degC, ages in h); a worm-shaft
torque is a magnitude whose sign each side's formula sets (a drag opposes the rotation); ``load_fraction``
and ``reference_torque`` are of the torque the mesh carries on the gear side (the mesh load).

At their defaults the aging effects (``wear``, ``lubricant_loss``, ``seal_drag``) leave the gearbox as
new; their parameters say how it ages.
"""
from __future__ import annotations

import math

from worm_model.effects.parameters import Parameter
from worm_model.effects.registry import Declaration, declare

#: [Hz] the firmware's PWM: timers 4/5 in fast PWM with TOP = PWM_TOP = 799 at 16 MHz, 16e6 / 800 = 20 kHz
#: (firmware/motors.c; worm_rig_driver's protocol/table.py holds PWM_TOP and F_CPU_HZ, and its tests pin that
#: they give these two numbers: worm_model does not import the driver package)
PWM_FREQUENCY = 20_000.0
#: the firmware's duty steps from 0 to 100 %, PWM_TOP + 1
PWM_LEVELS = 800

#: [K/W] oil to ambient through the housing of the bundled NMRV030 (centre distance C = 30 mm), in still air.
#: Assumption, argued from AGMA's rule for worm-gear housings (Shigley's Mechanical Engineering Design, 9th ed.,
#: Sec. 15-8): heat transfer coefficient without a fan h = n_w / 6494 + 0.13 ft lbf/(min in^2 degF) (n_w the worm
#: speed in rpm), over a lateral area of at least 43.2 C^1.7 in^2 (C in in): 8.2 W/(m^2 K) at a standing worm over
#: 0.037 m^2, 3.3 K/W; 1.5 K/W at 1000 rpm. Rounded up to 5 K/W because the rig's housing is a small die-cast box
#: that may fall short of AGMA's area and its worm turns slowly much of the time; to identify once with an oil sensor.
THERMAL_RESISTANCE = 5.0
#: [s] the housing's and oil's thermal time constant R_th C (assumption: ~15 min)
THERMAL_TIME_CONSTANT = 900.0


declare(Declaration("bearing_coulomb", "bearing and seal Coulomb drag on the worm and gear shafts", {
    "worm_torque": Parameter(3e-3, "N m", "Coulomb drag on the worm shaft (assumption: two ball bearings "
                             "and a 15 mm lip seal, a few mN m)", "nonnegative"),
    "gear_torque": Parameter(15e-3, "N m", "Coulomb drag on the gear shaft (assumption: two 14 mm lip "
                             "seals and the output bearings)", "nonnegative"),
}))

declare(Declaration("viscous_drag", "viscous and oil-churning drag on the worm and gear shafts", {
    "worm_torque": Parameter(3e-3, "N m", "drag on the worm shaft at the reference speed (assumption: "
                             "splash-lubricated worm, ~1 W at 300 rad/s)", "nonnegative"),
    "gear_torque": Parameter(10e-3, "N m", "drag on the gear shaft at the reference worm speed "
                             "(assumption: wheel churning in the oil bath)", "nonnegative"),
    "reference_speed": Parameter(300.0, "rad/s", "worm speed at which the torques above are reached",
                                 "positive"),
    "exponent": Parameter(1.0, "1", "speed exponent: 1 viscous, 0.5..1 churning", "nonnegative"),
}))

declare(Declaration("speed_dependent_mu", "mesh mu rising at low sliding speed (Stribeck), beyond the model's mu law", {
    "low_speed_gain": Parameter(0.5, "1", "relative increase of mu as the sliding speed goes to 0 "
                                "(assumption: boundary vs. EHL friction of bronze on steel)", "relative"),
    "stribeck_speed": Parameter(0.3, "m/s", "sliding speed over which the increase decays "
                                "(assumption: 0.3 m/s ~ 40 rad/s worm speed on the bundled rig)", "positive"),
}))

declare(Declaration("load_dependent_mu", "mesh mu changing with the transmitted load", {
    "sensitivity": Parameter(-0.15, "1", "relative change of mu at the reference torque (assumption: mu "
                             "falls as the load grows, as the paper's Fig. 9 shows)"),
    "reference_torque": Parameter(0.25, "N m", "gear-side torque at which the change is `sensitivity`",
                                  "positive"),
}))

declare(Declaration("oil_temperature", "oil temperature (first order, thermal time constant) scaling the mesh mu", {
    "ambient": Parameter(25.0, "degC", "ambient temperature; the model's mu holds there (assumption: lab)"),
    "initial": Parameter(25.0, "degC", "oil temperature at the start of the run"),
    "thermal_resistance": Parameter(THERMAL_RESISTANCE, "K/W", "oil to ambient through the housing (assumption: "
                                    "AGMA's still-air rule gives 3.3 K/W for a 30 mm worm housing, Shigley 9th ed. "
                                    "Sec. 15-8; rounded up for a small box and a slow worm)", "positive"),
    "time_constant": Parameter(THERMAL_TIME_CONSTANT, "s", "thermal time constant R_th C (assumption: ~15 min, "
                               "housing and oil)", "positive"),
    "mu_per_kelvin": Parameter(-0.003, "1/K", "relative change of mu per kelvin (assumption: thinner, "
                               "hotter oil lowers the viscous part of the mesh friction)"),
}))

declare(Declaration("worm_runout", "torque ripple once per worm turn (eccentricity, misalignment)", {
    "amplitude": Parameter(1e-3, "N m", "load-independent ripple amplitude on the worm shaft (assumption)",
                           "nonnegative"),
    "load_fraction": Parameter(0.02, "1", "ripple amplitude per unit of mesh torque at the worm "
                               "(assumption: ~2 %, eccentricity + misalignment)", "nonnegative"),
    "phase": Parameter(0.0, "rad", "angle of the ripple's zero crossing on the worm"),
}))

declare(Declaration("tooth_pass", "mesh ripple at the tooth-pass order (Z_g per gear turn = n per worm turn)", {
    "amplitude": Parameter(5e-3, "N m", "load-independent ripple amplitude on the gear shaft (assumption)",
                           "nonnegative"),
    "load_fraction": Parameter(0.03, "1", "ripple amplitude per unit of mesh load (assumption: mesh "
                               "stiffness variation of a few %)", "nonnegative"),
    "phase": Parameter(0.0, "rad", "phase of the ripple at theta_gear = 0"),
}))

declare(Declaration("gear_runout", "torque ripple once per gear turn (wheel eccentricity)", {
    "amplitude": Parameter(10e-3, "N m", "load-independent ripple amplitude on the gear shaft (assumption)",
                           "nonnegative"),
    "load_fraction": Parameter(0.03, "1", "ripple amplitude per unit of mesh load (assumption)",
                               "nonnegative"),
    "phase": Parameter(0.0, "rad", "phase of the ripple at theta_gear = 0"),
}))

declare(Declaration("motor_cogging", "drive-motor cogging torque, `order` cycles per motor turn", {
    "amplitude": Parameter(2e-3, "N m", "cogging torque amplitude (assumption: ~1.5 % of the rated "
                           "0.14 N m of a brushed servo)", "nonnegative"),
    "order": Parameter(14, "1", "cogging cycles per turn (assumption: 2 poles, 7 slots -> LCM 14)", "count"),
    "phase": Parameter(0.0, "rad", "phase at theta_worm = 0"),
}))

declare(Declaration("backlash", "mesh clearance: a dead zone crossed at each flank change", {
    "angle": Parameter(math.radians(15.0 / 60.0), "rad", "circumferential clearance at the gear (output) "
                       "shaft (assumption: 15 arcmin, the order catalogues give for small worm gearboxes)",
                       "nonnegative"),
}))

declare(Declaration("sensor_gain", "gain error of the current sensors and tachos (readings only)", {
    "drive_current": Parameter(0.03, "1", "relative gain error of the drive current sensor (assumption: "
                               "ACS712 sensitivity tolerance is a few %)", "relative"),
    "load_current": Parameter(0.02, "1", "relative gain error of both load current sensors", "relative"),
    "drive_tacho": Parameter(0.01, "1", "relative gain error of the drive tacho", "relative"),
    "load_tacho": Parameter(0.01, "1", "relative gain error of both load tachos", "relative"),
}))

declare(Declaration("sensor_offset", "zero offset of the current sensors and tachos (readings only)", {
    "drive_current": Parameter(0.05, "A", "offset of the drive current sensor (assumption: ACS712 zero "
                               "drift of ~10 mV / 185 mV/A)"),
    "load_current": Parameter(0.03, "A", "offset of both load current sensors"),
    "drive_tacho": Parameter(0.0, "rad/s", "offset of the drive tacho channel"),
    "load_tacho": Parameter(0.0, "rad/s", "offset of both load tacho channels"),
}))

declare(Declaration("inertia_error", "true shaft inertias differ from the rig file's", {
    "worm": Parameter(0.2, "1", "relative error of the worm-shaft inertia (worm + motor rotor)", "relative"),
    "gear": Parameter(0.2, "1", "relative error of the gear-shaft inertia (gear + load rotors)", "relative"),
}))

declare(Declaration("pwm", "H-bridge PWM: duty resolution and the current ripple the ADC samples", {
    "frequency": Parameter(PWM_FREQUENCY, "Hz",
                           "PWM frequency (the firmware's: 16 MHz / (PWM_TOP + 1) = 20 kHz)", "positive"),
    "duty_levels": Parameter(PWM_LEVELS, "1", "duty steps from 0 to 100 % (the firmware's "
                             "PWM_TOP + 1 = 800); 0 = continuous", "count0"),
    "filter_cutoff": Parameter(2000.0, "Hz", "first-order cut-off of the Hall sensor's output filter "
                               "(assumption: ACS712 with C_F = 47 nF)", "positive"),
}))

declare(Declaration("wear", "wear: mu, shaft drags and backlash rising with the hours run", {
    "hours": Parameter(0.0, "h", "age at the start of the run (0: new)", "nonnegative"),
    "time_factor": Parameter(0.0, "1", "hours of wear per hour of rig time (0: the age is fixed over the "
                             "run; 3600: an hour per second)", "nonnegative"),
    "mu_rate": Parameter(0.05, "1", "relative rise of mu per 1000 h (assumption: a bronze wheel running in "
                         "and wearing, ~5 % per 1000 h)"),
    "worm_drag_rate": Parameter(1e-3, "N m", "rise of the worm shaft's Coulomb drag per 1000 h (assumption: "
                                "a hardening input seal lip)", "nonnegative"),
    "gear_drag_rate": Parameter(2e-3, "N m", "rise of the gear shaft's Coulomb drag per 1000 h (assumption: "
                                "output seals and bearings)", "nonnegative"),
    "backlash_rate": Parameter(math.radians(3.0 / 60.0), "rad", "growth of the clearance at the gear per "
                               "1000 h (assumption: 3 arcmin per 1000 h of tooth wear)", "nonnegative"),
}))

declare(Declaration("lubricant_loss", "lubricant loss: mu stepping up at a given rig time", {
    "rise": Parameter(0.0, "1", "relative rise of mu after the loss (0: healthy; a starved mesh: 0.3)",
                      "relative"),
    "at": Parameter(0.0, "s", "rig time of the loss since the start of the run", "nonnegative"),
    "duration": Parameter(0.0, "s", "time over which mu rises to its new value (0: a step)", "nonnegative"),
}))

declare(Declaration("seal_drag", "a seal starting to drag: Coulomb drag on the worm and gear shafts from a given "
                                 "rig time", {
    "worm_torque": Parameter(0.0, "N m", "extra Coulomb drag on the worm shaft (0: healthy; a dragging "
                             "15 mm lip seal: a few mN m)", "nonnegative"),
    "gear_torque": Parameter(0.0, "N m", "extra Coulomb drag on the gear shaft (0: healthy)", "nonnegative"),
    "onset": Parameter(0.0, "s", "rig time at which the drag starts", "nonnegative"),
    "growth": Parameter(0.0, "s", "time over which the drag grows to its full value (0: at once)",
                        "nonnegative"),
}))


__all__ = ["PWM_FREQUENCY", "PWM_LEVELS", "THERMAL_RESISTANCE", "THERMAL_TIME_CONSTANT"]
