"""LinkCore without a port: handshake, conversion to SI, sequence gaps, timeouts, limits, keep-alives."""
from __future__ import annotations

import math
import random

import pytest

from worm_model.physics.parameters import load_rig
import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import StreamDecoder, encode_frame
from worm_rig_driver.link.core import (
    RIG_STATUS_DRIVE_LIMIT, RIG_STATUS_SENSOR_FAULT, RIG_STATUS_WATCHDOG_STOP, CommandLimits, LinkConfig, LinkCore,
    LinkState)
from worm_rig_driver.protocol.scaling import RigScaling

RIG = load_rig()
SCALING = RigScaling.from_rig(RIG)
LIMITS = CommandLimits(max_drive_voltage=12.0, max_load_torque=RIG.max_load_torque)
STATUS = {k: v for k, (v, _) in table.STATUS_BITS.items()}


class Rig:
    """The rig's side, by hand: frames in, frames out."""

    def __init__(self, core: LinkCore) -> None:
        self.core = core
        self.seq = 100
        self.host = StreamDecoder()

    def sent(self) -> list:
        return self.host.feed(self.core.take_output())

    def send(self, kind: str, now: float = 0.0, recv_ns: int = 10**12, **values):
        self.seq = (self.seq + 1) & 0xFFFF
        return self.core.on_bytes(encode_frame(kind, self.seq, **values), now, recv_ns)

    def telemetry(self, now: float = 0.0, recv_ns: int = 10**12, **overrides):
        values = dict(t_us=1000, current_drive=512, current_load_1=512, current_load_2=512, tacho_drive=512,
                      tacho_load_1=512, tacho_load_2=512, count_drive=0, count_load_1=0, count_load_2=0,
                      duty_drive=0, duty_load_1=0, duty_load_2=0, status=0, cmd_seq=0)
        values.update(overrides)
        return self.send("TELEMETRY", now, recv_ns, **values)


def up(config: LinkConfig = LinkConfig(), limits: CommandLimits = LIMITS) -> tuple[LinkCore, Rig]:
    core = LinkCore(SCALING, limits, config)
    rig = Rig(core)
    core.on_open(0.0)
    hello = rig.sent()[0]
    rig.send("HELLO_REPLY", version=table.PROTOCOL_VERSION, nonce=hello.payload.nonce, table_crc=table.TABLE_CRC,
             sample_rate_hz=1000, watchdog_ms=50, pwm_top=799)
    assert core.state is LinkState.UP
    return core, rig


def test_handshake_asks_for_the_stream_and_feeds_the_watchdog() -> None:
    core = LinkCore(SCALING, LIMITS, LinkConfig(stream_rate_hz=500))
    rig = Rig(core)
    core.on_open(0.0)
    [hello] = rig.sent()
    assert hello.name == "HELLO" and hello.payload.version == table.PROTOCOL_VERSION
    assert core.state is LinkState.HANDSHAKE
    rig.send("HELLO_REPLY", version=1, nonce=hello.payload.nonce, table_crc=table.TABLE_CRC,
             sample_rate_hz=1000, watchdog_ms=50, pwm_top=799)
    sent = rig.sent()
    assert [f.name for f in sent] == ["STREAM", "HEARTBEAT"]
    assert sent[0].payload.rate_hz == 500
    assert core.stats.handshakes == 1 and any("link up" in m for _, m in core.take_logs())


def test_unanswered_hello_is_resent() -> None:
    core = LinkCore(SCALING, LIMITS)
    rig = Rig(core)
    core.on_open(0.0)
    first = rig.sent()[0]
    core.poll(0.1)
    assert rig.sent() == []
    core.poll(0.25)
    [again] = rig.sent()
    assert again.name == "HELLO" and again.payload.nonce != first.payload.nonce
    # The late reply to the first HELLO does not count: it may be from before a reset.
    rig.send("HELLO_REPLY", version=1, nonce=first.payload.nonce, table_crc=table.TABLE_CRC,
             sample_rate_hz=1000, watchdog_ms=50, pwm_top=799)
    assert core.state is LinkState.HANDSHAKE and core.stats.unexpected_frames == 1
    assert core.stats.handshake_retries == 1


@pytest.mark.parametrize("version, crc", [(2, table.TABLE_CRC), (1, table.TABLE_CRC ^ 1)])
def test_other_protocol_or_table_is_incompatible(version: int, crc: int) -> None:
    core = LinkCore(SCALING, LIMITS)
    rig = Rig(core)
    core.on_open(0.0)
    hello = rig.sent()[0]
    rig.send("HELLO_REPLY", version=version, nonce=hello.payload.nonce, table_crc=crc, sample_rate_hz=1000,
             watchdog_ms=50, pwm_top=799)
    assert core.state is LinkState.INCOMPATIBLE
    assert [lvl for lvl, _ in core.take_logs()] == ["error"]
    assert core.drive(3.0, 0.1) is None and rig.sent() == []  # nothing is commanded
    assert core.stats.dropped_commands == 1
    core.poll(1.5)
    assert [f.name for f in rig.sent()] == ["HELLO"]  # a reflashed rig is picked up


def test_telemetry_becomes_si() -> None:
    core, rig = up()
    lsb = RIG.sensors.current_lsb
    [s] = rig.telemetry(t_us=5_000_000, current_drive=512 + 40, current_load_1=512 - 10, current_load_2=512 - 12,
                        tacho_drive=512 + 100, tacho_load_1=512 + 50, tacho_load_2=512 + 54, count_drive=4000,
                        count_load_1=-500, count_load_2=-498, duty_drive=2500, status=STATUS["SENSOR_FAULT"])
    assert s.seq == 5000  # the firmware tick of t_us = 5 s
    assert s.current_drive == pytest.approx(40 * lsb)
    assert (s.current_load_1, s.current_load_2) == pytest.approx((-10 * lsb, -12 * lsb))
    assert s.omega_worm == pytest.approx(100 * SCALING.tacho_drive_lsb)
    assert s.omega_gear == pytest.approx(52 * SCALING.tacho_load_lsb)
    assert s.theta_worm == pytest.approx(2 * 2 * math.pi)  # 4000 counts at 2000 counts/rev
    assert s.theta_gear == pytest.approx(-499 / 2000 * 2 * math.pi)
    assert s.voltage_drive == pytest.approx(0.25 * RIG.supply_voltage)
    kt = RIG.load_motor.torque_constant
    assert s.tau_load == pytest.approx(kt * (-22 * lsb) * RIG.load_motor_count / 2)
    assert (s.count_drive, s.count_load_1) == (4000, -500)
    assert s.status == RIG_STATUS_SENSOR_FAULT


def test_status_bits_map_to_rig_sample() -> None:
    core, rig = up()
    [s] = rig.telemetry(status=STATUS["DRIVE_LIMIT"] | STATUS["WATCHDOG_STOP"] | STATUS["ENCODER_ERROR"])
    assert s.status == RIG_STATUS_DRIVE_LIMIT | RIG_STATUS_WATCHDOG_STOP | RIG_STATUS_SENSOR_FAULT
    [s] = rig.telemetry(t_us=2000, status=STATUS["STOPPED"] | STATUS["RX_ERROR"])
    assert s.status == 0


def test_counters_unwrap_across_their_wrap() -> None:
    core, rig = up()
    t0 = 2**32 - 1000  # 1 ms before the firmware's microsecond clock wraps
    c0 = 2**31 - 3
    a = rig.telemetry(t_us=t0, count_drive=c0)[0]
    b = rig.telemetry(t_us=(t0 + 1000) % 2**32, count_drive=-(2**31) + 2)[0]  # +5 counts across the int32 wrap
    assert b.seq - a.seq == 1
    assert b.theta_worm - a.theta_worm == pytest.approx(5 * 2 * math.pi / 2000)
    assert b.count_drive == -(2**31) + 2  # raw counts stay raw (EncoderCounts wraps as int32)


def test_sequence_gaps_are_counted_with_the_frames_lost() -> None:
    core, rig = up()
    rig.telemetry()
    rig.seq += 7
    rig.telemetry(t_us=9000)
    rig.telemetry(t_us=10000)
    rig.seq += 1
    rig.telemetry(t_us=12000)
    assert core.stats.seq_gaps == 2 and core.stats.lost_frames == 8


def test_silence_is_a_timeout_and_a_new_handshake() -> None:
    core, rig = up(LinkConfig(rx_timeout=0.25))
    rig.sent()
    rig.telemetry(now=1.0)
    core.poll(1.2)
    assert core.state is LinkState.UP
    rig.sent()  # the keep-alive
    core.poll(1.3)
    assert core.state is LinkState.HANDSHAKE and core.stats.timeouts == 1
    assert [f.name for f in rig.sent()] == ["HELLO"]
    assert rig.telemetry(now=1.31) == []  # telemetry before the new handshake is not published
    assert core.stats.unexpected_frames == 1


@pytest.mark.parametrize("voltage, reason", [(12.5, "exceeds max_drive_voltage=12 V"), (-100.0, "exceeds"),
                                             (math.nan, "not finite"), (math.inf, "not finite")])
def test_drive_commands_beyond_the_limits_are_refused(voltage: float, reason: str) -> None:
    core, rig = up()
    rig.sent()
    assert reason in core.drive(voltage, 0.0)
    assert rig.sent() == [] and core.stats.rejected_commands == 1


def test_drive_and_load_commands_become_setpoints() -> None:
    core, rig = up()
    rig.sent()
    assert core.drive(-6.0, 0.0) is None
    [sp] = rig.sent()
    assert sp.name == "SETPOINT" and sp.payload.drive == -2500 and sp.payload.mode == 0b110
    assert core.load(0.1, 0.01) is None
    [sp] = rig.sent()
    per_motor = 0.1 / (RIG.load_motor_count * RIG.load_motor.torque_constant)
    assert sp.payload.load_1 == sp.payload.load_2 == round(per_motor / RIG.sensors.current_lsb)
    assert sp.payload.drive == -2500  # the drive target is kept


def test_load_commands_beyond_the_limits_are_refused() -> None:
    core, rig = up(limits=CommandLimits(12.0, max_load_torque=10.0))
    rig.sent()
    assert "exceeds max_load_torque" in core.load(-10.5, 0.0)
    assert "beyond the firmware's limit" in core.load(5.0, 0.0)  # 45 A per motor
    assert "not finite" in core.load(math.nan, 0.0)
    assert rig.sent() == [] and core.stats.rejected_commands == 3


def test_stale_drive_command_is_zeroed_by_the_host() -> None:
    core, rig = up(LinkConfig(command_timeout=0.5))
    core.drive(6.0, 1.0)
    rig.sent()
    rig.telemetry(now=1.4)
    core.poll(1.45)
    assert [f.name for f in rig.sent()] == ["SETPOINT"]  # keep-alive with the targets
    rig.telemetry(now=1.5, t_us=2000)
    core.poll(1.51)
    [stop] = rig.sent()
    assert stop.name == "HEARTBEAT" and core.watchdog_active  # all targets zero now
    [s] = rig.telemetry(now=1.52, t_us=3000)
    assert s.status & RIG_STATUS_WATCHDOG_STOP
    core.drive(1.0, 1.6)
    assert not core.watchdog_active


def test_keep_alive_every_heartbeat_period() -> None:
    core, rig = up()
    rig.sent()
    names = []
    for i in range(1, 11):
        now = i / 64  # exact in binary: no rounding at the period boundaries
        rig.telemetry(now=now, t_us=1000 * (i + 1))
        core.poll(now)
        names += [f.name for f in rig.sent()]
    assert names == ["HEARTBEAT"] * 5  # every 20 ms (every other 15.6 ms step) while idle


def test_rig_errors_are_counted_and_logged() -> None:
    core, rig = up()
    core.take_logs()
    rig.send("ERROR", ref_seq=12, ref_type=table.BY_NAME["SETPOINT"].code, code=4, detail=-12000)
    assert core.stats.rig_errors == 1 and core.rig_error_counts == {"OUT_OF_RANGE": 1}
    [(level, message)] = core.take_logs()
    assert level == "warn" and "SETPOINT seq 12: OUT_OF_RANGE (detail -12000)" in message


def test_port_loss_closes_the_link_and_holds_the_load_target() -> None:
    core, rig = up()
    core.load(0.1, 0.0)
    core.on_close(0.1, "EIO")
    assert core.state is LinkState.CLOSED and core.stats.disconnects == 1
    assert core.load(0.2, 0.2) is None
    core.on_open(0.3)
    hello = rig.sent()[-1]
    assert hello.name == "HELLO"
    rig.send("HELLO_REPLY", version=1, nonce=hello.payload.nonce, table_crc=table.TABLE_CRC,
             sample_rate_hz=1000, watchdog_ms=50, pwm_top=799)
    names = rig.sent()
    assert [f.name for f in names] == ["STREAM", "SETPOINT"]
    assert names[1].payload.load_1 == round(0.2 / (2 * RIG.load_motor.torque_constant) / RIG.sensors.current_lsb)


def test_any_bytes_in_any_state_never_raise() -> None:
    rng = random.Random(1)
    core, rig = up()
    for state_change in range(40):
        for _ in range(50):
            data = bytes(rng.randrange(256) for _ in range(rng.randrange(200)))
            core.on_bytes(data, 0.0, 0)
        if state_change % 3 == 0:
            core.on_close(0.0, "test")
            core.on_open(0.0)
        core.poll(rng.random() * 10)
    assert core.decoder.stats.bad_frames > 0
