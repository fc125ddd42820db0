"""Firmware in the loop: the rig firmware's real ELF in simavr, closed through the simulated plant.

Plain Python (no rclpy). ``FilHarness`` is a ctypes binding of
``firmware/build/libwormfil.so`` (firmware/sim/fil_harness.c: simavr, the UART
on a pty, the multiplexed ADC, the encoder pins, the PWM read-back).
``FilPlant`` is the rig the firmware drives: the simulator's SimulatedRig for
the worm, gearbox, drive armature and sensors, plus the two load motors'
armatures, which here are voltage-driven by their bridges (the plant models
them as ideal current sources; in the loop the firmware's own current loops
make the current). ``FirmwareInTheLoop`` steps both, one sample period at a
time:

    duties read over step k  ->  plant advances step k+1  ->  sensors -> ADC mV and
    encoder counts applied during step k+1 (one sample period of delay, as a
    real sensor chain sampled at 1 kHz has at most)

Sign conventions as plant.py: a load motor's positive current makes a load
torque opposing positive rotation, so its back-EMF sees -omega_gear.
"""
from __future__ import annotations

import ctypes
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from worm_model.physics.motor import exact_current_step
from worm_model.physics.parameters import Rig

import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.scaling import RigScaling, adc_code_to_simavr_mv
from worm_rig_driver.sim.sensors import Measurement
from worm_rig_driver.sim.simulated_rig import SimulatedRig
from worm_rig_driver.errors import FilError



class FilInputs(ctypes.Structure):
    _fields_ = [("mux_a_mv", ctypes.c_uint16 * 8), ("mux_b_mv", ctypes.c_uint16 * 8),
                ("enc_target", ctypes.c_int32 * 3)]


class FilOutputs(ctypes.Structure):
    _fields_ = [("duty", ctypes.c_double * 3), ("cycle", ctypes.c_uint64), ("enc_position", ctypes.c_int32 * 3),
                ("host_bytes", ctypes.c_uint64), ("avr_bytes", ctypes.c_uint64), ("dropped", ctypes.c_uint64),
                ("state", ctypes.c_int32), ("cut", ctypes.c_int32), ("cut_last_byte_cycle", ctypes.c_uint64),
                ("stop_cycle", ctypes.c_uint64)]


class FilHarness:
    """The AVR in simavr with its pins wired (see fil_harness.c); one instance per process."""

    def __init__(self, library: Path, elf: Path, link: str) -> None:
        if not Path(library).exists():
            raise FilError(f"{library}: no such harness library (make -C firmware fil builds it)")
        if not Path(elf).exists():
            raise FilError(f"{elf}: no such firmware ELF (make -C firmware builds it)")
        self._lib = ctypes.CDLL(str(library))
        self._lib.fil_create.restype = ctypes.c_void_p
        self._lib.fil_create.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_int]
        self._lib.fil_step.argtypes = [ctypes.c_void_p, ctypes.c_uint32, ctypes.POINTER(FilInputs),
                                       ctypes.POINTER(FilOutputs)]
        self._lib.fil_cut.argtypes = [ctypes.c_void_p, ctypes.c_int]
        self._lib.fil_destroy.argtypes = [ctypes.c_void_p]
        error = ctypes.create_string_buffer(512)
        self._handle = self._lib.fil_create(str(elf).encode(), link.encode(), error, len(error))
        if not self._handle:
            raise FilError(error.value.decode())
        self.link = link
        self.frequency = table.F_CPU_HZ
        self.inputs = FilInputs()
        self.outputs = FilOutputs()

    def step(self, cycles: int) -> FilOutputs:
        if self._lib.fil_step(self._handle, cycles, ctypes.byref(self.inputs), ctypes.byref(self.outputs)) != 0:
            raise FilError(f"the simulated AVR stopped (simavr state {self.outputs.state}) at cycle "
                           f"{self.outputs.cycle}")
        return self.outputs

    def cut(self, cut: bool) -> None:
        """Stop (True) or resume forwarding host bytes; a cut takes effect at the next frame boundary."""
        self._lib.fil_cut(self._handle, int(cut))

    def close(self) -> None:
        if self._handle:
            self._lib.fil_destroy(self._handle)
            self._handle = None


class FilPlant:
    """The simulated rig as the firmware's bridges drive it (see the module docstring)."""

    def __init__(self, rig: Rig, seed: int = 0, substeps: int = 2) -> None:
        self.rig = rig
        self.sim = SimulatedRig(rig, n=1, seed=seed, substeps=substeps)
        self.scaling = RigScaling.from_rig(rig)
        self.load_currents = np.zeros(2)  # [A] armature currents of the two load motors

    def step(self, duty: tuple[float, float, float]) -> Measurement:
        """Advance one sample period with the bridges' mean duties (signed fractions); returns the sensors."""
        rig = self.rig
        dt = self.sim.sample_period
        volts = np.asarray(duty, float) * rig.supply_voltage
        omega_gear = rig.gearbox.ratio * self.sim.plant.state.omega_worm[0]
        self.load_currents = exact_current_step(rig.load_motor, volts[1:], self.load_currents, -omega_gear, dt)
        mean = float(self.load_currents.mean())
        # The plant's load model is a current source: hold it at what the armatures carry.
        self.sim.plant.state.current_load[:] = mean
        self.sim.command(voltage_drive=volts[0],
                         load_torque=rig.load_motor_count * rig.load_motor.torque_constant * mean)
        return self.sim.sample()

    def analogue(self, m: Measurement, inputs: FilInputs) -> None:
        """Write the sensor readings into the harness inputs: mux channels [mV] and encoder counts."""
        sc = self.scaling
        codes_a = (sc.current_code(m.current_drive[0]), sc.current_code(m.current_load_1[0]),
                   sc.current_code(m.current_load_2[0]))
        codes_b = (sc.tacho_code(m.omega_worm[0], load=False), sc.tacho_code(m.omega_gear[0], load=True),
                   sc.tacho_code(m.omega_gear[0], load=True))
        for ch in range(3):
            inputs.mux_a_mv[ch] = adc_code_to_simavr_mv(codes_a[ch])
            inputs.mux_b_mv[ch] = adc_code_to_simavr_mv(codes_b[ch])
        inputs.enc_target[0] = int(m.count_drive[0])
        inputs.enc_target[1] = int(m.count_load_1[0])
        inputs.enc_target[2] = int(m.count_load_2[0])


@dataclass
class FilStatus:
    rig_time: float  #: [s] simulated time
    wall_time: float  #: [s] since the loop started
    avr_bytes: int
    host_bytes: int
    dropped: int
    duty: tuple[float, float, float]
    omega_worm: float  #: [rad/s] the plant's true worm speed

    @property
    def real_time_factor(self) -> float:
        return self.rig_time / self.wall_time if self.wall_time > 0 else float("nan")


class FirmwareInTheLoop:
    """Steps the harness and the plant together, never ahead of the wall clock.

    The host side (driver_node) keeps wall-clock timeouts and sends a keep-alive every
    20 ms of wall time; a rig running faster than real time would see gaps longer
    than its 50 ms watchdog, so the loop sleeps whenever rig time gets ahead.
    """

    def __init__(self, harness: FilHarness, plant: FilPlant) -> None:
        self.harness = harness
        self.plant = plant
        self.cycles = int(round(harness.frequency * plant.sim.sample_period))
        self.rig_time = 0.0
        self._start = time.monotonic()
        self._measurement: Measurement | None = None
        self.last = harness.outputs

    def step(self) -> FilOutputs:
        out = self.harness.step(self.cycles)
        self.last = out
        self._measurement = self.plant.step(tuple(out.duty))
        self.plant.analogue(self._measurement, self.harness.inputs)
        self.rig_time += self.plant.sim.sample_period
        ahead = self.rig_time - (time.monotonic() - self._start)
        if ahead > 0.002:
            time.sleep(ahead)
        return out

    def status(self) -> FilStatus:
        out = self.last
        return FilStatus(self.rig_time, time.monotonic() - self._start, out.avr_bytes, out.host_bytes, out.dropped,
                         tuple(out.duty), float(self.plant.sim.plant.state.omega_worm[0]))

    def stop_time_after_cut(self, timeout: float = 0.5) -> float:
        """Cut the host link and run until every bridge is off; returns the time [s] from the
        last host byte the AVR received to the bridges off (nan if not within `timeout` of rig time)."""
        self.harness.cut(True)
        end = self.rig_time + timeout
        while self.rig_time < end:
            out = self.step()
            if out.cut and out.stop_cycle:
                return (out.stop_cycle - out.cut_last_byte_cycle) / self.harness.frequency
        return float("nan")
