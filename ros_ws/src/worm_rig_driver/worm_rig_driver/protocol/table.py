"""The serial protocol between driver_node and the ATmega2560 rig firmware: the one table.

Every frame type, every field with its C type, unit and scale, and the link
constants live here. Everything else is derived from it:

* the Python codec (``worm_rig_driver.protocol.codec``) builds its struct layouts from it;
* the firmware's C header ``firmware/protocol_frames.h`` is generated from it
  (``python -m worm_rig_driver.protocol.table --header firmware/protocol_frames.h``)
  and a test checks that the committed header equals the generated one;
* the frame table of ``docs/protocol.md`` is generated from it the same way
  (``--markdown``) and checked by the same test.

Adding a frame or a field is adding a row here, regenerating, and handling it
in the firmware's ``main.c`` and in ``link.py``.

Wire format (docs/protocol.md has the full spec): a frame is
``type:u8 | seq:u16 | payload | crc:u16``, multi-byte fields little-endian,
the CRC-16/XMODEM of type..payload appended big-endian; the frame is COBS
encoded and terminated by one 0x00 byte.

Version history:
    1: first version (HELLO/SETPOINT/HEARTBEAT/STREAM/STOP; TELEMETRY/HELLO_REPLY/ACK/ERROR/STATS).
"""
from __future__ import annotations

import argparse
import binascii
import struct
import sys
from dataclasses import dataclass
from pathlib import Path

PROTOCOL_VERSION = 1

# --- link constants -----------------------------------------------------------------
F_CPU_HZ = 16_000_000  #: ATmega2560 clock [Hz] (Arduino Mega 2560 crystal)
BAUD = 1_000_000  #: [bit/s] 8N1
U2X = 1  #: double-speed mode: UBRR = F_CPU / (8 BAUD) - 1
UBRR = F_CPU_HZ // (8 * BAUD) - 1  #: = 1, exact: 16e6 / (8 * 2) = 1e6 (0 % error)
SAMPLE_RATE_HZ = 1000  #: firmware control/sample tick [Hz]
WATCHDOG_MS = 50  #: firmware stops every motor this long after the last valid SETPOINT/HEARTBEAT [ms]
HEARTBEAT_PERIOD_MS = 20  #: host sends a HEARTBEAT at least this often while the link is up [ms]
STATS_PERIOD_MS = 1000  #: firmware sends STATS this often while streaming [ms]
DUTY_FULL_SCALE = 10000  #: duty 1.0 on the wire (int16 -10000..10000, 1e-4 per unit)
PWM_TOP = 799  #: ICR of timers 4/5 in fast PWM mode 14: 16 MHz / 800 = 20 kHz, 800 duty steps
ADC_BITS = 10
ADC_REF_MV = 5000  #: AVCC reference [mV]
CURRENT_ZERO_CODE = 512  #: ADC code of zero armature current (Hall sensor output at VCC/2)
TACHO_ZERO_CODE = 512  #: ADC code of zero speed (tacho conditioning offset to VCC/2)
CURRENT_TARGET_LIMIT = 400  #: |current target| the firmware accepts [ADC counts from zero]

HEADER_LEN = 3  #: type u8 + seq u16
CRC_LEN = 2

#: C type -> (struct format char, size in bytes).
C_TYPES: dict[str, tuple[str, int]] = {
    "uint8_t": ("B", 1), "int8_t": ("b", 1),
    "uint16_t": ("H", 2), "int16_t": ("h", 2),
    "uint32_t": ("I", 4), "int32_t": ("i", 4),
}


@dataclass(frozen=True)
class Field:
    """One payload field: wire type, physical meaning and how to scale it."""

    name: str
    ctype: str  #: a key of C_TYPES
    unit: str  #: unit of the physical quantity after scaling ("1" for counts/flags)
    scale: str  #: how a wire value becomes that quantity
    doc: str

    @property
    def fmt(self) -> str:
        return C_TYPES[self.ctype][0]

    @property
    def size(self) -> int:
        return C_TYPES[self.ctype][1]


@dataclass(frozen=True)
class FrameType:
    """One frame type: its code, who sends it, and its payload fields in wire order."""

    name: str
    code: int
    sender: str  #: "host" or "rig"
    doc: str
    fields: tuple[Field, ...] = ()

    @property
    def payload_len(self) -> int:
        return sum(f.size for f in self.fields)

    @property
    def struct_format(self) -> str:
        return "<" + "".join(f.fmt for f in self.fields)


_ADC = "ADC count 0..1023, 5000/1024 mV per count"
_CURRENT = f"{_ADC}; I = (code - {CURRENT_ZERO_CODE}) x current_lsb (rig parameter sensors.current_lsb)"
_TACHO = f"{_ADC}; omega = (code - {TACHO_ZERO_CODE}) x tacho lsb (worm_rig_driver.protocol.scaling)"
_COUNT = "1 count; 4x decoded, counts_per_rev = 4 x encoder_pulses_per_rev; wraps as int32"
_DUTY = f"1/{DUTY_FULL_SCALE} of the supply (signed: + drives the RPWM side)"
_TARGET = (f"duty mode: {_DUTY}; current mode: ADC counts from zero current "
           f"(x current_lsb = A), |value| <= {CURRENT_TARGET_LIMIT}")

FRAMES: tuple[FrameType, ...] = (
    # --- host -> rig ---------------------------------------------------------------
    FrameType("HELLO", 0x01, "host", "Start (or restart) the link: the rig stops its motors and streaming, "
              "resets its receive sequence and answers HELLO_REPLY.", (
                  Field("version", "uint16_t", "1", "protocol version", "protocol version the host speaks"),
                  Field("nonce", "uint16_t", "1", "opaque", "echoed in HELLO_REPLY to pair request and reply"),
              )),
    FrameType("SETPOINT", 0x02, "host", "Targets of the three motors; refreshes the watchdog when accepted. "
              "No reply: TELEMETRY.cmd_seq echoes the last accepted command; ERROR if refused.", (
                  Field("mode", "uint8_t", "1", "bit set", "bit i set: motor i (0 drive, 1 load_1, 2 load_2) "
                        "in current mode, else duty mode"),
                  Field("drive", "int16_t", "1 or A", _TARGET, "drive motor (worm shaft) target"),
                  Field("load_1", "int16_t", "1 or A", _TARGET, "load motor 1 (gear shaft) target"),
                  Field("load_2", "int16_t", "1 or A", _TARGET, "load motor 2 (gear shaft) target"),
              )),
    FrameType("HEARTBEAT", 0x03, "host", "Keeps the watchdog from stopping the motors; changes nothing else."),
    FrameType("STREAM", 0x04, "host", "Set the telemetry rate; answered by ACK (or ERROR BAD_RATE).", (
        Field("rate_hz", "uint16_t", "Hz", "1 Hz", f"0 = off, else a divisor of {SAMPLE_RATE_HZ}"),
    )),
    FrameType("STOP", 0x05, "host", "Zero every target and disable the bridges at once; answered by ACK."),
    # --- rig -> host ---------------------------------------------------------------
    FrameType("TELEMETRY", 0x81, "rig", "One synchronized sample of every channel, at the stream rate.", (
        Field("t_us", "uint32_t", "s", "1e-6 s; wraps after 71.6 min", "firmware time of the sample tick"),
        Field("current_drive", "uint16_t", "A", _CURRENT, "drive armature current (Hall sensor, mux A ch 0)"),
        Field("current_load_1", "uint16_t", "A", _CURRENT, "load 1 armature current (mux A ch 1)"),
        Field("current_load_2", "uint16_t", "A", _CURRENT, "load 2 armature current (mux A ch 2)"),
        Field("tacho_drive", "uint16_t", "rad/s", _TACHO, "drive tachogenerator (mux B ch 0)"),
        Field("tacho_load_1", "uint16_t", "rad/s", _TACHO, "load 1 tachogenerator (mux B ch 1)"),
        Field("tacho_load_2", "uint16_t", "rad/s", _TACHO, "load 2 tachogenerator (mux B ch 2)"),
        Field("count_drive", "int32_t", "rad", _COUNT, "drive encoder (worm shaft)"),
        Field("count_load_1", "int32_t", "rad", _COUNT, "load 1 encoder (gear shaft)"),
        Field("count_load_2", "int32_t", "rad", _COUNT, "load 2 encoder (gear shaft)"),
        Field("duty_drive", "int16_t", "1", _DUTY, "duty applied to the drive bridge (0 when stopped)"),
        Field("duty_load_1", "int16_t", "1", _DUTY, "duty applied to load bridge 1"),
        Field("duty_load_2", "int16_t", "1", _DUTY, "duty applied to load bridge 2"),
        Field("status", "uint16_t", "1", "bit set", "STATUS_* bits"),
        Field("cmd_seq", "uint16_t", "1", "frame seq", "seq of the last accepted SETPOINT/HEARTBEAT/STOP"),
    )),
    FrameType("HELLO_REPLY", 0x82, "rig", "Answer to HELLO: what the firmware speaks and how it is set up.", (
        Field("version", "uint16_t", "1", "protocol version", "protocol version the firmware speaks"),
        Field("nonce", "uint16_t", "1", "opaque", "the HELLO's nonce"),
        Field("table_crc", "uint16_t", "1", "CRC-16/XMODEM", "checksum of the frame table the firmware was built from"),
        Field("sample_rate_hz", "uint16_t", "Hz", "1 Hz", "control/sample tick"),
        Field("watchdog_ms", "uint16_t", "s", "1e-3 s", "command watchdog timeout"),
        Field("pwm_top", "uint16_t", "1", "timer counts", "PWM period - 1 (duty resolution)"),
    )),
    FrameType("ACK", 0x83, "rig", "A STREAM or STOP was applied.", (
        Field("ack_seq", "uint16_t", "1", "frame seq", "seq of the acknowledged frame"),
        Field("ack_type", "uint8_t", "1", "frame type", "type of the acknowledged frame"),
    )),
    FrameType("ERROR", 0x84, "rig", "A well-formed frame was refused (corrupt frames are only counted, in STATS).", (
        Field("ref_seq", "uint16_t", "1", "frame seq", "seq of the refused frame"),
        Field("ref_type", "uint8_t", "1", "frame type", "type of the refused frame"),
        Field("code", "uint8_t", "1", "ERR_* code", "why"),
        Field("detail", "int16_t", "1", "code-specific", "e.g. the offending value"),
    )),
    FrameType("STATS", 0x85, "rig", f"Firmware link and health counters, every {STATS_PERIOD_MS} ms while "
              "streaming; counters are totals since reset and wrap.", (
                  Field("uptime_ms", "uint32_t", "s", "1e-3 s", "time since reset"),
                  Field("rx_frames", "uint32_t", "1", "count", "host frames accepted"),
                  Field("rx_crc_errors", "uint16_t", "1", "count", "host frames with a bad CRC"),
                  Field("rx_cobs_errors", "uint16_t", "1", "count", "segments that are not valid COBS"),
                  Field("rx_length_errors", "uint16_t", "1", "count", "frames too short or of the wrong length"),
                  Field("rx_oversize", "uint16_t", "1", "count", "segments longer than any frame"),
                  Field("rx_overruns", "uint16_t", "1", "count", "bytes lost: receive ring full or UART overrun"),
                  Field("rx_seq_gaps", "uint16_t", "1", "count", "breaks in the host's frame sequence"),
                  Field("tx_dropped", "uint16_t", "1", "count", "frames not sent: transmit ring full"),
                  Field("watchdog_stops", "uint16_t", "1", "count", "motor stops by the command watchdog"),
                  Field("encoder_errors", "uint16_t", "1", "count", "encoder edges too close together to decode"),
                  Field("tick_overruns", "uint16_t", "1", "count",
                        "samples lost: the ADC sequence or the control step not done by the next tick"),
                  Field("stack_free", "uint16_t", "B", "1 byte", "SRAM never touched by the stack since reset"),
              )),
)

#: Status bits of TELEMETRY.status.
STATUS_BITS: dict[str, tuple[int, str]] = {
    "DRIVE_LIMIT": (1 << 0, "the drive duty was clamped (current loop saturated or max duty)"),
    "WATCHDOG_STOP": (1 << 1, "motors stopped by the watchdog: no valid command for WATCHDOG_MS"),
    "SENSOR_FAULT": (1 << 2, "an ADC channel read 0 or 1023 (open or shorted sensor)"),
    "ENCODER_ERROR": (1 << 3, "encoder edges too close together to decode, since the last telemetry"),
    "RX_ERROR": (1 << 4, "a corrupt host frame since the last telemetry"),
    "TX_DROPPED": (1 << 5, "a frame was dropped since the last telemetry (transmit ring full)"),
    "WDT_RESET": (1 << 6, "the last reset was by the hardware watchdog"),
    "STOPPED": (1 << 7, "bridges disabled: no setpoint since HELLO/STOP/watchdog"),
    "LOAD_LIMIT": (1 << 8, "a load duty was clamped (current loop saturated)"),
}

#: ERROR.code values.
ERROR_CODES: dict[str, tuple[int, str]] = {
    "UNKNOWN_TYPE": (1, "type not known or not sent by the host"),
    "BAD_LENGTH": (2, "payload length differs from the table"),
    "BAD_VERSION": (3, "HELLO version differs (detail = firmware version)"),
    "OUT_OF_RANGE": (4, "a SETPOINT value beyond its limit (detail = the value)"),
    "NOT_READY": (5, "a command before HELLO"),
    "BAD_RATE": (6, "STREAM rate not 0 nor a divisor of the sample rate (detail = rate)"),
}

BY_CODE: dict[int, FrameType] = {f.code: f for f in FRAMES}
BY_NAME: dict[str, FrameType] = {f.name: f for f in FRAMES}
MAX_PAYLOAD_LEN = max(f.payload_len for f in FRAMES)
MAX_FRAME_LEN = HEADER_LEN + MAX_PAYLOAD_LEN + CRC_LEN
#: COBS adds one byte per started 254 bytes; the delimiter is not counted here.
MAX_ENCODED_LEN = MAX_FRAME_LEN + (MAX_FRAME_LEN + 253) // 254


def encoded_frame_bytes(frame: FrameType) -> int:
    """Bytes one frame of this type occupies on the wire, COBS overhead and delimiter included."""
    raw = HEADER_LEN + frame.payload_len + CRC_LEN
    return raw + (raw + 253) // 254 + 1


def line_utilisation(frame: FrameType, rate_hz: float, baud: float = BAUD) -> float:
    """Fraction of the line one stream of `frame` at `rate_hz` takes (8N1: 10 bits per byte)."""
    return encoded_frame_bytes(frame) * 10 * rate_hz / baud


def table_text() -> str:
    """Canonical text of the table; its CRC (TABLE_CRC) pairs firmware and host builds."""
    lines = [f"v{PROTOCOL_VERSION}"]
    for f in FRAMES:
        lines.append(f"{f.code:02x} {f.name} {f.sender} " + " ".join(f"{x.name}:{x.ctype}" for x in f.fields))
    lines += [f"S {k} {v[0]}" for k, v in STATUS_BITS.items()]
    lines += [f"E {k} {v[0]}" for k, v in ERROR_CODES.items()]
    return "\n".join(lines) + "\n"


TABLE_CRC = binascii.crc_hqx(table_text().encode(), 0)


def _check_table() -> None:
    codes = [f.code for f in FRAMES]
    if len(set(codes)) != len(codes):
        raise ValueError("protocol_table: duplicate frame codes")
    for f in FRAMES:
        if (f.sender == "host") != (f.code < 0x80):
            raise ValueError(f"protocol_table: {f.name}: host frames use codes < 0x80, rig frames >= 0x80")
        for x in f.fields:
            if x.ctype not in C_TYPES:
                raise ValueError(f"protocol_table: {f.name}.{x.name}: unknown C type {x.ctype}")
        assert struct.calcsize(f.struct_format) == f.payload_len


_check_table()


# --- generators ----------------------------------------------------------------------
def c_header() -> str:
    """The firmware's firmware/protocol_frames.h, generated from the table."""
    out = [
        "/* protocol_frames.h - GENERATED by `python -m worm_rig_driver.protocol.table --header`.",
        " * Do not edit: change worm_rig_driver/protocol/table.py and regenerate",
        " * (test_protocol_table.py fails while this file differs from the table). */",
        "#ifndef PROTOCOL_FRAMES_H",
        "#define PROTOCOL_FRAMES_H",
        "",
        "#include <stdint.h>",
        "",
        f"#define PROTO_VERSION {PROTOCOL_VERSION}u",
        f"#define PROTO_TABLE_CRC 0x{TABLE_CRC:04X}u",
        f"#define PROTO_F_CPU {F_CPU_HZ}UL",
        f"#define PROTO_BAUD {BAUD}UL",
        f"#define PROTO_U2X {U2X}",
        f"#define PROTO_UBRR {UBRR}u /* exact: F_CPU / (8 * (UBRR + 1)) = BAUD */",
        f"#define PROTO_SAMPLE_RATE_HZ {SAMPLE_RATE_HZ}u",
        f"#define PROTO_WATCHDOG_MS {WATCHDOG_MS}u",
        f"#define PROTO_STATS_PERIOD_MS {STATS_PERIOD_MS}u",
        f"#define PROTO_DUTY_FULL_SCALE {DUTY_FULL_SCALE}",
        f"#define PROTO_PWM_TOP {PWM_TOP}u",
        f"#define PROTO_CURRENT_ZERO_CODE {CURRENT_ZERO_CODE}",
        f"#define PROTO_TACHO_ZERO_CODE {TACHO_ZERO_CODE}",
        f"#define PROTO_CURRENT_TARGET_LIMIT {CURRENT_TARGET_LIMIT}",
        f"#define PROTO_HEADER_LEN {HEADER_LEN}u",
        f"#define PROTO_CRC_LEN {CRC_LEN}u",
        f"#define PROTO_MAX_PAYLOAD_LEN {MAX_PAYLOAD_LEN}u",
        f"#define PROTO_MAX_FRAME_LEN {MAX_FRAME_LEN}u",
        f"#define PROTO_MAX_ENCODED_LEN {MAX_ENCODED_LEN}u /* COBS, without the 0x00 delimiter */",
        "",
        "/* Frame types (host -> rig below 0x80, rig -> host from 0x80). */",
    ]
    for f in FRAMES:
        out.append(f"#define FRAME_{f.name} 0x{f.code:02X}u /* {f.sender}: {f.doc} */")
    out += ["", "/* Payload lengths [bytes]. */"]
    for f in FRAMES:
        out.append(f"#define FRAME_{f.name}_LEN {f.payload_len}u")
    out += ["", "/* Payload layouts: little-endian, packed (AVR and x86 are both little-endian). */"]
    for f in FRAMES:
        if not f.fields:
            continue
        out.append("typedef struct __attribute__((packed)) {")
        for x in f.fields:
            out.append(f"    {x.ctype} {x.name}; /* [{x.unit}] {x.doc}; {x.scale} */")
        out.append(f"}} frame_{f.name.lower()}_t;")
        out.append(f"_Static_assert(sizeof(frame_{f.name.lower()}_t) == FRAME_{f.name}_LEN, "
                   f"\"{f.name} layout\");")
    out += ["", "/* TELEMETRY.status bits. */"]
    for k, (v, doc) in STATUS_BITS.items():
        out.append(f"#define STATUS_{k} 0x{v:04X}u /* {doc} */")
    out += ["", "/* ERROR.code values. */"]
    for k, (v, doc) in ERROR_CODES.items():
        out.append(f"#define ERR_{k} {v}u /* {doc} */")
    out += [
        "",
        "/* Payload length of a known frame type, or -1 for an unknown type. */",
        "static inline int16_t proto_payload_len(uint8_t type)",
        "{",
        "    switch (type) {",
    ]
    for f in FRAMES:
        out.append(f"    case FRAME_{f.name}: return FRAME_{f.name}_LEN;")
    out += ["    default: return -1;", "    }", "}", "", "#endif /* PROTOCOL_FRAMES_H */", ""]
    return "\n".join(out)


def markdown_table() -> str:
    """The frame table of docs/protocol.md, generated from the table."""
    out = []
    for f in FRAMES:
        out.append(f"#### `{f.name}` = 0x{f.code:02X} ({f.sender} -> {'rig' if f.sender == 'host' else 'host'}), "
                   f"payload {f.payload_len} B, {encoded_frame_bytes(f)} B on the wire")
        out.append("")
        out.append(f.doc)
        out.append("")
        if f.fields:
            out.append("| offset | field | type | unit | scale | meaning |")
            out.append("| ---: | --- | --- | --- | --- | --- |")
            offset = 0
            for x in f.fields:
                out.append(f"| {offset} | `{x.name}` | `{x.ctype}` | {x.unit} | {x.scale} | {x.doc} |")
                offset += x.size
            out.append("")
    out.append("#### Status bits (`TELEMETRY.status`)")
    out.append("")
    out.append("| bit | name | meaning |")
    out.append("| --- | --- | --- |")
    for k, (v, doc) in STATUS_BITS.items():
        out.append(f"| 0x{v:04X} | `{k}` | {doc} |")
    out.append("")
    out.append("#### Error codes (`ERROR.code`)")
    out.append("")
    out.append("| code | name | meaning |")
    out.append("| --- | --- | --- |")
    for k, (v, doc) in ERROR_CODES.items():
        out.append(f"| {v} | `{k}` | {doc} |")
    out.append("")
    out.append(f"Table CRC (HELLO_REPLY.table_crc): 0x{TABLE_CRC:04X}")
    return "\n".join(out) + "\n"


MARK_BEGIN = ("<!-- BEGIN GENERATED FRAME TABLE "
              "(python -m worm_rig_driver.protocol.table --markdown docs/protocol.md) -->")
MARK_END = "<!-- END GENERATED FRAME TABLE -->"


def splice_markdown(document: str) -> str:
    """Replace the generated section of a markdown document (between the markers) with the table."""
    begin, end = document.find(MARK_BEGIN), document.find(MARK_END)
    if begin < 0 or end < begin:
        raise ValueError("the document has no generated-frame-table markers")
    return document[:begin + len(MARK_BEGIN)] + "\n" + markdown_table() + document[end:]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m worm_rig_driver.protocol.table",
        description="Write the firmware's C header and/or the docs' frame table from the protocol table.")
    parser.add_argument("--header", type=Path, metavar="FILE",
                        help="write the C header (firmware/protocol_frames.h) to FILE")
    parser.add_argument("--markdown", type=Path, metavar="FILE",
                        help="replace the generated frame-table section of the markdown FILE (docs/protocol.md)")
    parser.add_argument("--check", action="store_true",
                        help="do not write: exit 1 if a given FILE differs from what would be written")
    args = parser.parse_args(argv)
    if not args.header and not args.markdown:
        parser.error("give --header and/or --markdown")
    stale = []
    jobs = []
    if args.header:
        jobs.append((args.header, lambda old: c_header()))
    if args.markdown:
        jobs.append((args.markdown, splice_markdown))
    for path, make in jobs:
        try:
            old = path.read_text() if path.exists() else ""
            new = make(old)
        except (OSError, ValueError) as err:
            print(f"protocol_table: {path}: {err}", file=sys.stderr)
            return 2
        if args.check:
            if old != new:
                stale.append(path)
        elif old != new:
            path.write_text(new)
            print(f"protocol_table: wrote {path}")
    for path in stale:
        print(f"protocol_table: {path} differs from the table; regenerate it", file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    raise SystemExit(main())
