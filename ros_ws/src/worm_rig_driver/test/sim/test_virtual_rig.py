"""VirtualFirmware: the simulated rig behind the firmware's protocol (virtual_rig.py).

Host frames are built with the protocol's codec and the rig's replies decoded with
it; expectations come from the protocol table, firmware/main.c's rules and the
physics (steady state of Eqs 28-30), never from a recorded run.
"""
from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_model.physics.steady_state import steady_worm_speed
import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import StreamDecoder, encode_frame, encode_raw, pack_frame
from worm_rig_driver.protocol.scaling import RigScaling
from worm_rig_driver.sim.simulated_rig import SimulatedRig
from worm_rig_driver.sim.virtual_rig import PtyPort, VirtualFirmware, motors_set, serve

RIG = load_rig()
SC = RigScaling.from_rig(RIG)
STATUS = {k: v for k, (v, _) in table.STATUS_BITS.items()}
ERROR = {k: v for k, (v, _) in table.ERROR_CODES.items()}
LOAD_MODE = 0b110  # the driver's: drive in duty mode, both load motors in current mode


class Host:
    """The host's side in a test: numbered frames out, decoded frames in."""

    def __init__(self, seed: int = 0) -> None:
        self.fw = VirtualFirmware(SimulatedRig(RIG, n=1, seed=seed))
        self.decoder = StreamDecoder()
        self.seq = 0
        self.received: list = []

    def send(self, kind: str, **values: int) -> int:
        self.seq += 1
        self.fw.receive(encode_frame(kind, self.seq, **values))
        return self.seq

    def ticks(self, n: int, keepalive: dict | None = None) -> list:
        """Run n ticks (refreshing the watchdog with `keepalive` SETPOINTs every 20 ms); return new frames."""
        new = []
        for k in range(n):
            if keepalive is not None and k % 20 == 0:
                self.send("SETPOINT", **keepalive)
            self.fw.tick()
            new += self.decoder.feed(self.fw.take_output())
        self.received += new
        return new

    def replies(self) -> list:
        new = self.decoder.feed(self.fw.take_output())
        self.received += new
        return new

    def up(self, rate: int = 1000) -> None:
        self.send("HELLO", version=table.PROTOCOL_VERSION, nonce=7)
        self.send("STREAM", rate_hz=rate)
        self.replies()


def _telemetry(frames) -> list:
    return [f.payload for f in frames if f.name == "TELEMETRY"]


def test_motors_set_is_the_firmware_quantisation() -> None:
    for duty in (0, 1, 6, 7, 2500, -2500, 3333, -4999, 9999, 10000, 12000, -20000):
        applied = motors_set(duty)
        clamped = max(-10000, min(10000, duty))
        steps = round(abs(clamped) * (table.PWM_TOP + 1) / table.DUTY_FULL_SCALE + 1e-9)  # nearest of 800 steps
        assert abs(applied) == pytest.approx(steps * table.DUTY_FULL_SCALE / (table.PWM_TOP + 1), abs=0.5)
        assert np.sign(applied) == np.sign(clamped) or applied == 0


def test_handshake_stream_rates_and_refusals() -> None:
    host = Host()
    host.send("SETPOINT", mode=0, drive=100, load_1=0, load_2=0)  # before HELLO
    host.send("HELLO", version=table.PROTOCOL_VERSION + 1, nonce=1234)
    frames = host.replies()
    assert [f.name for f in frames] == ["ERROR", "ERROR", "HELLO_REPLY"]
    assert frames[0].payload.code == ERROR["NOT_READY"]
    assert frames[1].payload.code == ERROR["BAD_VERSION"] and frames[1].payload.detail == table.PROTOCOL_VERSION
    reply = frames[2].payload
    assert (reply.version, reply.nonce, reply.table_crc) == (table.PROTOCOL_VERSION, 1234, table.TABLE_CRC)
    assert (reply.sample_rate_hz, reply.watchdog_ms, reply.pwm_top) == (table.SAMPLE_RATE_HZ, table.WATCHDOG_MS,
                                                                         table.PWM_TOP)
    assert host.ticks(10) == []  # no stream yet
    bad = host.send("STREAM", rate_hz=7)
    ok = host.send("STREAM", rate_hz=250)
    frames = host.replies()
    assert frames[0].name == "ERROR" and frames[0].payload.code == ERROR["BAD_RATE"]
    assert frames[0].payload.ref_seq == bad and frames[0].payload.detail == 7
    assert frames[1].name == "ACK" and (frames[1].payload.ack_seq, frames[1].payload.ack_type) == (ok, 0x04)
    telemetry = _telemetry(host.ticks(40))
    assert len(telemetry) == 10 and np.all(np.diff([t.t_us for t in telemetry]) == 4000)  # every 4th tick
    # a rig -> host type sent to the rig
    host.fw.receive(encode_frame("ACK", 99, ack_seq=1, ack_type=1))
    frame = host.replies()[0]
    assert frame.name == "ERROR" and frame.payload.code == ERROR["UNKNOWN_TYPE"]


def test_telemetry_carries_the_simulated_measurement_in_raw_units() -> None:
    host = Host(seed=3)
    captured = []
    sample = host.fw.sim.sample

    def recording_sample():
        captured.append(sample())
        return captured[-1]

    host.fw.sim.sample = recording_sample
    host.up()
    keep = dict(mode=LOAD_MODE, drive=SC.duty(8.0), load_1=30, load_2=30)
    telemetry = _telemetry(host.ticks(300, keep))
    assert len(telemetry) == len(captured) == 300
    for t, m in zip(telemetry, captured):
        assert SC.current(t.current_drive) == pytest.approx(m.current_drive[0], abs=1e-12)
        assert SC.current(t.current_load_1) == pytest.approx(m.current_load_1[0], abs=1e-12)
        assert SC.current(t.current_load_2) == pytest.approx(m.current_load_2[0], abs=1e-12)
        assert SC.tacho(t.tacho_drive, load=False) == pytest.approx(m.omega_worm[0], abs=1e-9)
        assert SC.tacho(t.tacho_load_1, load=True) == pytest.approx(m.tacho_load_1[0], abs=1e-9)
        assert (t.count_drive, t.count_load_1, t.count_load_2) == (m.count_drive[0], m.count_load_1[0],
                                                                   m.count_load_2[0])
    assert telemetry[-1].duty_drive == motors_set(SC.duty(8.0)) and telemetry[-1].status == 0
    assert [t.t_us for t in telemetry[:3]] == [1000, 2000, 3000]


def test_the_rig_turns_at_the_model_speed_and_the_load_loops_hold_the_torque() -> None:
    host = Host(seed=1)
    host.up()
    torque = 0.1
    per_motor = SC.current_target(SC.load_current_per_motor(torque))
    keep = dict(mode=LOAD_MODE, drive=SC.duty(6.0), load_1=per_motor, load_2=per_motor)
    telemetry = _telemetry(host.ticks(800, keep))
    late = telemetry[400:]
    omega = np.mean([SC.tacho(t.tacho_drive, load=False) for t in late])
    tau = np.mean([SC.load_torque(SC.current(t.current_load_1), SC.current(t.current_load_2)) for t in late])
    applied_voltage = SC.voltage(motors_set(SC.duty(6.0)))
    true_tau = float(host.fw.sim.truth().tau_load[0])
    assert omega == pytest.approx(steady_worm_speed(RIG, applied_voltage, true_tau), abs=0.3)
    # the firmware's PI loops hold each load current on its target (integral action: zero mean error)
    for name in ("current_load_1", "current_load_2"):
        codes = np.array([getattr(t, name) for t in late]) - table.CURRENT_ZERO_CODE
        assert abs(codes.mean() - per_motor) < 0.3
    assert tau == pytest.approx(torque, abs=0.005)
    assert all(t.status & STATUS["LOAD_LIMIT"] == 0 for t in late)


def test_the_watchdog_stops_everything_and_the_drive_coasts() -> None:
    host = Host()
    host.up()
    host.send("SETPOINT", mode=LOAD_MODE, drive=SC.duty(12.0), load_1=20, load_2=20)
    frames = host.ticks(table.WATCHDOG_MS)  # no refresh, but not yet late
    assert _telemetry(frames)[-1].duty_drive != 0
    frames = host.ticks(5)
    last = _telemetry(frames)[-1]
    assert last.status & STATUS["WATCHDOG_STOP"] and last.status & STATUS["STOPPED"]
    assert (last.duty_drive, last.duty_load_1, last.duty_load_2) == (0, 0, 0)
    # bridges off: the armature is open, the current dies within a few L/R and the worm coasts on
    late = _telemetry(host.ticks(30))[-1]
    assert abs(SC.current(late.current_drive)) <= 2 * RIG.sensors.current_lsb
    assert SC.tacho(late.tacho_drive, load=False) > 10.0
    stats = [f.payload for f in host.ticks(1000) if f.name == "STATS"]
    assert stats and stats[-1].watchdog_stops == 1
    # a new SETPOINT re-enables
    host.send("SETPOINT", mode=0, drive=SC.duty(3.0), load_1=0, load_2=0)
    assert _telemetry(host.ticks(2))[-1].status & (STATUS["STOPPED"] | STATUS["WATCHDOG_STOP"]) == 0


def test_out_of_range_setpoints_are_refused_and_stop_acks() -> None:
    host = Host()
    host.up()
    good = dict(mode=LOAD_MODE, drive=1000, load_1=10, load_2=10)
    host.ticks(5, good)
    bad = host.send("SETPOINT", mode=LOAD_MODE, drive=1000, load_1=table.CURRENT_TARGET_LIMIT + 1, load_2=10)
    frames = host.replies()
    assert frames[0].name == "ERROR" and frames[0].payload.code == ERROR["OUT_OF_RANGE"]
    assert (frames[0].payload.ref_seq, frames[0].payload.detail) == (bad, table.CURRENT_TARGET_LIMIT + 1)
    assert host.fw.targets == [1000, 10, 10]  # unchanged
    stop = host.send("STOP")
    frames = host.replies()
    assert frames[0].name == "ACK" and frames[0].payload.ack_seq == stop
    last = _telemetry(host.ticks(2))[-1]
    assert last.status & STATUS["STOPPED"] and last.duty_drive == 0 and last.cmd_seq == stop


def test_corrupt_frames_are_counted_and_flagged_once() -> None:
    host = Host()
    host.up()
    raw = bytearray(pack_frame("HEARTBEAT", 50))
    raw[-1] ^= 1
    host.fw.receive(b"\x13\x37garbage\x00" + encode_raw(bytes(raw)))
    telemetry = _telemetry(host.ticks(3))
    assert telemetry[0].status & STATUS["RX_ERROR"] and not telemetry[1].status & STATUS["RX_ERROR"]
    stats = [f.payload for f in host.ticks(1000) if f.name == "STATS"]
    assert stats[-1].rx_crc_errors == 1 and stats[-1].rx_cobs_errors + stats[-1].rx_length_errors >= 1


def test_the_pty_serves_the_protocol_in_real_time(tmp_path) -> None:
    link = str(tmp_path / "rig")
    firmware = VirtualFirmware(SimulatedRig(RIG, n=1))
    port = PtyPort(link)
    stop = threading.Event()
    counters = {}
    thread = threading.Thread(target=lambda: counters.update(serve(firmware, port, stop.is_set, 5.0)))
    thread.start()
    fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(fd, encode_frame("HELLO", 1, version=table.PROTOCOL_VERSION, nonce=9)
                 + encode_frame("STREAM", 2, rate_hz=100))
        decoder, frames = StreamDecoder(), []
        deadline = time.monotonic() + 5.0
        while len([f for f in frames if f.name == "TELEMETRY"]) < 5 and time.monotonic() < deadline:
            frames += decoder.feed(os.read(fd, 4096))
        names = [f.name for f in frames]
        assert names[:2] == ["HELLO_REPLY", "ACK"] and names.count("TELEMETRY") >= 5
        assert decoder.stats.bad_frames == 0
    finally:
        os.close(fd)
        stop.set()
        thread.join(5.0)
        port.close()
    assert counters["ticks"] > 0 and not os.path.lexists(link)
