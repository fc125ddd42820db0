"""The rig's sensors as the firmware reads them (paper section 3.1).

Analogue: Hall-effect armature current sensors (one per motor) and
tachogenerators (one per motor) go through two SN74HC4051 8:1 analogue
multiplexers into the 10-bit ADC of the ATmega2560. The ADC converts one
channel at a time, so within one sample period every channel is sampled at its
own instant (:class:`AdcChain`): the firmware's tick latches the encoders and
starts the sequence, channel k is held 1.5 ADC clocks into its conversion.
Every number of the chain (noise, resolutions, ripple, ADC timing) is the rig
file's ``sensors:`` section (worm_model.physics.parameters.Sensors), which the
estimators read too.
Each reading is: true signal -> sensor effects (gain, offset, PWM ripple; see
sim/effects/sensing.py) -> noise -> 10-bit quantisation with the converter's range limits.

Digital: 500 pulse/rev two-channel encoders decoded 4x into counts that wrap
as int32, latched at the tick.

Vectorised over an ensemble of rigs; plain numpy. Signs follow plant.py:
positive worm rotation is the reference and gear quantities are referred to it.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from worm_model.physics.parameters import ADC_SEQUENCE, Rig, Sensors, load_rig

from worm_rig_driver.protocol.table import ADC_BITS
from worm_rig_driver.sim.effects import EffectStack, SenseContext
from worm_rig_driver.sim.plant import PlantOutputs, PlantState

STATUS_DRIVE_LIMIT = 1
STATUS_SIMULATED = 8


@dataclass(frozen=True)
class AdcChannel:
    """One analogue line: which signal, on which multiplexer input."""

    signal: str  # effects.SIGNALS name
    mux: int  # 0 = first SN74HC4051 (currents), 1 = second (tachos)
    mux_input: int  # 0..7, the 3-bit address the firmware sets


#: Multiplexer (0: A, the currents, on one ADC input; 1: B, the tachos, on the other) and input of each
#: signal (firmware/board.h): motor i on address i of both.
MUX_INPUTS = {"current_drive": (0, 0), "tacho_drive": (1, 0), "current_load_1": (0, 1), "tacho_load_1": (1, 1),
              "current_load_2": (0, 2), "tacho_load_2": (1, 2)}
#: The channels in the firmware's conversion order (worm_model.physics.parameters.ADC_SEQUENCE,
#: firmware/adc_mux.c): for each motor its current, then its tacho.
DEFAULT_CHANNELS = tuple(AdcChannel(signal, *MUX_INPUTS[signal]) for signal in ADC_SEQUENCE)


@dataclass(frozen=True)
class AdcChain:
    """Multiplexers + the ATmega2560's 10-bit successive-approximation ADC: which channel is converted when.

    Timing: the rig file's (rig.sensors.adc_clock_hz, adc_conversion_cycles, adc_hold_cycles;
    ATmega2560 datasheet, ADC chapter: a conversion takes 13 ADC clock cycles and the input is
    held 1.5 cycles after its start; the firmware's prescaler 128 at 16 MHz gives a 125 kHz ADC
    clock, so 104 us per channel), the channels converted one after the other in ``channels``
    order. The SN74HC4051's switching time (~tens of ns) is negligible against that. The
    firmware starts the next conversion from the ADC interrupt; its few microseconds of latency
    are neglected.

    Scaling (the driver's too, worm_rig_driver.protocol.scaling, so that simulator and driver
    agree): each Hall channel reads (code - 512) x rig.sensors.current_lsb over codes 0..1023
    (zero current at mid-scale); each tacho channel (code - 512) x its shaft's lsb
    (rig.sensors.tacho_drive_lsb on the worm shaft, tacho_load_lsb on the gear shaft).
    """

    bits: int = ADC_BITS
    channels: tuple[AdcChannel, ...] = DEFAULT_CHANNELS

    @property
    def codes(self) -> int:
        return 2 ** self.bits

    def sample_times(self, sensors: Sensors | None = None) -> dict[str, float]:
        """Signal -> instant [s] after the tick at which its channel is held, with the ADC timing of
        ``sensors`` (None: the bundled rig's)."""
        return (sensors or load_rig().sensors).sample_times(tuple(ch.signal for ch in self.channels))

    def sequence_time(self, sensors: Sensors | None = None) -> float:
        """[s] from the tick to the end of the last conversion (``sensors``' timing; None: the bundled rig's)."""
        return (sensors or load_rig().sensors).sequence_time(len(self.channels))


@dataclass
class Measurement:
    """One sample of every rig channel, as worm_msgs/RigSample carries it; arrays of shape (n,)."""

    current_drive: np.ndarray  # [A]
    current_load_1: np.ndarray  # [A]
    current_load_2: np.ndarray  # [A]
    omega_worm: np.ndarray  # [rad/s] drive tacho
    omega_gear: np.ndarray  # [rad/s] mean of the load tachos
    theta_worm: np.ndarray  # [rad] from the drive encoder, unwrapped
    theta_gear: np.ndarray  # [rad] from the load encoders, unwrapped
    count_drive: np.ndarray  # [count] int32, wraps
    count_load_1: np.ndarray
    count_load_2: np.ndarray
    voltage_drive: np.ndarray  # [V]
    tau_load: np.ndarray  # [N m] K_t,load x measured load currents
    status: np.ndarray  # uint32 bit set (RigSample.STATUS_*)
    tacho_load_1: np.ndarray | None = None  # [rad/s] each load tacho (omega_gear is their mean)
    tacho_load_2: np.ndarray | None = None


class Trajectory:
    """The plant's state at the substep boundaries of one sample period, for sampling at any instant.

    Args:
        duration: length of the period [s]; the states are equally spaced over it.
        states: name -> array (k+1, n) of the values at 0, duration/k, ..., duration
            (k = 0: one state held over the period). Names: current_drive,
            current_load, omega_worm, theta_worm, omega_gear, theta_gear.
    """

    def __init__(self, duration: float, states: Mapping[str, np.ndarray]) -> None:
        self.duration = duration
        self.states = states
        self.steps = len(next(iter(states.values()))) - 1

    @classmethod
    def held(cls, state: PlantState, ratio: float) -> "Trajectory":
        """One state held over the period (sensor tests, or a measurement without a history)."""
        omega_gear, theta_gear = state.gear(ratio)
        values = {"current_drive": state.current_drive, "current_load": state.current_load,
                  "omega_worm": state.omega_worm, "theta_worm": state.theta_worm,
                  "omega_gear": omega_gear, "theta_gear": theta_gear}
        return cls(0.0, {k: np.asarray(v, dtype=float)[None, :] for k, v in values.items()})

    def at(self, name: str, time: float) -> np.ndarray:
        """Value of `name` at `time` [s] after the period's start, linearly interpolated."""
        values = self.states[name]
        if self.steps == 0:
            return values[0]
        x = min(max(time / self.duration, 0.0), 1.0) * self.steps
        k = min(int(x), self.steps - 1)
        frac = x - k
        return values[k] + frac * (values[k + 1] - values[k]) if frac else values[k]


def wrap_int32(counts: np.ndarray) -> np.ndarray:
    """Wrap integer counts to signed 32 bit, as a free-running hardware counter does."""
    return ((np.asarray(counts, dtype=np.int64) + 2**31) % 2**32 - 2**31).astype(np.int32)


class SensorModel:
    """Turns the plant's true trajectory into what the rig's sensors report.

    Args:
        rig: rig parameters (noise, resolution, encoder, sample rate).
        rng: the only source of randomness (the sensor noise).
        effects: live effects whose `sense` hook changes the analogue signals.
        adc: the multiplexers' channel order and the ADC's resolution (timing and scaling: rig.sensors).

    Raises:
        ValueError: the ADC sequence does not fit in one sample period.
    """

    def __init__(self, rig: Rig, rng: np.random.Generator, effects: EffectStack | None = None,
                 adc: AdcChain = AdcChain()) -> None:
        self.rig = rig
        self.rng = rng
        self.effects = effects
        self.adc = adc
        sensors = rig.sensors
        self.counts_per_rev = sensors.encoder_pulses_per_rev * sensors.encoder_decoding
        self.sample_period = 1.0 / sensors.sample_rate_hz
        sequence = adc.sequence_time(sensors)
        if sequence > self.sample_period:
            raise ValueError(f"the ADC sequence ({len(adc.channels)} channels x {sensors.adc_conversion_cycles} "
                             f"cycles at {sensors.adc_clock_hz:g} Hz = {sequence * 1e6:.0f} us) does not fit in the "
                             f"sample period ({self.sample_period * 1e6:.0f} us)")
        self.sample_time = adc.sample_times(sensors)
        #: [rad/s] per ADC code of the drive tacho and of the gear-shaft (load) tachos
        self.tacho_lsb = {"tacho_drive": sensors.tacho_drive_lsb, "tacho_load_1": sensors.tacho_load_lsb,
                          "tacho_load_2": sensors.tacho_load_lsb}
        #: tacho ripple periods per shaft turn
        self.ripple_order = sensors.tacho_ripple_order

    # --- one channel -------------------------------------------------------------------------------
    def _adc(self, signal: np.ndarray, lsb: float) -> np.ndarray:
        """10-bit conversion around mid-scale: nearest code, clipped to the converter's range."""
        half = self.adc.codes // 2
        # (minimum/maximum: np.clip's dispatch costs more than the work for a single rig)
        return np.minimum(np.maximum(np.round(signal / lsb), -half), half - 1) * lsb

    def _current(self, signal: np.ndarray) -> np.ndarray:
        sensors = self.rig.sensors
        noisy = signal + self.rng.normal(0.0, sensors.current_noise_std, np.shape(signal))
        return self._adc(noisy, sensors.current_lsb)

    def _tacho(self, signal: np.ndarray, name: str) -> np.ndarray:
        noisy = signal + self.rng.normal(0.0, self.rig.sensors.tacho_noise_std, np.shape(signal))
        return self._adc(noisy, self.tacho_lsb[name])

    def _encoder(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Counts (wrapped int32) and the angle they resolve [rad]."""
        counts = np.floor(theta * self.counts_per_rev / (2.0 * np.pi)).astype(np.int64)
        return wrap_int32(counts), counts * (2.0 * np.pi / self.counts_per_rev)

    # --- a whole sample -------------------------------------------------------------------------------
    def true_signals(self, trajectory: Trajectory) -> dict[str, np.ndarray]:
        """Each analogue channel's true value at its own sampling instant (before effects and noise).

        Tachos: omega (1 + ripple sin(p theta)) of their own shaft, p = rig.sensors.tacho_ripple_order.
        """
        t = self.sample_time
        ripple, order = self.rig.sensors.tacho_ripple, self.ripple_order

        def tacho(omega_name: str, theta_name: str, at: float) -> np.ndarray:
            omega, theta = trajectory.at(omega_name, at), trajectory.at(theta_name, at)
            return omega * (1.0 + ripple * np.sin(order * theta))

        return {
            "current_drive": trajectory.at("current_drive", t["current_drive"]),
            "current_load_1": trajectory.at("current_load", t["current_load_1"]),
            "current_load_2": trajectory.at("current_load", t["current_load_2"]),
            "tacho_drive": tacho("omega_worm", "theta_worm", t["tacho_drive"]),
            "tacho_load_1": tacho("omega_gear", "theta_gear", t["tacho_load_1"]),
            "tacho_load_2": tacho("omega_gear", "theta_gear", t["tacho_load_2"]),
        }

    def measure_period(self, trajectory: Trajectory, outputs: PlantOutputs, tick: float = 0.0) -> Measurement:
        """Sample every channel of every rig over one period that started at sim time `tick` [s]."""
        rig = self.rig
        signals = self.true_signals(trajectory)
        if self.effects is not None and self.effects.has_sense:
            context = SenseContext({k: tick + v for k, v in self.sample_time.items()}, outputs.voltage_drive,
                                   rig.supply_voltage)
            self.effects.sense(signals, context)
        current_drive = self._current(signals["current_drive"])
        load_1 = self._current(signals["current_load_1"])
        load_2 = self._current(signals["current_load_2"])
        tacho_drive = self._tacho(signals["tacho_drive"], "tacho_drive")
        tacho_load_1 = self._tacho(signals["tacho_load_1"], "tacho_load_1")
        tacho_load_2 = self._tacho(signals["tacho_load_2"], "tacho_load_2")
        count_drive, theta_worm = self._encoder(trajectory.at("theta_worm", 0.0))
        count_load, theta_gear = self._encoder(trajectory.at("theta_gear", 0.0))
        status = np.where(outputs.drive_saturated, STATUS_DRIVE_LIMIT, 0) | STATUS_SIMULATED
        return Measurement(
            current_drive=current_drive,
            current_load_1=load_1,
            current_load_2=load_2,
            omega_worm=tacho_drive,
            omega_gear=0.5 * (tacho_load_1 + tacho_load_2),
            theta_worm=theta_worm,
            theta_gear=theta_gear,
            count_drive=count_drive,
            count_load_1=count_load,
            count_load_2=count_load.copy(),
            voltage_drive=outputs.voltage_drive.copy(),
            tau_load=rig.load_motor.torque_constant * (load_1 + load_2) * rig.load_motor_count / 2.0,
            status=status.astype(np.uint32),
            tacho_load_1=tacho_load_1,
            tacho_load_2=tacho_load_2,
        )

    def measure(self, state: PlantState, outputs: PlantOutputs) -> Measurement:
        """Sample every channel of every rig with `state` held over the whole period."""
        return self.measure_period(Trajectory.held(state, self.rig.gearbox.ratio), outputs)
