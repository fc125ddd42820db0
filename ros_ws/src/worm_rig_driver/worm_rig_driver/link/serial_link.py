"""Binds a LinkCore to a serial device: a reader thread that owns the port and reconnects.

Why a thread (and not a non-blocking read in an executor timer): the port is
read the moment bytes arrive (select() wakes the thread), so the latency of a
sample does not depend on a timer period or on what else the executor is
doing; opening a port that is missing (reconnect attempts every
reconnect_period) never stalls the executor; and at 1 kHz one thread doing
select/read/decode costs less than waking a timer often enough for the same
latency. The executor thread only calls command(), which takes the same lock.

Plain Python (pyserial opens and configures the port; select/os.read on its
descriptor); no rclpy. Any OSError on the port (EIO
when a USB adapter or a pty master goes away, ENOENT while it is absent) closes
it and the thread retries every reconnect_period.
"""
from __future__ import annotations

import errno
import os
import select
import threading
import time
import traceback
from collections.abc import Callable

import serial

from worm_model.rig_data.samples import RigSample
from worm_rig_driver.link.core import LinkCore

# Standard rates a 16 MHz AVR reaches with U2X (1 Mbaud exactly: UBRR = 1) and Linux names.
SUPPORTED_BAUDS = (115200, 230400, 460800, 500000, 1000000, 2000000)


def open_port(path: str, baud: int) -> serial.Serial:
    """Open a serial device with pyserial: raw 8N1, no flow control, non-blocking, exclusive.

    Raises:
        OSError: the port is missing, busy (another driver holds it) or refuses the settings
            (pyserial's SerialException is an OSError).
    """
    port = serial.Serial(path, baudrate=baud, bytesize=serial.EIGHTBITS, parity=serial.PARITY_NONE,
                         stopbits=serial.STOPBITS_ONE, xonxoff=False, rtscts=False, dsrdtr=False,
                         timeout=0, exclusive=True)
    try:
        port.reset_input_buffer()  # bytes from before we opened belong to nobody's frame
    except BaseException:
        port.close()
        raise
    return port


class SerialLink:
    """Reader thread + port ownership around a LinkCore.

    Args:
        path: serial device (e.g. /dev/ttyACM0, a /dev/serial/by-id link, a pty symlink).
        core: the link logic.
        on_samples: called from the reader thread with each batch of new samples.
        on_log: called (level, message) for the core's log lines, from either thread.
        baud: one of SUPPORTED_BAUDS.
        reconnect_period: [s] between attempts to open a missing port.
        poll_period: [s] longest sleep of the reader (timeouts and keep-alives are checked this often).
        on_thread_start: called first thing in the reader thread (e.g. to ask for real-time scheduling).
    """

    def __init__(self, path: str, core: LinkCore, on_samples: Callable[[list[RigSample]], None],
                 on_log: Callable[[str, str], None], baud: int = 1_000_000,
                 reconnect_period: float = 0.1, poll_period: float = 0.005,
                 on_thread_start: Callable[[], None] | None = None) -> None:
        if baud not in SUPPORTED_BAUDS:
            raise ValueError(f"baud={baud} is not one of {SUPPORTED_BAUDS}")
        self.path = path
        self.core = core
        self.on_samples = on_samples
        self.on_log = on_log
        self.baud = baud
        self.reconnect_period = reconnect_period
        self.poll_period = poll_period
        self.on_thread_start = on_thread_start
        self.lock = threading.Lock()
        self._port: serial.Serial | None = None
        self._fd: int | None = None  # the port's descriptor, read with select/os.read
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="rig-serial", daemon=True)
        self._last_open_error = ""

    # --- lifecycle ------------------------------------------------------------------------
    def start(self) -> None:
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Tell the rig to stop, close the port, join the thread."""
        with self.lock:
            self.core.stop(time.monotonic())
            self._flush()
        self._stop.set()
        self._thread.join(timeout)
        with self.lock:
            self._close("driver stopped")

    # --- commands (any thread) -------------------------------------------------------------
    def command(self, apply: Callable[[LinkCore, float], str | None]) -> str | None:
        """Run `apply(core, now)` under the lock and write what it produced; returns its refusal reason."""
        with self.lock:
            reason = apply(self.core, time.monotonic())
            self._flush()
        self._drain_logs()
        return reason

    def report(self) -> dict[str, object]:
        with self.lock:
            values = self.core.report()
        values["port"] = self.path
        return values

    # --- the thread -------------------------------------------------------------------------
    def _run(self) -> None:
        if self.on_thread_start is not None:
            self.on_thread_start()
        while not self._stop.is_set():
            if self._fd is None:
                if not self._try_open():
                    self._stop.wait(self.reconnect_period)
                    continue
            fd = self._fd
            try:
                readable, _, _ = select.select([fd], [], [], self.poll_period)
                data = os.read(fd, 65536) if readable else b""
                if readable and not data:
                    raise OSError(errno.EIO, "end of file on the port")
            except (OSError, ValueError) as err:  # ValueError: fd closed under us by stop()
                with self.lock:
                    self._close(str(err))
                self._drain_logs()
                continue
            now = time.monotonic()
            recv_ns = time.time_ns()
            with self.lock:
                samples = self.core.on_bytes(data, now, recv_ns) if data else []
                self.core.poll(now)
                self._flush()
            try:
                if samples:
                    self.on_samples(samples)
                self._drain_logs()
            except Exception:  # noqa: BLE001 - a bug downstream must not end the thread that owns the port
                self.core.stats.internal_errors += 1
                if self.core.stats.internal_errors == 1:
                    traceback.print_exc()

    def _try_open(self) -> bool:
        try:
            port = open_port(self.path, self.baud)
        except OSError as err:
            message = f"cannot open {self.path}: {err.strerror or err}"
            if message != self._last_open_error:  # log each kind of failure once, not every 0.1 s
                self.on_log("warn", message)
                self._last_open_error = message
            return False
        self._last_open_error = ""
        with self.lock:
            self._port, self._fd = port, port.fileno()
            self.core.on_open(time.monotonic())
            self._flush()
        self.on_log("info", f"opened {self.path} at {self.baud} baud")
        self._drain_logs()
        return True

    def _flush(self) -> None:
        """Write the core's pending bytes (caller holds the lock); a full port drops them, counted."""
        out = self.core.take_output()
        if not out or self._fd is None:
            return
        try:
            written = os.write(self._fd, out)
        except BlockingIOError:
            written = 0
        except OSError as err:
            self._close(str(err))
            return
        if written < len(out):
            self.core.stats.tx_dropped_bytes += len(out) - written

    def _close(self, reason: str) -> None:
        """Caller holds the lock."""
        if self._port is not None:
            try:
                self._port.close()
            except OSError:
                pass
            self._port = self._fd = None
            self.core.on_close(time.monotonic(), reason)

    def _drain_logs(self) -> None:
        with self.lock:
            logs = self.core.take_logs()
        for level, message in logs:
            self.on_log(level, message)
