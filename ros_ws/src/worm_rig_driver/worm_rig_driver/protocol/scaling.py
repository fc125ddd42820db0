"""Raw rig readings (ADC codes, encoder counts, duties) <-> SI, from the rig parameters.

The sensor scales are the ones the simulator's SensorModel uses, from one source: the
rig file's ``sensors:`` section (worm_model rig parameters): the Hall current channel's
``current_lsb``, the tachos' ``tacho_drive_lsb`` (worm shaft) and ``tacho_load_lsb`` (gear
shaft), and the encoders' counts per turn.

Signs follow plant.py / RigSample: positive worm rotation is the reference;
gear quantities are referred to it; a positive load-motor current makes a
load torque opposing positive rotation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from worm_model.physics.parameters import Rig

import worm_rig_driver.protocol.table as table

ADC_MAX = (1 << table.ADC_BITS) - 1


@dataclass(frozen=True)
class RigScaling:
    """Conversions between the firmware's raw units and SI for one rig."""

    current_lsb: float  #: [A/count] Hall current channel (rig.sensors.current_lsb)
    tacho_drive_lsb: float  #: [rad/s per count] (rig.sensors.tacho_drive_lsb)
    tacho_load_lsb: float  #: [rad/s per count] (rig.sensors.tacho_load_lsb)
    counts_per_rev: int  #: [count/rev] after quadrature decoding
    supply_voltage: float  #: [V] H-bridge supply: duty 1.0 applies this
    load_torque_constant: float  #: [N m/A] K_t of one load motor
    load_motor_count: int

    @classmethod
    def from_rig(cls, rig: Rig) -> "RigScaling":
        return cls(
            current_lsb=rig.sensors.current_lsb,
            tacho_drive_lsb=rig.sensors.tacho_drive_lsb,
            tacho_load_lsb=rig.sensors.tacho_load_lsb,
            counts_per_rev=rig.sensors.counts_per_rev,
            supply_voltage=rig.supply_voltage,
            load_torque_constant=rig.load_motor.torque_constant,
            load_motor_count=rig.load_motor_count,
        )

    # --- currents ---------------------------------------------------------------------
    def current(self, code: int) -> float:
        """Armature current [A] from its ADC code."""
        return (code - table.CURRENT_ZERO_CODE) * self.current_lsb

    def current_code(self, amps: float) -> int:
        """ADC code the current channel reads for `amps` [A] (nearest step, clipped to the rails)."""
        return int(min(max(round(amps / self.current_lsb) + table.CURRENT_ZERO_CODE, 0), ADC_MAX))

    def current_target(self, amps: float) -> int:
        """SETPOINT current-mode target [counts from zero] for `amps` [A] (not clipped)."""
        return int(round(amps / self.current_lsb))

    # --- tachogenerators --------------------------------------------------------------
    def tacho(self, code: int, load: bool) -> float:
        """Shaft speed [rad/s] from a tacho ADC code (load=True: a load motor's, i.e. the gear's)."""
        return (code - table.TACHO_ZERO_CODE) * (self.tacho_load_lsb if load else self.tacho_drive_lsb)

    def tacho_code(self, omega: float, load: bool) -> int:
        """ADC code a tacho channel reads at `omega` [rad/s] (nearest step, clipped)."""
        lsb = self.tacho_load_lsb if load else self.tacho_drive_lsb
        return int(min(max(round(omega / lsb) + table.TACHO_ZERO_CODE, 0), ADC_MAX))

    # --- encoders, duties, torque -----------------------------------------------------
    def angle(self, counts: int) -> float:
        """Shaft angle [rad] of unwrapped encoder counts."""
        return counts * (2.0 * math.pi / self.counts_per_rev)

    def voltage(self, duty: int) -> float:
        """Mean bridge voltage [V] of a wire duty (1e-4 units)."""
        return duty * self.supply_voltage / table.DUTY_FULL_SCALE

    def duty(self, volts: float) -> int:
        """Wire duty for a mean bridge voltage [V] (not clipped)."""
        return int(round(volts / self.supply_voltage * table.DUTY_FULL_SCALE))

    def load_torque(self, current_1: float, current_2: float) -> float:
        """Load torque on the gear shaft [N m] from the two load currents [A] (as SensorModel reports it)."""
        return self.load_torque_constant * (current_1 + current_2) * self.load_motor_count / 2.0

    def load_current_per_motor(self, torque: float) -> float:
        """Current [A] each load motor needs for a load torque [N m] on the gear shaft."""
        return torque / (self.load_motor_count * self.load_torque_constant)


def adc_code_to_simavr_mv(code: int) -> int:
    """Millivolts to give simavr's ADC so that it reads `code`.

    simavr 1.6 converts with code = floor(mV * 1023 / Vref) (not the datasheet's
    1024); the smallest integer mV that floors to `code` inverts that exactly.
    """
    return -(-code * table.ADC_REF_MV // ADC_MAX)
