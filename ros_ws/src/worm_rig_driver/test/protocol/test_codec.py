"""Codec: CRC-16/XMODEM, COBS, frame pack/unpack, and the stream decoder under 10^5 damaged streams."""
from __future__ import annotations

import random

import pytest

import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import (StreamDecoder, cobs_decode, cobs_encode, crc16, encode_frame, encode_raw,
    pack_frame)
from worm_rig_driver.errors import CobsError, CodecError
from worm_rig_driver.protocol.stream_fuzz import frame_pool, mutated_stream, random_frame, random_stream


def test_crc16_xmodem_check_value() -> None:
    assert crc16(b"123456789") == 0x31C3  # the catalogued check value of CRC-16/XMODEM
    assert crc16(b"") == 0


@pytest.mark.parametrize("data, encoded", [
    (b"", b"\x01"),
    (b"\x00", b"\x01\x01"),
    (b"\x00\x00", b"\x01\x01\x01"),
    (b"\x11\x22\x00\x33", b"\x03\x11\x22\x02\x33"),
    (b"\x11\x22\x33\x44", b"\x05\x11\x22\x33\x44"),
    (b"\x11\x00\x00\x00", b"\x02\x11\x01\x01\x01"),
    (bytes(range(1, 255)), b"\xff" + bytes(range(1, 255))),
    (bytes(range(0, 255)), b"\x01\xff" + bytes(range(1, 255))),
    (bytes(range(1, 256)), b"\xff" + bytes(range(1, 255)) + b"\x02\xff"),
])
def test_cobs_known_vectors(data: bytes, encoded: bytes) -> None:
    assert cobs_encode(data) == encoded
    assert cobs_decode(encoded) == data


def test_cobs_round_trip_of_random_data() -> None:
    rng = random.Random(7)
    for _ in range(3000):
        data = bytes(rng.choice((0, 0, 1, 255, rng.randrange(256))) for _ in range(rng.randrange(700)))
        encoded = cobs_encode(data)
        assert 0 not in encoded
        assert len(encoded) <= len(data) + len(data) // 254 + 1
        assert cobs_decode(encoded) == data


@pytest.mark.parametrize("bad", [b"\x05\x11\x22", b"\x02\x00", b"\x00"])
def test_cobs_decode_rejects_malformed(bad: bytes) -> None:
    with pytest.raises(CobsError):
        cobs_decode(bad)


def test_every_frame_type_round_trips() -> None:
    rng = random.Random(3)
    for ftype in table.FRAMES:
        for _ in range(50):
            frame, wire = random_frame(rng, (ftype,))
            assert wire.endswith(b"\x00") and 0 not in wire[:-1]
            decoded = StreamDecoder().feed(wire)
            assert decoded == [frame]
            assert decoded[0].name == ftype.name


def test_frame_crc_of_the_whole_frame_is_zero() -> None:
    raw = pack_frame("STREAM", 258, rate_hz=500)
    assert raw[:3] == bytes([0x04, 0x02, 0x01])  # type, seq little-endian
    assert raw[3:5] == (500).to_bytes(2, "little")
    assert int.from_bytes(raw[-2:], "big") == crc16(raw[:-2])
    assert crc16(raw) == 0


@pytest.mark.parametrize("kind, seq, values, message", [
    ("NOPE", 1, {}, "unknown frame type"),
    ("STREAM", 1, {}, "missing fields"),
    ("STREAM", 1, {"rate_hz": 70000}, "is not a uint16_t"),
    ("SETPOINT", 1, {"mode": 0, "drive": -40000, "load_1": 0, "load_2": 0}, "is not a int16_t"),
    ("STREAM", 1, {"rate_hz": 1.5}, "is not a uint16_t"),
    ("HEARTBEAT", 70000, {}, "seq=70000"),
])
def test_pack_refuses_bad_values(kind, seq, values, message) -> None:
    with pytest.raises(CodecError, match=message):
        pack_frame(kind, seq, **values)


def test_decoder_gives_the_same_frames_whatever_the_chunking() -> None:
    rng = random.Random(11)
    pool = frame_pool(rng, 300)
    stream = b"".join(w for _, w in pool)
    whole = StreamDecoder().feed(stream)
    assert whole == [f for f, _ in pool]
    chunked = StreamDecoder()
    out = []
    i = 0
    while i < len(stream):
        n = rng.randint(1, 70)
        out += chunked.feed(stream[i:i + n])
        i += n
    assert out == whole
    assert chunked.stats.frames == len(pool) and chunked.stats.bad_frames == 0


def test_decoder_counts_each_kind_of_bad_frame() -> None:
    good = encode_frame("HEARTBEAT", 5)
    raw = bytearray(pack_frame("STREAM", 6, rate_hz=100))
    raw[-1] ^= 0xFF
    bad_crc = encode_raw(bytes(raw))
    unknown = encode_raw(_with_crc(bytes([0x7E, 7, 0])))
    wrong_length = encode_raw(_with_crc(bytes([table.BY_NAME["STREAM"].code, 8, 0, 1])))
    too_short = encode_raw(b"\x01\x02")
    not_cobs = b"\x09\x01\x00"
    oversize = b"\x01" * (table.MAX_ENCODED_LEN + 5) + b"\x00"
    d = StreamDecoder()
    frames = d.feed(bad_crc + unknown + wrong_length + too_short + not_cobs + oversize + good)
    assert [f.seq for f in frames] == [5]
    s = d.stats
    assert (s.crc_errors, s.unknown_types, s.length_errors, s.cobs_errors, s.oversize) == (1, 1, 2, 1, 1)
    assert s.frames == 1 and s.bytes == len(bad_crc + unknown + wrong_length + too_short + not_cobs + oversize + good)


def _with_crc(body: bytes) -> bytes:
    return body + crc16(body).to_bytes(2, "big")


def test_an_endless_segment_is_dropped_as_it_grows() -> None:
    d = StreamDecoder()
    for _ in range(1000):
        assert d.feed(b"\x07" * 100) == []
    assert d.stats.oversize == 1
    assert len(d._pending) <= table.MAX_ENCODED_LEN  # bounded memory
    good = encode_frame("HEARTBEAT", 9)
    assert d.feed(b"\x00" + good) == StreamDecoder().feed(good)


def test_100k_random_and_mutated_streams_never_raise_and_resync_within_one_frame() -> None:
    rng = random.Random(2024)
    pool = frame_pool(rng, 2000)
    kinds: dict[str, int] = {}
    for i in range(100_000):
        s = random_stream(rng, pool) if i % 5 == 0 else mutated_stream(rng, pool)
        kinds[s.kind] = kinds.get(s.kind, 0) + 1
        decoder = StreamDecoder()
        out = []
        cut = rng.randrange(len(s.data) + 1)  # in two chunks, split anywhere
        out += decoder.feed(s.data[:cut])
        out += decoder.feed(s.data[cut:])
        assert out[:s.must_before] == s.frames[:s.must_before], (i, s.kind)
        tail = s.frames[s.must_from:]
        if tail:
            assert out[-len(tail):] == tail, (i, s.kind, s.data.hex())
        assert decoder.stats.bytes == len(s.data)
    assert len(kinds) == 9 and min(kinds.values()) > 5000  # every mutation exercised
