"""The driver's core: link state machine, command limits, telemetry -> SI samples, link statistics.

Transport-agnostic and clock-explicit (every call takes ``now`` [s, monotonic]),
so it is tested without a port; ``serial_link.SerialLink`` binds it to a
serial device and a reader thread, ``driver_node`` to the ROS graph. Not
thread-safe by itself: SerialLink serialises every call with one lock.

Link states::

    CLOSED --on_open--> HANDSHAKE --HELLO_REPLY ok--> UP --no frame for rx_timeout--> HANDSHAKE
       ^                   |  (HELLO resent every handshake_retry)        |
       +---- on_close -----+---------------------------------------------+
    HANDSHAKE --HELLO_REPLY with another version/table--> INCOMPATIBLE (HELLO retried every 1 s)

Commands: a DriveCommand voltage becomes the drive duty, a LoadCommand torque
the two load motors' current targets (the firmware closes the current loops).
Anything non-finite or beyond the configured limits is refused with a reason
and counted; nothing is clamped silently. While UP the host sends the targets
again (or a HEARTBEAT when all are zero) every heartbeat_period, which keeps
the firmware's watchdog fed and restores targets it dropped; a drive command
older than command_timeout is replaced by zero drive (like sim_node).
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass, field, fields
from enum import Enum

import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import Frame, StreamDecoder, encode_frame
from worm_rig_driver.protocol.scaling import RigScaling
from worm_model.rig_data.samples import RigSample

T = {f.name: f.code for f in table.FRAMES}
STATUS = {k: v for k, (v, _) in table.STATUS_BITS.items()}
ERROR_NAMES = {v: k for k, (v, _) in table.ERROR_CODES.items()}

#: worm_msgs/RigSample.STATUS_* (driver_node's test checks these equal the message's constants).
RIG_STATUS_DRIVE_LIMIT = 1
RIG_STATUS_WATCHDOG_STOP = 2
RIG_STATUS_SENSOR_FAULT = 4


class LinkState(Enum):
    CLOSED = "closed"
    HANDSHAKE = "handshake"
    UP = "up"
    INCOMPATIBLE = "incompatible"


@dataclass(frozen=True)
class LinkConfig:
    """Timing of the link (all [s] except the rate)."""

    stream_rate_hz: int = table.SAMPLE_RATE_HZ  #: telemetry rate asked for (0 or a divisor of 1000)
    rx_timeout: float = 0.25  #: no frame from the rig for this long while UP -> timeout, re-handshake
    handshake_retry: float = 0.2  #: HELLO resent this often while unanswered
    heartbeat_period: float = table.HEARTBEAT_PERIOD_MS / 1000.0
    command_timeout: float = 0.5  #: drive command age after which the drive is set to zero
    clock_max_drift: float = 0.005  #: [s/s] how fast the firmware clock may run slow vs the host's

    def __post_init__(self) -> None:
        if self.stream_rate_hz and table.SAMPLE_RATE_HZ % self.stream_rate_hz:
            raise ValueError(f"stream_rate_hz={self.stream_rate_hz} is not a divisor of {table.SAMPLE_RATE_HZ}")


@dataclass(frozen=True)
class CommandLimits:
    """Safe limits; a command beyond them is refused (not clamped)."""

    max_drive_voltage: float  #: [V] |DriveCommand.voltage|
    max_load_torque: float  #: [N m] |LoadCommand.torque|

    def drive_problem(self, voltage: float) -> str | None:
        if not math.isfinite(voltage):
            return f"voltage={voltage} is not finite"
        if abs(voltage) > self.max_drive_voltage:
            return f"|voltage|={abs(voltage):g} V exceeds max_drive_voltage={self.max_drive_voltage:g} V"
        return None

    def load_problem(self, torque: float) -> str | None:
        if not math.isfinite(torque):
            return f"torque={torque} is not finite"
        if abs(torque) > self.max_load_torque:
            return f"|torque|={abs(torque):g} N m exceeds max_load_torque={self.max_load_torque:g} N m"
        return None


@dataclass
class LinkStats:
    """Counters of the link since the driver started (decoder counters are in DecoderStats)."""

    telemetry: int = 0
    seq_gaps: int = 0  #: breaks in the rig's frame sequence
    lost_frames: int = 0  #: frames the gaps skipped
    timeouts: int = 0  #: no frame for rx_timeout while UP
    handshakes: int = 0  #: successful handshakes
    handshake_retries: int = 0  #: HELLOs resent unanswered
    connects: int = 0  #: port opened
    disconnects: int = 0  #: port lost (read/write error, hangup)
    rejected_commands: int = 0  #: refused by the limits
    dropped_commands: int = 0  #: arrived while the link was not UP
    rig_errors: int = 0  #: ERROR frames from the rig
    unexpected_frames: int = 0  #: frames not expected in the current state
    tx_frames: int = 0
    tx_dropped_bytes: int = 0  #: could not be written (port full)
    internal_errors: int = 0  #: exceptions from the publishing callbacks (printed once), survived

    def as_dict(self) -> dict[str, int]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


class Unwrapper:
    """Extends a wrapping unsigned/signed counter of `bits` to an unbounded int."""

    def __init__(self, bits: int, signed: bool) -> None:
        self.modulus = 1 << bits
        self.half = self.modulus >> 1
        self.signed = signed
        self.value: int | None = None

    def __call__(self, raw: int) -> int:
        if self.value is None:
            self.value = raw
        else:
            step = (raw - self.value) % self.modulus
            self.value += step - self.modulus if step >= self.half else step
        return self.value

    def reset(self) -> None:
        self.value = None


class ClockMapper:
    """Maps the firmware clock to host time: offset = the least (receive - firmware) time seen.

    The least transport delay is the best estimate of the offset; it may rise by
    at most clock_max_drift per second of firmware time (the firmware clock running
    slow), and falls at once to any smaller observation.
    """

    def __init__(self, max_drift: float) -> None:
        self.max_drift = max_drift
        self.offset_ns: float | None = None
        self._last_fw_ns = 0

    def stamp(self, fw_ns: int, recv_ns: int) -> int:
        observed = recv_ns - fw_ns
        if self.offset_ns is None:
            self.offset_ns = observed
        else:
            allowed = self.offset_ns + self.max_drift * max(fw_ns - self._last_fw_ns, 0)
            self.offset_ns = min(allowed, observed)
        self._last_fw_ns = fw_ns
        return int(fw_ns + self.offset_ns)

    def reset(self) -> None:
        self.offset_ns = None


@dataclass
class Targets:
    """What the host wants the firmware to apply (wire units)."""

    drive_duty: int = 0
    load_target: int = 0  #: per load motor, current counts from zero
    drive_time: float | None = None  #: when the last accepted drive command arrived [s]

    def idle(self) -> bool:
        return self.drive_duty == 0 and self.load_target == 0


@dataclass
class LinkCore:
    """The link's logic; see the module docstring."""

    scaling: RigScaling
    limits: CommandLimits
    config: LinkConfig = field(default_factory=LinkConfig)
    state: LinkState = LinkState.CLOSED
    stats: LinkStats = field(default_factory=LinkStats)
    decoder: StreamDecoder = field(default_factory=StreamDecoder)
    firmware_stats: dict[str, int] = field(default_factory=dict)
    firmware_info: dict[str, int] = field(default_factory=dict)
    rig_error_counts: dict[str, int] = field(default_factory=dict)
    watchdog_active: bool = False  #: the host dropped the drive (stale drive command)
    last_fw_status: int = 0

    def __post_init__(self) -> None:
        self.targets = Targets()
        self._out = bytearray()
        self._tx_seq = random.randrange(0x10000)
        self._rx_seq: int | None = None
        self._nonce = 0
        self._last_rx = 0.0
        self._last_hello = -math.inf
        self._last_keepalive = -math.inf
        self._t_us = Unwrapper(32, signed=False)
        self._counts = [Unwrapper(32, signed=True) for _ in range(3)]
        self._clock = ClockMapper(self.config.clock_max_drift)
        self._logs: list[tuple[str, str]] = []
        self._first_t_fw: float | None = None
        self._last_t_fw: float | None = None
        self._telemetry_in_span = 0

    # --- outputs to the transport and the log ---------------------------------------------
    def take_output(self) -> bytes:
        """Bytes to write to the port (and forget them)."""
        out = bytes(self._out)
        self._out.clear()
        return out

    def take_logs(self) -> list[tuple[str, str]]:
        """(level, message) pairs to log: level is "info", "warn" or "error"."""
        logs, self._logs = self._logs, []
        return logs

    def _log(self, level: str, message: str) -> None:
        self._logs.append((level, message))

    def _send(self, kind: str, **values: int) -> None:
        self._tx_seq = (self._tx_seq + 1) & 0xFFFF
        self._out += encode_frame(kind, self._tx_seq, **values)
        self.stats.tx_frames += 1

    # --- transport events -------------------------------------------------------------------
    def on_open(self, now: float) -> None:
        """The port was opened: start the handshake."""
        self.stats.connects += 1
        self.decoder.reset()  # a new connection starts a new stream (the counters go on)
        self._enter_handshake(now)

    def on_close(self, now: float, reason: str) -> None:
        """The port was lost or closed."""
        if self.state is not LinkState.CLOSED:
            self.stats.disconnects += 1
            self._log("warn", f"port lost: {reason}")
        self.state = LinkState.CLOSED
        self._out.clear()

    def _enter_handshake(self, now: float) -> None:
        self.state = LinkState.HANDSHAKE
        self._rx_seq = None
        self._last_rx = now
        self._send_hello(now)

    def _send_hello(self, now: float) -> None:
        self._nonce = (self._nonce + 1) & 0xFFFF
        self._send("HELLO", version=table.PROTOCOL_VERSION, nonce=self._nonce)
        self._last_hello = now

    # --- incoming bytes ---------------------------------------------------------------------
    def on_bytes(self, data: bytes, now: float, recv_ns: int) -> list[RigSample]:
        """Decode bytes read from the port at `now` (host time recv_ns [ns]); returns the new samples."""
        samples: list[RigSample] = []
        for frame in self.decoder.feed(data):
            self._last_rx = now
            if self.state is LinkState.UP:
                self._track_seq(frame.seq)
            code = frame.code
            if code == T["TELEMETRY"]:
                if self.state is LinkState.UP:
                    samples.append(self._sample(frame, recv_ns))
                else:
                    self.stats.unexpected_frames += 1
            elif code == T["HELLO_REPLY"]:
                self._on_hello_reply(frame, now)
            elif code == T["ERROR"]:
                self._on_error(frame)
            elif code == T["STATS"]:
                self.firmware_stats = frame.payload._asdict()
            elif code == T["ACK"]:
                pass
            else:  # a host -> rig frame coming back (a loop-back or a crossed wire)
                self.stats.unexpected_frames += 1
        return samples

    def _track_seq(self, seq: int) -> None:
        if self._rx_seq is not None:
            gap = (seq - self._rx_seq - 1) & 0xFFFF
            if gap:
                self.stats.seq_gaps += 1
                # A gap of more than half the range is a duplicate or a restart, not a loss.
                self.stats.lost_frames += gap if gap < 0x8000 else 0
        self._rx_seq = seq

    def _on_hello_reply(self, frame: Frame, now: float) -> None:
        reply = frame.payload
        if self.state not in (LinkState.HANDSHAKE, LinkState.INCOMPATIBLE) or reply.nonce != self._nonce:
            self.stats.unexpected_frames += 1  # an old reply: the HELLO it answers was resent since
            return
        self.firmware_info = reply._asdict()
        if reply.version != table.PROTOCOL_VERSION or reply.table_crc != table.TABLE_CRC:
            if self.state is not LinkState.INCOMPATIBLE:
                self._log("error", f"incompatible firmware: protocol v{reply.version} table 0x{reply.table_crc:04X}, "
                                   f"driver speaks v{table.PROTOCOL_VERSION} table 0x{table.TABLE_CRC:04X}; "
                                   "flash the firmware built from this tree")
            self.state = LinkState.INCOMPATIBLE
            return
        self.state = LinkState.UP
        self.stats.handshakes += 1
        self._rx_seq = frame.seq
        self._t_us.reset()
        self._clock.reset()
        self._first_t_fw = None
        self._log("info", f"link up: firmware protocol v{reply.version}, {reply.sample_rate_hz} Hz, "
                          f"watchdog {reply.watchdog_ms} ms; streaming at {self.config.stream_rate_hz} Hz")
        self._send("STREAM", rate_hz=self.config.stream_rate_hz)
        self._send_targets(now)

    def _on_error(self, frame: Frame) -> None:
        err = frame.payload
        name = ERROR_NAMES.get(err.code, f"code {err.code}")
        ref = table.BY_CODE[err.ref_type].name if err.ref_type in table.BY_CODE else f"type 0x{err.ref_type:02X}"
        self.stats.rig_errors += 1
        self.rig_error_counts[name] = self.rig_error_counts.get(name, 0) + 1
        self._log("warn", f"rig refused {ref} seq {err.ref_seq}: {name} (detail {err.detail})")

    def _sample(self, frame: Frame, recv_ns: int) -> RigSample:
        p = frame.payload
        sc = self.scaling
        self.stats.telemetry += 1
        t_us = self._t_us(p.t_us)
        t_fw = t_us * 1e-6
        if self._first_t_fw is None:
            self._first_t_fw = t_fw
            self._telemetry_in_span = 0
        else:
            self._telemetry_in_span += 1
        self._last_t_fw = t_fw
        c0 = self._counts[0](p.count_drive)
        c1 = self._counts[1](p.count_load_1)
        c2 = self._counts[2](p.count_load_2)
        i1, i2 = sc.current(p.current_load_1), sc.current(p.current_load_2)
        fw = p.status
        self.last_fw_status = fw
        status = ((RIG_STATUS_DRIVE_LIMIT if fw & STATUS["DRIVE_LIMIT"] else 0)
                  | (RIG_STATUS_WATCHDOG_STOP if fw & STATUS["WATCHDOG_STOP"] or self.watchdog_active else 0)
                  | (RIG_STATUS_SENSOR_FAULT if fw & (STATUS["SENSOR_FAULT"] | STATUS["ENCODER_ERROR"]) else 0))
        return RigSample(
            seq=t_us * table.SAMPLE_RATE_HZ // 1_000_000,
            stamp_ns=self._clock.stamp(t_us * 1000, recv_ns),
            current_drive=sc.current(p.current_drive), current_load_1=i1, current_load_2=i2,
            omega_worm=sc.tacho(p.tacho_drive, load=False),
            omega_gear=0.5 * (sc.tacho(p.tacho_load_1, load=True) + sc.tacho(p.tacho_load_2, load=True)),
            theta_worm=sc.angle(c0), theta_gear=sc.angle(0.5 * (c1 + c2)),
            count_drive=p.count_drive, count_load_1=p.count_load_1, count_load_2=p.count_load_2,
            voltage_drive=sc.voltage(p.duty_drive), tau_load=sc.load_torque(i1, i2),
            status=status)

    @property
    def telemetry_rate_hz(self) -> float:
        """Telemetry frames per second of firmware time since the link came up (nan before 2 frames)."""
        if self._first_t_fw is None or self._last_t_fw is None or self._last_t_fw <= self._first_t_fw:
            return math.nan
        return self._telemetry_in_span / (self._last_t_fw - self._first_t_fw)

    # --- time -------------------------------------------------------------------------------
    def poll(self, now: float) -> None:
        """Timeouts, handshake retries, the host-side drive watchdog and keep-alives."""
        cfg = self.config
        if self.state is LinkState.HANDSHAKE and now - self._last_hello >= cfg.handshake_retry:
            self.stats.handshake_retries += 1
            self._send_hello(now)
        elif self.state is LinkState.INCOMPATIBLE and now - self._last_hello >= 1.0:
            self._send_hello(now)
        elif self.state is LinkState.UP:
            if now - self._last_rx > cfg.rx_timeout:
                self.stats.timeouts += 1
                self._log("warn", f"no frame from the rig for {cfg.rx_timeout:g} s: handshaking again")
                self._enter_handshake(now)
                return
            drive = self.targets
            stale = drive.drive_time is None or now - drive.drive_time > cfg.command_timeout
            if stale and drive.drive_duty != 0:
                self._log("warn", f"no drive command for {cfg.command_timeout:g} s: drive set to zero")
                drive.drive_duty = 0
                self.watchdog_active = True
                self._send_targets(now)
            elif now - self._last_keepalive >= cfg.heartbeat_period:
                self._send_targets(now)

    def _send_targets(self, now: float) -> None:
        t = self.targets
        if t.idle():
            self._send("HEARTBEAT")
        else:
            self._send("SETPOINT", mode=0b110, drive=t.drive_duty, load_1=t.load_target, load_2=t.load_target)
        self._last_keepalive = now

    # --- commands ---------------------------------------------------------------------------
    def drive(self, voltage: float, now: float) -> str | None:
        """Forward a drive voltage [V]; returns why it was refused (None: sent)."""
        problem = self.limits.drive_problem(voltage)
        if problem is None and self.state is not LinkState.UP:
            self.stats.dropped_commands += 1
            return None
        if problem is not None:
            self.stats.rejected_commands += 1
            return problem
        self.targets.drive_duty = self.scaling.duty(voltage)
        self.targets.drive_time = now
        self.watchdog_active = False
        self._send_targets(now)
        return None

    def load(self, torque: float, now: float) -> str | None:
        """Set the load torque [N m] (held until changed); returns why it was refused (None: accepted)."""
        problem = self.limits.load_problem(torque)
        if problem is None:
            target = self.scaling.current_target(self.scaling.load_current_per_motor(torque))
            if abs(target) > table.CURRENT_TARGET_LIMIT:
                problem = (f"torque={torque:g} N m needs {abs(target)} current counts per motor, "
                           f"beyond the firmware's limit {table.CURRENT_TARGET_LIMIT}")
        if problem is not None:
            self.stats.rejected_commands += 1
            return problem
        self.targets.load_target = target
        if self.state is LinkState.UP:  # else held, and sent when the link comes up
            self._send_targets(now)
        return None

    def stop(self, now: float) -> None:
        """Zero every target and tell the rig to stop now (driver shutdown)."""
        self.targets = Targets()
        if self.state is LinkState.UP:
            self._send("STOP")

    # --- diagnostics ------------------------------------------------------------------------
    def report(self) -> dict[str, object]:
        """Flat key/value view of the link for diagnostics."""
        values: dict[str, object] = {"state": self.state.value}
        values.update(self.stats.as_dict())
        values.update({f"rx_{k}": v for k, v in self.decoder.stats.as_dict().items()})
        values["telemetry_rate_hz"] = round(self.telemetry_rate_hz, 2)
        values.update({f"fw_{k}": v for k, v in self.firmware_stats.items()})
        values.update({f"rig_error_{k}": v for k, v in self.rig_error_counts.items()})
        return values
