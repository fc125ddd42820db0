"""virtual_rig: the simulated rig behind a pseudo-terminal, speaking the firmware's protocol byte for byte.

The real driver_node runs unchanged against it: point its ``port`` parameter at
the symlink this program makes (default /tmp/worm_rig), as it would point at
/dev/serial/by-id/... of the real board. sim_node stays the direct, topic-only path.

Two layers:

* :class:`VirtualFirmware` (no I/O, clock-explicit) is firmware/main.c's
  behaviour over a :class:`~worm_rig_driver.sim.simulated_rig.SimulatedRig`: the
  handshake, STREAM/SETPOINT/HEARTBEAT/STOP with the firmware's range checks
  and ERROR replies, the command watchdog, the PI current loops of motors in
  current mode (the firmware's gains and fixed-point arithmetic), the duty
  quantisation of motors_set(), TELEMETRY at the stream rate and STATS every
  second. Frames are built and parsed with the protocol's own codec
  (worm_rig_driver.protocol.codec, layouts from protocol_table); raw readings are the
  simulator's measurements turned into ADC codes with the driver's scaling.
* :func:`serve` binds it to a pty, paced by the wall clock (real time).

Simplifications, each small against the effects being studied:
  * duties take effect at the next tick (the firmware applies them ~0.6 ms
    into the period, when its ADC sequence is done);
  * the two load motors share one armature current (RigPlant's load state):
    each is driven by its own loop, the plant gets the mean of their targets,
    and each channel reads that current with its own noise;
  * a load motor's armature is the plant's first-order current lag with the
    motor's L/R: exact for a voltage held over a tick (Eq. 29), driven by the
    current (V + K_e omega_gear)/R its duty would settle to (its EMF opposes the
    gear's rotation with this sign convention);
  * disabled bridges leave the drive armature open: the plant gets the
    back-EMF as its voltage, so the current decays to zero and the worm coasts;
  * the line has no bit rate limit (a pty), and encoder errors, UART overruns
    and the stack are not simulated (reported as 0 / the firmware's budget).
"""
from __future__ import annotations

import os
import select
import signal
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from worm_model.cli.errors import run_tool
from worm_model.errors import InputError
from worm_model.cli.options import Parser, existing_file, integer, number, output_path
from worm_model.files.writing import unwritable
from worm_model.physics.parameters import load_rig

import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import Frame, StreamDecoder, encode_frame
from worm_rig_driver.protocol.scaling import RigScaling
from worm_rig_driver.sim.simulated_rig import SimulatedRig

FRAME = {f.name: f.code for f in table.FRAMES}
STATUS = {k: v for k, (v, _) in table.STATUS_BITS.items()}
ERROR = {k: v for k, (v, _) in table.ERROR_CODES.items()}
MOTORS = 3  # 0 drive, 1 load_1, 2 load_2
#: firmware/main.c current loop: duty units per ADC count of error, Q8 fixed point
KP_Q8 = 8 * 256
KI_Q8 = 4 * 256
CURRENT_DUTY_MAX = 9500
#: SRAM the firmware reports free (not simulated: the ATmega2560's 8 kB less a typical use)
STACK_FREE = 6000
#: Most ticks simulated at once when the process fell behind; beyond, the rig's clock is dilated.
MAX_CATCH_UP = 20


def motors_set(duty: int) -> int:
    """firmware/motors.c motors_set(): clamp, quantise to the 800 PWM steps, return the applied duty."""
    duty = max(-table.DUTY_FULL_SCALE, min(table.DUTY_FULL_SCALE, duty))
    steps = (abs(duty) * 2 + 12) // 25
    applied = (steps * 25 + 1) >> 1
    return -applied if duty < 0 else applied


@dataclass
class FirmwareLog:
    """What the virtual firmware received and did (for tests and the exit summary)."""

    frames: list[Frame] = field(default_factory=list)
    errors: list[tuple[str, str, int]] = field(default_factory=list)  #: (frame type, error, detail) sent
    telemetry_sent: int = 0
    stats_sent: int = 0


class VirtualFirmware:
    """firmware/main.c over a simulated rig: feed host bytes, tick once per ms, take the rig's bytes.

    Args:
        sim: a SimulatedRig with n = 1 (its sample period is the firmware tick); its plant's
            load-current lag is set to the load motor's L/R (the armature, see module docstring).
        version, table_crc: what HELLO_REPLY announces (change them to test a mismatch).
    """

    def __init__(self, sim: SimulatedRig, version: int = table.PROTOCOL_VERSION,
                 table_crc: int = table.TABLE_CRC) -> None:
        if sim.n != 1:
            raise ValueError(f"the virtual rig drives one simulated rig, got n={sim.n}")
        if round(1.0 / sim.sample_period) != table.SAMPLE_RATE_HZ:
            raise ValueError(f"the rig samples at {1 / sim.sample_period:g} Hz but the firmware ticks at "
                             f"{table.SAMPLE_RATE_HZ} Hz")
        self.sim = sim
        self.rig = sim.rig
        self.scaling = RigScaling.from_rig(sim.rig)
        load = sim.rig.load_motor
        sim.plant.load_current_time_constant = load.inductance / load.resistance  # armature L/R (Eq. 29)
        self.version, self.table_crc = version, table_crc
        self.decoder = StreamDecoder()
        self.log = FirmwareLog()
        self._out = bytearray()
        self.tick_ms = 0
        self.tx_seq = 0
        self.link_ready = False
        self.expected_seq = 0
        self.stream_divider = 0
        self.stream_countdown = 0
        self.enabled = False
        self.modes = 0
        self.targets = [0] * MOTORS
        self.integ = [0] * MOTORS
        self.applied = [0] * MOTORS
        self.last_cmd_ms = 0
        self.cmd_seq = 0
        self.status = STATUS["STOPPED"]
        self.sticky = 0
        self.rx_seq_gaps = 0
        self.watchdog_stops = 0
        self.last_stats_ms = 0
        self._bad_seen = 0
        self._apply_outputs(None)

    # --- bytes in and out ------------------------------------------------------------------------
    def take_output(self) -> bytes:
        """Bytes the rig has sent since the last call."""
        out, self._out = bytes(self._out), bytearray()
        return out

    def _send(self, kind: str, **values: int) -> None:
        ftype = table.BY_NAME[kind]
        full = {f.name: 0 for f in ftype.fields}  # fields added to the table later default to 0
        full.update({k: v for k, v in values.items() if k in full})
        self.tx_seq = (self.tx_seq + 1) & 0xFFFF
        self._out += encode_frame(kind, self.tx_seq, **full)

    def _error(self, frame: Frame, code: str, detail: int = 0) -> None:
        self.log.errors.append((table.BY_CODE[frame.code].name, code, detail))
        self._send("ERROR", ref_seq=frame.seq, ref_type=frame.code, code=ERROR[code], detail=detail)

    def receive(self, data: bytes) -> None:
        """Decode host bytes and act on every complete frame (the firmware's main loop)."""
        for frame in self.decoder.feed(data):
            self.log.frames.append(frame)
            self._on_frame(frame)
        bad = self.decoder.stats.bad_frames
        if bad != self._bad_seen:
            self._bad_seen = bad
            self.sticky |= STATUS["RX_ERROR"]

    # --- commands (main.c on_frame / on_setpoint) ----------------------------------------------------
    def _stop_all(self) -> None:
        self.enabled = False
        self.targets = [0] * MOTORS
        self.integ = [0] * MOTORS
        self.applied = [0] * MOTORS
        self.status |= STATUS["STOPPED"]

    def _on_frame(self, frame: Frame) -> None:
        code, seq = frame.code, frame.seq
        if code == FRAME["HELLO"]:
            self._stop_all()
            self.stream_divider = 0
            self.link_ready = True
            self.expected_seq = (seq + 1) & 0xFFFF
            self.status &= ~STATUS["WATCHDOG_STOP"]
            if frame.payload.version != table.PROTOCOL_VERSION:
                self._error(frame, "BAD_VERSION", table.PROTOCOL_VERSION)
            self._send("HELLO_REPLY", version=self.version, nonce=frame.payload.nonce, table_crc=self.table_crc,
                       sample_rate_hz=table.SAMPLE_RATE_HZ, watchdog_ms=table.WATCHDOG_MS, pwm_top=table.PWM_TOP)
            return
        if code >= 0x80:
            self._error(frame, "UNKNOWN_TYPE")
            return
        if not self.link_ready:
            self._error(frame, "NOT_READY")
            return
        if seq != self.expected_seq:
            self.rx_seq_gaps += 1
        self.expected_seq = (seq + 1) & 0xFFFF
        if code == FRAME["SETPOINT"]:
            self._on_setpoint(frame)
        elif code == FRAME["HEARTBEAT"]:
            self.last_cmd_ms = self.tick_ms
            self.cmd_seq = seq
        elif code == FRAME["STREAM"]:
            rate = frame.payload.rate_hz
            if rate > table.SAMPLE_RATE_HZ or (rate and table.SAMPLE_RATE_HZ % rate):
                self._error(frame, "BAD_RATE", rate)
                return
            self.stream_divider = table.SAMPLE_RATE_HZ // rate if rate else 0
            self.stream_countdown = 0
            self.last_stats_ms = self.tick_ms
            self._send("ACK", ack_seq=seq, ack_type=code)
        elif code == FRAME["STOP"]:
            self._stop_all()
            self.cmd_seq = seq
            self._send("ACK", ack_seq=seq, ack_type=code)
        else:
            self._error(frame, "UNKNOWN_TYPE")

    def _on_setpoint(self, frame: Frame) -> None:
        p = frame.payload
        values = (p.drive, p.load_1, p.load_2)
        for i, value in enumerate(values):
            limit = table.CURRENT_TARGET_LIMIT if p.mode >> i & 1 else table.DUTY_FULL_SCALE
            if abs(value) > limit:
                self._error(frame, "OUT_OF_RANGE", value)
                return
        for i, value in enumerate(values):
            if (self.modes ^ p.mode) >> i & 1:
                self.integ[i] = 0  # a motor changing mode starts its loop afresh
            self.targets[i] = value
        self.modes = p.mode & 0x07
        self.enabled = True
        self.status &= ~(STATUS["WATCHDOG_STOP"] | STATUS["STOPPED"])
        self.last_cmd_ms = self.tick_ms
        self.cmd_seq = frame.seq

    # --- the tick (main.c control_step) ---------------------------------------------------------------
    def _current_loop(self, i: int, measured: int) -> tuple[int, bool]:
        error = self.targets[i] - measured
        limit = CURRENT_DUTY_MAX << 8
        self.integ[i] = max(-limit, min(limit, self.integ[i] + KI_Q8 * error))
        u = (KP_Q8 * error + self.integ[i]) >> 8
        if abs(u) > CURRENT_DUTY_MAX:
            return (CURRENT_DUTY_MAX if u > 0 else -CURRENT_DUTY_MAX), True
        return u, False

    def _apply_outputs(self, omega_gear: float | None) -> None:
        """The bridges' outputs over the next tick, as plant commands."""
        sim, rig = self.sim, self.rig
        if not self.enabled:  # bridges off: armatures open, no current
            sim.command(voltage_drive=rig.drive_motor.back_emf_constant * float(sim.plant.state.omega_worm[0]),
                        load_torque=0.0)
            return
        sim.command(voltage_drive=self.scaling.voltage(self.applied[0]))
        load = rig.load_motor
        omega = 0.0 if omega_gear is None else omega_gear
        currents = [(self.scaling.voltage(self.applied[i]) + load.back_emf_constant * omega) / load.resistance
                    for i in (1, 2)]
        sim.command(load_torque=rig.load_motor_count * load.torque_constant * 0.5 * (currents[0] + currents[1]))

    def tick(self) -> None:
        """One firmware tick: the simulated rig runs one sample period, then the control step."""
        self.tick_ms += 1
        t = self.tick_ms
        m = self.sim.sample()
        sc = self.scaling
        currents = [sc.current_code(float(m.current_drive[0])), sc.current_code(float(m.current_load_1[0])),
                    sc.current_code(float(m.current_load_2[0]))]
        gear_speed = float(self.sim.plant.state.omega_gear[0])
        tachos = [sc.tacho_code(float(m.omega_worm[0]), load=False), sc.tacho_code(float(m.tacho_load_1[0]), load=True),
                  sc.tacho_code(float(m.tacho_load_2[0]), load=True)]
        counts = [int(m.count_drive[0]), int(m.count_load_1[0]), int(m.count_load_2[0])]

        if self.enabled and t - self.last_cmd_ms > table.WATCHDOG_MS:
            self._stop_all()
            self.status |= STATUS["WATCHDOG_STOP"]
            self.watchdog_stops += 1
        flags = 0
        for i in range(MOTORS):
            duty = 0
            if self.enabled:
                if self.modes >> i & 1:
                    duty, limited = self._current_loop(i, currents[i] - table.CURRENT_ZERO_CODE)
                    if limited:
                        flags |= STATUS["DRIVE_LIMIT"] if i == 0 else STATUS["LOAD_LIMIT"]
                else:
                    duty = self.targets[i]
            self.applied[i] = motors_set(duty)
            if currents[i] in (0, 1023) or tachos[i] in (0, 1023):
                flags |= STATUS["SENSOR_FAULT"]
        self._apply_outputs(gear_speed)

        if not self.stream_divider:
            return
        if self.stream_countdown == 0:
            self.stream_countdown = self.stream_divider
            self._send("TELEMETRY", t_us=(t * 1000) % 2**32,
                       current_drive=currents[0], current_load_1=currents[1], current_load_2=currents[2],
                       tacho_drive=tachos[0], tacho_load_1=tachos[1], tacho_load_2=tachos[2],
                       count_drive=counts[0], count_load_1=counts[1], count_load_2=counts[2],
                       duty_drive=self.applied[0], duty_load_1=self.applied[1], duty_load_2=self.applied[2],
                       status=self.status | self.sticky | flags, cmd_seq=self.cmd_seq)
            self.sticky = 0
            self.log.telemetry_sent += 1
        self.stream_countdown -= 1
        if t - self.last_stats_ms >= table.STATS_PERIOD_MS:
            self.last_stats_ms = t
            d = self.decoder.stats
            self._send("STATS", uptime_ms=t % 2**32, rx_frames=d.frames % 2**32, rx_crc_errors=d.crc_errors,
                       rx_cobs_errors=d.cobs_errors, rx_length_errors=(d.length_errors + d.unknown_types) & 0xFFFF,
                       rx_oversize=d.oversize, rx_overruns=0, rx_seq_gaps=self.rx_seq_gaps & 0xFFFF, tx_dropped=0,
                       watchdog_stops=self.watchdog_stops & 0xFFFF, encoder_errors=0, stack_free=STACK_FREE)
            self.log.stats_sent += 1



# --- the pseudo-terminal ---------------------------------------------------------------------------

class PtyPort:
    """A pty whose slave end is reachable through the symlink `link` (as a udev by-id link)."""

    def __init__(self, link: str) -> None:
        self.link = link
        self.master, self.slave = os.openpty()
        os.set_blocking(self.master, False)
        tty.setraw(self.slave)  # a serial line: no echo, no line discipline
        tmp = f"{link}.tmp{os.getpid()}"
        os.symlink(os.ttyname(self.slave), tmp)
        os.replace(tmp, link)
        self.dropped_bytes = 0

    def read(self) -> bytes:
        try:
            return os.read(self.master, 65536)
        except (BlockingIOError, OSError):  # nothing there (EIO: no reader attached yet)
            return b""

    def write(self, data: bytes) -> None:
        try:
            written = os.write(self.master, data)
        except (BlockingIOError, OSError):  # buffer full, nobody reading: lost, as from a full UART ring
            written = 0
        self.dropped_bytes += len(data) - written

    def wait(self, timeout: float) -> None:
        select.select([self.master], [], [], max(timeout, 0.0))

    def close(self) -> None:
        if os.path.islink(self.link) and os.readlink(self.link) == os.ttyname(self.slave):
            os.unlink(self.link)
        os.close(self.master)
        os.close(self.slave)


def serve(firmware: VirtualFirmware, port: PtyPort, stop: Callable[[], bool], duration: float = 0.0) -> dict[str, int]:
    """Run the firmware in real time on the port until stop() is true or `duration` [s] has passed.

    Returns counters: ticks run, ticks skipped because the process fell behind.
    """
    start = time.monotonic()
    period = firmware.sim.sample_period
    done_ticks = skipped = 0
    while not stop():
        now = time.monotonic()
        if duration and now - start >= duration:
            break
        firmware.receive(port.read())
        due = int((now - start) / period) - done_ticks - skipped
        if due > MAX_CATCH_UP:  # the rig's clock is dilated rather than run open-loop on stale commands
            skipped += due - MAX_CATCH_UP
            due = MAX_CATCH_UP
        for _ in range(max(due, 0)):
            firmware.tick()
            done_ticks += 1
        out = firmware.take_output()
        if out:
            port.write(out)
        next_tick = start + (done_ticks + skipped + 1) * period
        port.wait(next_tick - time.monotonic())
    return {"ticks": done_ticks, "skipped_ticks": skipped, "dropped_bytes": port.dropped_bytes}


def main(argv: list[str] | None = None) -> int:
    return run_tool("virtual_rig", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    parser = Parser(
        prog="virtual_rig",
        description="The simulated worm-gear rig behind a pseudo-terminal, speaking the rig firmware's serial "
                    "protocol (docs/protocol.md) byte for byte, in real time. Run driver_node with "
                    "port:=<LINK> against it.")
    parser.add_argument("--link", type=output_path, default="/tmp/worm_rig",
                        help="path of the symlink to the pty's slave end, the 'serial port' to give driver_node")
    parser.add_argument("--rig", type=existing_file, default=None,
                        help="rig parameter YAML (default: the bundled NMRV030 rig)")
    parser.add_argument("--effects", type=existing_file, default=None,
                        help="worm_rig_effects YAML: effects the model lacks, switched on in the simulator only "
                             "(see worm_effects --list)")
    parser.add_argument("--seed", type=integer(0, 2**32 - 1), default=0, help="seed of the sensor noise")
    parser.add_argument("--substeps", type=integer(1, 1000), default=1, help="integration steps per 1 ms tick")
    parser.add_argument("--duration", type=number("s", 0, 1e7), default=0.0,
                        help="stop after this many seconds (0: until SIGINT)")
    args = parser.parse_args(argv)
    link = Path(args.link)
    if link.exists() and not link.is_symlink():
        raise InputError(f"--link {link}", "exists and is not a symlink: refusing to replace it")
    if not link.absolute().parent.is_dir():
        raise InputError(f"--link {link}", f"folder {link.absolute().parent} does not exist")
    if problem := unwritable(link.absolute().parent):  # tried: permissions do not tell for root
        raise InputError(f"--link {link}", f"folder {link.absolute().parent}: cannot write there ({problem})")
    rig = load_rig(args.rig)
    sim = SimulatedRig(rig, n=1, seed=args.seed, substeps=args.substeps, effects=args.effects)
    firmware = VirtualFirmware(sim)
    stopping = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stopping.append(True))
    port = PtyPort(str(link))
    effects = ", ".join(sim.effects.names) or "none"
    print(f"virtual_rig: '{rig.name}' on {link} -> {os.ttyname(port.slave)} "
          f"(protocol v{table.PROTOCOL_VERSION}, table 0x{table.TABLE_CRC:04X}; effects: {effects})", flush=True)
    try:
        counters = serve(firmware, port, lambda: bool(stopping), args.duration)
    finally:
        port.close()
    print(f"virtual_rig: {counters['ticks']} ticks, {counters['skipped_ticks']} skipped (fell behind), "
          f"{firmware.log.telemetry_sent} telemetry frames, {len(firmware.log.frames)} host frames, "
          f"{firmware.decoder.stats.bad_frames} bad", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
