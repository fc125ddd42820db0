"""Codec of the rig's serial protocol: COBS framing, CRC-16/XMODEM, frame pack/unpack, stream decoder.

Plain Python (no rclpy); the layouts come from ``protocol_table``. A frame on
the wire is ``COBS(type:u8 | seq:u16 LE | payload | crc:u16 BE) 0x00`` where
the CRC (CRC-16/XMODEM: poly 0x1021, init 0, no reflection, no final xor;
``binascii.crc_hqx(data, 0)``, avr-libc ``_crc_xmodem_update``) covers type,
seq and payload. Appended big-endian, the CRC of the whole frame is then 0.

Receiver rules (the firmware's ``frame.c`` follows the same ones, and a test
feeds both the same streams):
  1. bytes accumulate until a 0x00; an empty segment is ignored;
  2. a segment longer than MAX_ENCODED_LEN is discarded whole (``oversize``);
  3. a segment that is not valid COBS is discarded (``cobs_errors``);
  4. a decoded frame shorter than header + CRC is discarded (``length_errors``);
  5. a CRC that does not check is discarded (``crc_errors``);
  6. an unknown type is discarded (``unknown_types``);
  7. a payload whose length differs from the table is discarded (``length_errors``).
A corrupt frame can therefore take at most the frame after it with it (when the
corruption removes the delimiter between them): the decoder is back in step
within one frame.
"""
from __future__ import annotations

import binascii
import struct
from collections import namedtuple
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import worm_rig_driver.protocol.table as table
from worm_rig_driver.errors import CobsError, CodecError

_HEADER = struct.Struct("<BH")
_CRC = struct.Struct(">H")
_MIN_FRAME = table.HEADER_LEN + table.CRC_LEN


def crc16(data: bytes) -> int:
    """CRC-16/XMODEM of `data` (poly 0x1021, init 0)."""
    return binascii.crc_hqx(data, 0)


def cobs_encode(data: bytes) -> bytes:
    """COBS-encode `data` (Cheshire & Baker 1999): the result has no 0x00 byte; no delimiter added."""
    out = bytearray()
    start = 0
    n = len(data)
    while True:
        zero = data.find(0, start, start + 254)
        if zero < 0:
            block = data[start:start + 254]
            if len(block) == 254:
                out.append(0xFF)
                out += block
                start += 254
                if start >= n:  # a full group ends the data: no implied zero, nothing more
                    break
                continue
            out.append(len(block) + 1)
            out += block
            break
        out.append(zero - start + 1)
        out += data[start:zero]
        start = zero + 1
        if start >= n:
            out.append(0x01)  # the data ended with a zero
            break
    return bytes(out)


def cobs_decode(data: bytes) -> bytes:
    """Invert cobs_encode; raises CobsError on a 0x00 byte or a group running past the end."""
    out = bytearray()
    i = 0
    n = len(data)
    while i < n:
        code = data[i]
        if code == 0:
            raise CobsError(f"0x00 inside a COBS segment at byte {i}")
        end = i + code
        if end > n:
            raise CobsError(f"group at byte {i} (code {code}) runs past the end ({n} bytes)")
        block = data[i + 1:end]
        if 0 in block:
            raise CobsError(f"0x00 inside a COBS group at byte {i}")
        out += block
        i = end
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)


# --- frames ------------------------------------------------------------------------
#: One namedtuple class per frame type, fields as in the table (e.g. Telemetry(t_us=..., ...)).
PAYLOADS: dict[int, type] = {
    f.code: namedtuple("".join(p.title() for p in f.name.split("_")), [x.name for x in f.fields])
    for f in table.FRAMES
}
_STRUCTS: dict[int, struct.Struct] = {f.code: struct.Struct(f.struct_format) for f in table.FRAMES}
_LENGTHS: dict[int, int] = {f.code: f.payload_len for f in table.FRAMES}
_LIMITS = {t: (-(1 << (8 * s - 1)), (1 << (8 * s - 1)) - 1) if fmt.islower() else (0, (1 << (8 * s)) - 1)
           for t, (fmt, s) in table.C_TYPES.items()}


class Frame(NamedTuple):
    """A decoded frame: its type code, sequence number and payload (the type's namedtuple)."""

    code: int
    seq: int
    payload: Any

    @property
    def name(self) -> str:
        return table.BY_CODE[self.code].name


def _frame_type(kind: str | int) -> table.FrameType:
    try:
        return table.BY_NAME[kind] if isinstance(kind, str) else table.BY_CODE[kind]
    except KeyError:
        raise CodecError(f"unknown frame type {kind!r}") from None


def pack_frame(kind: str | int, seq: int, **values: int) -> bytes:
    """The raw frame (header, payload, CRC) before COBS; every field must be given, in range."""
    ftype = _frame_type(kind)
    names = [x.name for x in ftype.fields]
    missing = set(names) - set(values)
    extra = set(values) - set(names)
    if missing or extra:
        raise CodecError(f"{ftype.name}: missing fields {sorted(missing)}, unknown fields {sorted(extra)}")
    for x in ftype.fields:
        v = values[x.name]
        lo, hi = _LIMITS[x.ctype]
        if not isinstance(v, int) or not lo <= v <= hi:
            raise CodecError(f"{ftype.name}.{x.name}={v!r} is not a {x.ctype} ({lo}..{hi})")
    if not 0 <= seq <= 0xFFFF:
        raise CodecError(f"{ftype.name}: seq={seq} is not a uint16")
    body = _HEADER.pack(ftype.code, seq) + _STRUCTS[ftype.code].pack(*(values[n] for n in names))
    return body + _CRC.pack(crc16(body))


def encode_frame(kind: str | int, seq: int, **values: int) -> bytes:
    """The frame as sent on the wire: COBS of pack_frame(...) and the 0x00 delimiter."""
    return cobs_encode(pack_frame(kind, seq, **values)) + b"\x00"


def encode_raw(raw: bytes) -> bytes:
    """COBS + delimiter of an already packed frame (tests use it to send deliberately bad frames)."""
    return cobs_encode(raw) + b"\x00"


# --- the stream decoder ----------------------------------------------------------------
@dataclass
class DecoderStats:
    """Counters of a StreamDecoder (see the receiver rules in the module docstring)."""

    bytes: int = 0
    frames: int = 0
    crc_errors: int = 0
    cobs_errors: int = 0
    length_errors: int = 0
    unknown_types: int = 0
    oversize: int = 0
    discarded_bytes: int = 0  #: bytes of every discarded segment (garbage), delimiters excluded

    @property
    def bad_frames(self) -> int:
        return self.crc_errors + self.cobs_errors + self.length_errors + self.unknown_types + self.oversize

    def as_dict(self) -> dict[str, int]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


class StreamDecoder:
    """Turns a byte stream into frames; never raises on any input, counts what it discards."""

    def __init__(self, max_encoded: int = table.MAX_ENCODED_LEN) -> None:
        self.max_encoded = max_encoded
        self.stats = DecoderStats()
        self._pending = bytearray()
        self._overflowed = False  # the current segment already exceeded max_encoded

    def reset(self) -> None:
        """Forget the unfinished segment (a new connection); the counters go on."""
        self._pending.clear()
        self._overflowed = False

    def feed(self, data: bytes) -> list[Frame]:
        """Decode every frame completed by `data`; keep the unfinished tail for the next call."""
        stats = self.stats
        stats.bytes += len(data)
        if 0 not in data:
            self._pending += data
            self._check_overflow()
            return []
        self._pending += data
        segments = self._pending.split(b"\x00")
        self._pending = bytearray(segments.pop())
        frames: list[Frame] = []
        for segment in segments:
            if self._overflowed:  # the end of an oversize segment: already counted
                self._overflowed = False
                stats.discarded_bytes += len(segment)
                continue
            if not segment:
                continue
            frame = self._decode_segment(segment)
            if frame is not None:
                frames.append(frame)
        self._check_overflow()
        return frames

    def _check_overflow(self) -> None:
        if len(self._pending) > self.max_encoded:
            if not self._overflowed:
                self.stats.oversize += 1
                self._overflowed = True
            self.stats.discarded_bytes += len(self._pending)
            self._pending.clear()

    def _decode_segment(self, segment: bytes) -> Frame | None:
        stats = self.stats
        if len(segment) > self.max_encoded:
            stats.oversize += 1
            stats.discarded_bytes += len(segment)
            return None
        try:
            raw = cobs_decode(segment)
        except CobsError:
            stats.cobs_errors += 1
            stats.discarded_bytes += len(segment)
            return None
        if len(raw) < _MIN_FRAME:
            stats.length_errors += 1
            stats.discarded_bytes += len(segment)
            return None
        if binascii.crc_hqx(raw, 0) != 0:
            stats.crc_errors += 1
            stats.discarded_bytes += len(segment)
            return None
        code, seq = _HEADER.unpack_from(raw)
        length = _LENGTHS.get(code)
        if length is None:
            stats.unknown_types += 1
            stats.discarded_bytes += len(segment)
            return None
        if len(raw) - _MIN_FRAME != length:
            stats.length_errors += 1
            stats.discarded_bytes += len(segment)
            return None
        stats.frames += 1
        return Frame(code, seq, PAYLOADS[code]._make(_STRUCTS[code].unpack_from(raw, table.HEADER_LEN)))
