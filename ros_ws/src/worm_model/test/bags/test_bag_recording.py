"""Fast tests of bag_recording (no DDS): write bags, read them back two ways.

The second reader is the independent ``mcap`` + ``mcap_ros2`` decoder, which
knows only what the MCAP file carries: decoding proves the message
definitions are embedded.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from worm_msgs.msg import RigSample
from worm_model.bags.reader import BagReader
from worm_model.bags.writer import (
    BagClosedError,
    BagReadError,
    BagRecordingError,
    BagWriter,
    MessageTypes,
    TypeDefinitionNotFoundError,
    deserialize_cdr,
    read_bag_counts,
    read_messages,
)

SAMPLE_TOPIC = '/rig/sample'
JOINT_TOPIC = '/joint_states'
N_SAMPLES = 50
N_JOINTS = 7
T0_NS = 1_700_000_000_000_000_000


def rig_sample(seq: int) -> RigSample:
    """A RigSample whose every field depends on ``seq``."""
    return RigSample(
        header=Header(frame_id='rig'),
        seq=seq,
        current_drive=0.5 * seq,
        omega_worm=-1.25 * seq,
        theta_gear=1e-3 * seq,
        count_drive=-(2**31) + seq,
        tau_load=0.125 * seq,
        status=RigSample.STATUS_SIMULATED,
    )


def joint_state(i: int) -> JointState:
    """A JointState with variable-length arrays."""
    return JointState(name=['worm', 'gear'], position=[float(i), -float(i)], velocity=[0.5 * i])


@pytest.fixture
def types() -> MessageTypes:
    """Types resolved from the ament prefixes of the sourced workspace."""
    return MessageTypes()


def write_bag(path: Path, storage: str, types: MessageTypes, compression: str = 'none') -> BagWriter:
    """Write N_SAMPLES RigSamples and N_JOINTS JointStates, interleaved in time."""
    with BagWriter(path, storage, types=types, compression=compression) as writer:
        samples = writer.add_topic(SAMPLE_TOPIC, 'worm_msgs/msg/RigSample')
        joints = writer.add_topic(JOINT_TOPIC, 'sensor_msgs/JointState')
        for seq in range(N_SAMPLES):
            writer.write(samples, T0_NS + seq * 1_000_000, serialize_message(rig_sample(seq)))
        for i in range(N_JOINTS):
            writer.write(joints, T0_NS + i * 7_000_000 + 1, serialize_message(joint_state(i)))
    return writer


def assert_sample_fields(msg: Any, seq: int) -> None:
    """Compare a decoded RigSample (any reader's object) with rig_sample(seq)."""
    want = rig_sample(seq)
    for field in ('seq', 'current_drive', 'omega_worm', 'theta_gear', 'count_drive',
                  'tau_load', 'status'):
        assert getattr(msg, field) == getattr(want, field), field
    assert msg.header.frame_id == 'rig'


def mcap_messages(bag: Path) -> Iterator[tuple[str, str, int, Any]]:
    """Yield (topic, schema name, log time, decoded) with mcap_ros2 only."""
    (mcap_file,) = bag.glob('*.mcap')
    with mcap_file.open('rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            yield channel.topic, schema.name, message.log_time, decoded


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_roundtrip_with_rosbags(tmp_path: Path, storage: str, types: MessageTypes) -> None:
    bag = tmp_path / 'bag'
    writer = write_bag(bag, storage, types)

    assert writer.closed
    assert writer.counts == {SAMPLE_TOPIC: N_SAMPLES, JOINT_TOPIC: N_JOINTS}
    assert read_bag_counts(bag) == writer.counts
    assert (bag / 'metadata.yaml').is_file()

    samples = list(read_messages(bag, SAMPLE_TOPIC))
    assert [t for t, _ in samples] == [T0_NS + s * 1_000_000 for s in range(N_SAMPLES)]
    for seq, (_t, msg) in enumerate(samples):
        assert_sample_fields(msg, seq)

    joints = [m for _, m in read_messages(bag, JOINT_TOPIC)]
    assert [list(m.position) for m in joints] == [[float(i), -float(i)] for i in range(N_JOINTS)]
    assert joints[-1].name == ['worm', 'gear']


def test_mcap_readable_by_independent_decoder(tmp_path: Path, types: MessageTypes) -> None:
    bag = tmp_path / 'bag'
    write_bag(bag, 'mcap', types)

    decoded = list(mcap_messages(bag))
    samples = [d for d in decoded if d[0] == SAMPLE_TOPIC]
    joints = [d for d in decoded if d[0] == JOINT_TOPIC]
    assert len(samples) == N_SAMPLES
    assert len(joints) == N_JOINTS
    assert {d[1] for d in samples} == {'worm_msgs/msg/RigSample'}
    for seq, (_topic, _schema, log_time, msg) in enumerate(sorted(samples, key=lambda d: d[2])):
        assert log_time == T0_NS + seq * 1_000_000
        assert_sample_fields(msg, seq)
    assert list(joints[3][3].velocity) == [1.5]


def test_zstd_chunks_read_by_every_reader(tmp_path: Path, types: MessageTypes) -> None:
    """compression='zstd': MCAP chunks compressed with zstd, the bag otherwise the same to every reader."""
    plain, packed = tmp_path / 'plain', tmp_path / 'zstd'
    write_bag(plain, 'mcap', types)
    write_bag(packed, 'mcap', types, compression='zstd')
    (mcap_file,) = packed.glob('*.mcap')
    with mcap_file.open('rb') as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and {c.compression for c in summary.chunk_indexes} == {'zstd'}
    assert [d[:3] for d in mcap_messages(packed)] == [d[:3] for d in mcap_messages(plain)]
    assert read_bag_counts(packed) == read_bag_counts(plain)
    for seq, (_t, msg) in enumerate(read_messages(packed, SAMPLE_TOPIC)):
        assert_sample_fields(msg, seq)
    with BagReader(packed) as reader:
        assert reader.compression_mode == ''  # MCAP's own compression; not rosbag2's file/message modes


@pytest.mark.parametrize(('storage', 'compression'), [('sqlite3', 'zstd'), ('mcap', 'lz4'), ('mcap', 'file')])
def test_compression_refused_where_it_does_not_apply(tmp_path: Path, storage: str, compression: str) -> None:
    with pytest.raises(BagRecordingError, match=compression):
        BagWriter(tmp_path / 'bag', storage, compression=compression)
    assert not (tmp_path / 'bag').exists()


def test_embedded_hash_matches_rosidl(tmp_path: Path, types: MessageTypes) -> None:
    """The RIHS01 hash in the bag is the one rosidl generated for the installed type."""
    with BagWriter(tmp_path / 'bag', types=types) as writer:
        handle = writer.add_topic(SAMPLE_TOPIC, 'worm_msgs/msg/RigSample')
    description = types.interface_file('worm_msgs/msg/RigSample').with_suffix('.json')
    hashes = json.loads(description.read_text())['type_hashes']
    assert handle.type_hash == next(
        h['hash_string'] for h in hashes if h['type_name'] == 'worm_msgs/msg/RigSample'
    )


def test_unknown_type_is_named(tmp_path: Path, types: MessageTypes) -> None:
    with (
        BagWriter(tmp_path / 'bag', types=types) as writer,
        pytest.raises(TypeDefinitionNotFoundError) as err,
    ):
        writer.add_topic('/x', 'worm_msgs/msg/NoSuchThing')
    assert "'worm_msgs/msg/NoSuchThing'" in str(err.value)
    assert 'AMENT_PREFIX_PATH=' in str(err.value)
    assert os.environ['AMENT_PREFIX_PATH'].split(os.pathsep)[0] in str(err.value)


def test_custom_type_missing_from_search_path(tmp_path: Path) -> None:
    types = MessageTypes(search_prefixes=[tmp_path / 'nowhere'])
    with pytest.raises(TypeDefinitionNotFoundError, match='RigSample'):
        types.ensure('worm_msgs/msg/RigSample')
    # The stock store needs no prefix.
    assert types.ensure('sensor_msgs/JointState') == 'sensor_msgs/msg/JointState'


def test_nested_custom_types_resolved(tmp_path: Path) -> None:
    """A custom type referencing another custom type pulls in both."""
    msg_dir = tmp_path / 'share' / 'demo_msgs' / 'msg'
    msg_dir.mkdir(parents=True)
    (msg_dir / 'Inner.msg').write_text('float64 x  # [m]\n')
    (msg_dir / 'Outer.msg').write_text('demo_msgs/Inner[] inners\nstd_msgs/Header header\n')
    types = MessageTypes(search_prefixes=[tmp_path])
    types.ensure('demo_msgs/msg/Outer')
    assert 'demo_msgs/msg/Inner' in types


def test_misuse_raises_domain_errors(tmp_path: Path, types: MessageTypes) -> None:
    bag = tmp_path / 'bag'
    with pytest.raises(BagRecordingError, match='storage'):
        BagWriter(bag, 'rosbag1', types=types)
    writer = BagWriter(bag, types=types)
    handle = writer.add_topic(SAMPLE_TOPIC, 'worm_msgs/msg/RigSample')
    with pytest.raises(BagRecordingError, match='already in bag'):
        writer.add_topic(SAMPLE_TOPIC, 'sensor_msgs/msg/JointState')
    writer.close()
    writer.close()  # idempotent
    with pytest.raises(BagClosedError, match=str(bag)):
        writer.write(handle, 0, serialize_message(rig_sample(0)))
    with pytest.raises(BagRecordingError, match='exists'):
        BagWriter(bag, types=types)
    with pytest.raises(BagReadError, match='no topic'):
        list(read_messages(bag, '/nothing'))
    with pytest.raises(BagReadError, match='No bag'):
        read_bag_counts(tmp_path / 'missing')


def test_deserialize_accepts_fast_cdr_final_padding(types: MessageTypes) -> None:
    """rmw_fastrtps pads payloads and reserves alignment for empty sequences; rosbags rejects >3 bytes."""
    data = bytes(serialize_message(joint_state(2)))  # ends with an empty effort sequence
    decoded = deserialize_cdr(types.typestore, data, 'sensor_msgs/msg/JointState')
    assert list(decoded.position) == [2.0, -2.0]  # type: ignore[attr-defined]
    # Fast DDS also sends the alignment it reserved for empty sequences.
    empty = bytes(serialize_message(JointState(name=['worm'], position=[1.0])))
    assert list(deserialize_cdr(types.typestore, empty, 'sensor_msgs/msg/JointState')
                .position) == [1.0]  # type: ignore[attr-defined]
    # More than 7 bytes of final padding + 4 per sequence (JointState has 4) is not padding.
    with pytest.raises(BagReadError, match='left over'):
        deserialize_cdr(types.typestore, data + bytes(24), 'sensor_msgs/msg/JointState')
    with pytest.raises(BagReadError, match='plain CDR'):
        deserialize_cdr(types.typestore, b'\x00\x07\x00\x00', 'sensor_msgs/msg/JointState')


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_flushed_bag_is_readable_without_close(tmp_path: Path, storage: str) -> None:
    """What a killed recorder leaves: messages up to its last flush(), read without metadata.yaml."""
    import shutil

    writer = BagWriter(tmp_path / 'bag', storage)
    handle = writer.add_topic('/rig/sample', 'worm_msgs/msg/RigSample')
    for seq in range(30):
        writer.write(handle, 1000 + seq, bytes(serialize_message(RigSample(seq=seq))))
        if seq == 19:
            writer.flush()
    # as after SIGKILL: copy the files as they are on disk, then let the writer go
    shutil.copytree(tmp_path / 'bag', tmp_path / 'killed')
    writer.close()
    assert not (tmp_path / 'killed' / 'metadata.yaml').exists()
    seqs = [m.seq for _, m in read_messages(tmp_path / 'killed', '/rig/sample')]
    assert seqs[:20] == list(range(20)) and len(seqs) <= 30
    assert os.path.getsize(next((tmp_path / 'killed').iterdir())) > 0


def test_a_bag_before_its_first_flush_says_so(tmp_path: Path) -> None:
    """A recorder's MCAP file before its first flush holds nothing: reading it names why in one line; once
    the magic and header are there (an MCAP writer's start) it reads as no messages, not as damage."""
    import shutil

    from mcap.writer import Writer

    writer = BagWriter(tmp_path / 'bag', 'mcap')
    writer.add_topic('/rig/sample', 'worm_msgs/msg/RigSample')
    shutil.copytree(tmp_path / 'bag', tmp_path / 'opened')  # as a `bag info` sees it while recording
    writer.close()
    with pytest.raises(BagReadError, match="0 bytes, less than an MCAP file's magic and header"):
        read_bag_counts(tmp_path / 'opened')
    started = tmp_path / 'started'
    started.mkdir()
    with (started / 'started.mcap').open('wb') as stream:
        Writer(stream).start(profile='ros2', library='test')
    assert read_bag_counts(started) == {}


def test_a_chunk_a_second_for_an_hour_costs_under_30_kilobytes(tmp_path: Path) -> None:
    """The recorder closes a chunk every second (flush); the writer keeps each chunk's index for the summary it
    writes at close. Kept in an unnamed file in the bag's folder (writer._ChunkIndexes), a chunk costs 8 bytes
    of memory (its record's end), so an hour of flushes holds 29 kB (rosbags' own BytesIO a chunk: 323 bytes,
    1.16 MB); the summary the independent mcap reader reads indexes every chunk and every message, and the
    folder holds only the bag's own files."""
    import gc
    import tracemalloc

    writer = BagWriter(tmp_path / 'bag', 'mcap')
    handles = [writer.add_topic(f'/t{i}', 'worm_msgs/msg/RigSample') for i in range(13)]
    data = bytes(serialize_message(RigSample(seq=1)))
    chunks, stamp = 1000, T0_NS

    def flushed_chunks(n: int) -> None:
        nonlocal stamp
        for _ in range(n):
            for handle in handles:
                writer.write(handle, stamp, data)
                stamp += 1
            writer.flush()

    flushed_chunks(50)  # the writer's own first allocations
    gc.collect()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        flushed_chunks(chunks)
        gc.collect()
        per_chunk = (tracemalloc.get_traced_memory()[0] - before) / chunks
    finally:
        tracemalloc.stop()
    writer.close()
    assert per_chunk < 12, per_chunk  # measured 8.0 (the array of ends); 323 with a BytesIO a chunk
    with next((tmp_path / 'bag').glob('*.mcap')).open('rb') as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert len(summary.chunk_indexes) == chunks + 50
        assert summary.statistics.message_count == 13 * (chunks + 50)
        assert sum(1 for _ in reader.iter_messages()) == 13 * (chunks + 50)
    assert sorted(p.suffix for p in (tmp_path / 'bag').iterdir()) == ['.mcap', '.yaml']
