"""The firmware's frame code (frame.c, cobs.c, crc16.h) compiled for the host agrees with the Python codec.

`make -C firmware host-test` builds firmware/build/host_vectors with gcc; the same
vectors go through both: frames encoded by each are byte-identical, and random
and damaged streams decode to the same frames with the same counters.
"""
from __future__ import annotations

import random
import subprocess
from pathlib import Path

import pytest

import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import StreamDecoder, encode_frame
from worm_rig_driver.protocol.stream_fuzz import frame_pool, mutated_stream, random_stream, records

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware"
PROGRAM = FIRMWARE / "build" / "host_vectors"


@pytest.fixture(scope="module")
def host_vectors() -> Path:
    done = subprocess.run(["make", "-s", "-C", str(FIRMWARE), "host-test"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, f"building host_vectors failed:\n{done.stdout}\n{done.stderr}"
    return PROGRAM


def c_decode(program: Path, data: bytes) -> tuple[dict[int, list], dict[int, tuple[int, ...]]]:
    done = subprocess.run([str(program), "decode"], input=data, capture_output=True, timeout=300)
    assert done.returncode == 0, done.stderr.decode()
    frames: dict[int, list] = {}
    stats: dict[int, tuple[int, ...]] = {}
    for line in done.stdout.decode().splitlines():
        parts = line.split()
        if parts[0] == "F":
            frames.setdefault(int(parts[1]), []).append((int(parts[2]), int(parts[3]),
                                                         bytes.fromhex(parts[4]) if len(parts) > 4 else b""))
        else:
            stats[int(parts[1])] = tuple(int(x) for x in parts[2:])
    return frames, stats


def py_decode(data: bytes) -> tuple[list, tuple[int, ...]]:
    d = StreamDecoder()
    out = [(f.code, f.seq, _payload_bytes(f)) for f in d.feed(data)]
    s = d.stats
    return out, (s.frames, s.crc_errors, s.cobs_errors, s.length_errors, s.unknown_types, s.oversize)


def _payload_bytes(frame) -> bytes:
    import struct
    return struct.pack(table.BY_CODE[frame.code].struct_format, *frame.payload)


def test_c_and_python_encode_byte_identical_frames(host_vectors: Path) -> None:
    rng = random.Random(5)
    pool = frame_pool(rng, 3000)
    lines = "".join(f"{f.code} {f.seq} {_payload_bytes(f).hex()}\n" for f, _ in pool)
    done = subprocess.run([str(host_vectors), "encode"], input=lines, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    c_wires = [bytes.fromhex(x) for x in done.stdout.split()]
    assert c_wires == [w for _, w in pool]


def test_c_decodes_the_python_vectors(host_vectors: Path) -> None:
    rng = random.Random(6)
    pool = frame_pool(rng, 3000)
    stream = b"".join(w for _, w in pool)
    frames, stats = c_decode(host_vectors, records([type("S", (), {"data": stream})()]))
    assert frames[0] == [(f.code, f.seq, _payload_bytes(f)) for f, _ in pool]
    assert stats[0] == (len(pool), 0, 0, 0, 0, 0)


def test_c_and_python_agree_on_random_and_damaged_streams(host_vectors: Path) -> None:
    rng = random.Random(99)
    pool = frame_pool(rng, 2000)
    streams = [random_stream(rng, pool) if i % 4 == 0 else mutated_stream(rng, pool) for i in range(30_000)]
    frames, stats = c_decode(host_vectors, records(streams))
    for i, s in enumerate(streams):
        expected_frames, expected_stats = py_decode(s.data)
        assert frames.get(i, []) == expected_frames, (i, s.kind, s.data.hex())
        assert stats[i] == expected_stats, (i, s.kind, s.data.hex())


def test_a_known_telemetry_vector() -> None:
    # Pinned bytes: a change of layout, CRC or COBS shows here first.
    wire = encode_frame("TELEMETRY", 0x0102, t_us=1000, current_drive=512, current_load_1=0, current_load_2=1023,
                        tacho_drive=600, tacho_load_1=512, tacho_load_2=512, count_drive=-1, count_load_1=2000,
                        count_load_2=0, duty_drive=-10000, duty_load_1=0, duty_load_2=10000, status=0x0082,
                        cmd_seq=7)
    assert wire.hex() == VECTOR


VECTOR = ("06810201e803010102020105ff03580202020802ffffffffd007010101010103f0d801041027820207034f1200")
