"""Random valid frames, and byte streams made of them with one frame corrupted, for the decoders.

Used by the codec's fuzz test, the C/Python agreement test and the decoder
benchmark. Deterministic for a given seed.

A mutated stream is ``m`` valid frames where the bytes of frame ``k`` (its
delimiter included) were damaged in one of several ways; a random stream is
random bytes followed by valid frames. The decoder must decode every frame
before the damage and every frame from ``k + 2`` on (the damage can merge
frame ``k`` with frame ``k + 1`` by removing the delimiter between them).
"""
from __future__ import annotations

import random
import struct
from dataclasses import dataclass

import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import Frame, PAYLOADS, encode_frame

_LIMITS = {"B": (0, 0xFF), "b": (-0x80, 0x7F), "H": (0, 0xFFFF), "h": (-0x8000, 0x7FFF),
           "I": (0, 0xFFFFFFFF), "i": (-0x80000000, 0x7FFFFFFF)}
MUTATIONS = ("flip", "replace", "insert", "delete", "truncate", "zero", "duplicate_delimiter", "splice")


def random_frame(rng: random.Random, kinds: tuple[table.FrameType, ...] = table.FRAMES) -> tuple[Frame, bytes]:
    """A random valid frame (any type, random seq and field values) and its wire bytes."""
    ftype = rng.choice(kinds)
    values = {}
    for x in ftype.fields:
        lo, hi = _LIMITS[x.fmt]
        # Zeros and extremes on purpose: they exercise COBS groups and sign handling.
        values[x.name] = rng.choice((0, lo, hi, rng.randint(lo, hi), rng.randint(lo, hi)))
    seq = rng.choice((0, 0xFFFF, rng.randrange(0x10000)))
    wire = encode_frame(ftype.code, seq, **values)
    return Frame(ftype.code, seq, PAYLOADS[ftype.code](**values)), wire


@dataclass
class FuzzStream:
    data: bytes
    frames: list[Frame]  #: the valid frames it was built from
    must_before: int  #: frames[:must_before] must come out first, in order
    must_from: int  #: frames[must_from:] must come out last, in order
    kind: str


def mutated_stream(rng: random.Random, pool: list[tuple[Frame, bytes]], m: int = 5) -> FuzzStream:
    """m frames from `pool`, one of them damaged (see MUTATIONS)."""
    picks = [rng.choice(pool) for _ in range(m)]
    k = rng.randrange(m)
    wires = [bytearray(w) for _, w in picks]
    target = wires[k]
    kind = rng.choice(MUTATIONS)
    n = len(target)
    if kind == "flip":
        for _ in range(rng.randint(1, 3)):
            target[rng.randrange(n)] ^= rng.randint(1, 255)
    elif kind == "replace":
        for _ in range(rng.randint(1, 8)):
            target[rng.randrange(n)] = rng.randrange(256)
    elif kind == "insert":
        at = rng.randrange(n + 1)
        target[at:at] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 60)))
    elif kind == "delete":
        at = rng.randrange(n)
        del target[at:at + rng.randint(1, 6)]
    elif kind == "truncate":
        del target[rng.randrange(n):]
    elif kind == "zero":
        target[rng.randrange(n)] = 0
    elif kind == "duplicate_delimiter":
        at = rng.randrange(n)
        target[at:at] = b"\x00\x00"
    else:  # splice: the head of this frame with the tail of another
        other = rng.choice(pool)[1]
        target[rng.randrange(n):] = other[rng.randrange(len(other)):]
    return FuzzStream(b"".join(wires), [f for f, _ in picks], k, k + 2, kind)


def random_stream(rng: random.Random, pool: list[tuple[Frame, bytes]], m: int = 3) -> FuzzStream:
    """Random bytes (some zeros among them) followed by m valid frames."""
    n = rng.randint(0, 300)
    zero_rate = rng.choice((0.0, 0.01, 0.1))
    garbage = bytes(0 if rng.random() < zero_rate else rng.randrange(256) for _ in range(n))
    picks = [rng.choice(pool) for _ in range(m)]
    return FuzzStream(garbage + b"".join(w for _, w in picks), [f for f, _ in picks], 0, 1, "random")


def frame_pool(rng: random.Random, size: int = 2000) -> list[tuple[Frame, bytes]]:
    return [random_frame(rng) for _ in range(size)]


def records(streams: list[FuzzStream]) -> bytes:
    """The streams as host_vectors' decode input: (uint32 LE length, bytes) records."""
    return b"".join(struct.pack("<I", len(s.data)) + s.data for s in streams)
