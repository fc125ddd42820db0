"""A Python rig that speaks the firmware's side of the protocol on a pseudo-terminal.

For tests and benchmarks of driver_node without hardware or simavr: it opens
a pty, makes `link` a symlink to its slave end (the path driver_node opens),
answers HELLO/STREAM/STOP, applies SETPOINTs with the firmware's range checks
and watchdog, and streams TELEMETRY at the requested rate, paced by the wall
clock. Faults on demand: garbage bytes, frames with a broken CRC, skipped
sequence numbers, silence, and unplug/replug (the pty closed and the symlink
removed, then a new pty behind the same path).

The telemetry is synthetic but tied to the commands, so a test can follow a
command through: duty_* echo the applied duties, the current channels read
the load current targets, and the encoder counts advance with the drive duty.
"""
from __future__ import annotations

import os
import select
import threading
import time
import tty
from dataclasses import dataclass, field

import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import StreamDecoder, encode_frame, pack_frame, encode_raw

T = {f.name: f.code for f in table.FRAMES}
S = {k: v for k, (v, _) in table.STATUS_BITS.items()}
E = {k: v for k, (v, _) in table.ERROR_CODES.items()}


@dataclass
class PeerLog:
    """What the peer received and did, for tests to check."""

    frames: list = field(default_factory=list)  #: every decoded host frame
    setpoints: list = field(default_factory=list)  #: accepted SETPOINT payloads
    refused: list = field(default_factory=list)  #: (frame type name, error name, detail)
    hellos: int = 0
    telemetry_sent: int = 0
    watchdog_stops: int = 0


class PtyRigPeer:
    """The rig's protocol on a pty; call start(), then the fault methods, then close()."""

    def __init__(self, link: str, version: int = table.PROTOCOL_VERSION, table_crc: int = table.TABLE_CRC) -> None:
        self.link = link
        self.version = version
        self.table_crc = table_crc
        self.log = PeerLog()
        self.decoder = StreamDecoder()
        self.lock = threading.Lock()
        self._master: int | None = None
        self._slave: int | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._seq = 0
        self._rate = 0
        self._ms = 0  # firmware time [ms]
        self._t0 = 0.0
        self._link_ready = False
        self._duty = [0, 0, 0]
        self._current_target = [0, 0, 0]
        self._counts = [0, 0, 0]
        self._last_cmd_ms = 0
        self._cmd_seq = 0
        self._status = S["STOPPED"]
        self._silent_until = 0.0
        self._corrupt = 0
        self._skip = 0
        self._pending = bytearray()
        self.plug()

    # --- the pty ---------------------------------------------------------------------------
    def plug(self) -> None:
        """Create a new pty behind `link` (the port appears)."""
        master, slave = os.openpty()
        os.set_blocking(master, False)
        tty.setraw(slave)  # no echo, no line editing: a serial line carries bytes as they are
        name = os.ttyname(slave)
        tmp = f"{self.link}.tmp"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(name, tmp)
        os.replace(tmp, self.link)
        with self.lock:
            self._master, self._slave = master, slave
            self.decoder.reset()
            self._link_ready = False
            self._rate = 0

    def unplug(self) -> None:
        """Close the pty and remove `link` (the port disappears, as a USB cable pulled)."""
        with self.lock:
            master, slave = self._master, self._slave
            self._master = self._slave = None
        if os.path.lexists(self.link):
            os.unlink(self.link)
        for fd in (master, slave):
            if fd is not None:
                os.close(fd)

    # --- faults ------------------------------------------------------------------------------
    def inject(self, data: bytes) -> None:
        """Send raw bytes (garbage) in the stream at once."""
        with self.lock:
            self._pending += data

    def corrupt_next(self, n: int) -> None:
        """Flip one bit in the CRC of the next n frames."""
        with self.lock:
            self._corrupt += n

    def skip_seq(self, n: int) -> None:
        """Skip n sequence numbers before the next frame (as if n frames were lost)."""
        with self.lock:
            self._skip += n

    def silence(self, seconds: float) -> None:
        """Send nothing for `seconds` (frames due meanwhile are not sent)."""
        with self.lock:
            self._silent_until = time.monotonic() + seconds

    @property
    def streaming(self) -> bool:
        return self._link_ready and self._rate > 0

    # --- the thread --------------------------------------------------------------------------
    def start(self) -> None:
        self._t0 = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="rig-peer", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self.unplug()

    def _run(self) -> None:
        while not self._stop.is_set():
            master = self._master
            if master is None:
                time.sleep(0.002)
                self._advance_clock(send=False)
                continue
            try:
                readable, _, _ = select.select([master], [], [], 0.0005)
                data = os.read(master, 65536) if readable else b""
            except OSError:  # EIO while no process holds the slave open: nothing to read
                data = b""
            with self.lock:
                for frame in self.decoder.feed(data):
                    self._handle(frame)
            self._advance_clock(send=True)
            time.sleep(0.0005)

    def _advance_clock(self, send: bool) -> None:
        now_ms = int((time.monotonic() - self._t0) * 1000)
        with self.lock:
            while self._ms < now_ms:
                self._ms += 1
                self._tick()
            out, self._pending = bytes(self._pending), bytearray()
            master = self._master
        if send and out and master is not None and time.monotonic() >= self._silent_until:
            try:
                os.write(master, out)
            except OSError:  # pty buffer full (nobody reading): dropped, as a UART would
                pass

    # --- firmware behaviour ---------------------------------------------------------------
    def _frame(self, kind: str, **values: int) -> None:
        self._seq = (self._seq + 1 + self._skip) & 0xFFFF
        self._skip = 0
        if self._corrupt:
            self._corrupt -= 1
            raw = bytearray(pack_frame(kind, self._seq, **values))
            raw[-1] ^= 0x01
            self._pending += encode_raw(bytes(raw))
        else:
            self._pending += encode_frame(kind, self._seq, **values)

    def _tick(self) -> None:
        if self._link_ready and any(self._duty) and self._ms - self._last_cmd_ms > table.WATCHDOG_MS:
            self._duty = [0, 0, 0]
            self._current_target = [0, 0, 0]
            self._status |= S["WATCHDOG_STOP"] | S["STOPPED"]
            self.log.watchdog_stops += 1
        self._counts[0] = (self._counts[0] + self._duty[0] // 100 + 2**31) % 2**32 - 2**31
        if not self.streaming or self._ms % (table.SAMPLE_RATE_HZ // self._rate):
            return
        if time.monotonic() < self._silent_until:
            return
        zero = table.CURRENT_ZERO_CODE
        self._frame("TELEMETRY", t_us=(self._ms * 1000) % 2**32,
                    current_drive=zero, current_load_1=zero + self._current_target[1],
                    current_load_2=zero + self._current_target[2], tacho_drive=table.TACHO_ZERO_CODE,
                    tacho_load_1=table.TACHO_ZERO_CODE, tacho_load_2=table.TACHO_ZERO_CODE,
                    count_drive=self._counts[0], count_load_1=0, count_load_2=0,
                    duty_drive=self._duty[0], duty_load_1=self._duty[1], duty_load_2=self._duty[2],
                    status=self._status, cmd_seq=self._cmd_seq)
        self.log.telemetry_sent += 1

    def _refuse(self, frame, code: str, detail: int = 0) -> None:
        self.log.refused.append((table.BY_CODE[frame.code].name, code, detail))
        self._frame("ERROR", ref_seq=frame.seq, ref_type=frame.code, code=E[code], detail=detail)

    def _handle(self, frame) -> None:
        self.log.frames.append(frame)
        code = frame.code
        if code == T["HELLO"]:
            self.log.hellos += 1
            self._link_ready = True
            self._rate = 0
            self._duty = [0, 0, 0]
            self._current_target = [0, 0, 0]
            self._status = S["STOPPED"]
            self._frame("HELLO_REPLY", version=self.version, nonce=frame.payload.nonce, table_crc=self.table_crc,
                        sample_rate_hz=table.SAMPLE_RATE_HZ, watchdog_ms=table.WATCHDOG_MS, pwm_top=table.PWM_TOP)
            return
        if code >= 0x80:
            self._refuse(frame, "UNKNOWN_TYPE")
            return
        if not self._link_ready:
            self._refuse(frame, "NOT_READY")
            return
        if code == T["STREAM"]:
            rate = frame.payload.rate_hz
            if rate and table.SAMPLE_RATE_HZ % rate:
                self._refuse(frame, "BAD_RATE", rate)
                return
            self._rate = rate
            self._frame("ACK", ack_seq=frame.seq, ack_type=code)
        elif code == T["SETPOINT"]:
            p = frame.payload
            values = (p.drive, p.load_1, p.load_2)
            for i, v in enumerate(values):
                limit = table.CURRENT_TARGET_LIMIT if p.mode >> i & 1 else table.DUTY_FULL_SCALE
                if abs(v) > limit:
                    self._refuse(frame, "OUT_OF_RANGE", v)
                    return
            self.log.setpoints.append(p)
            for i, v in enumerate(values):
                if p.mode >> i & 1:
                    self._current_target[i] = v
                    self._duty[i] = v * 20  # a stand-in for the current loop's output
                else:
                    self._current_target[i] = 0
                    self._duty[i] = v
            self._status &= ~(S["WATCHDOG_STOP"] | S["STOPPED"])
            self._last_cmd_ms = self._ms
            self._cmd_seq = frame.seq
        elif code == T["HEARTBEAT"]:
            self._last_cmd_ms = self._ms
            self._cmd_seq = frame.seq
        elif code == T["STOP"]:
            self._duty = [0, 0, 0]
            self._current_target = [0, 0, 0]
            self._status |= S["STOPPED"]
            self._cmd_seq = frame.seq
            self._frame("ACK", ack_seq=frame.seq, ack_type=code)
