"""The bag reader against every layout rosbag2 writes (no DDS, no rosbag2 needed).

The bags come from fixtures.rosbag2_layouts (test/fixtures/), which writes what each
rosbag2 release (Foxy 0.3 ... Jazzy 0.26; metadata versions 4 to 9) writes:
sqlite3 and MCAP, split into several files, zstd-compressed per file or per
message. Each test would fail if the reader lost, reordered or misdecoded a
message of such a bag.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
import zstandard
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Reader as RosbagsReader
from sensor_msgs.msg import JointState
from worm_msgs.msg import RigSample
from worm_model.bags.bag_files import storage_files
from worm_model.bags.reader import BagReader
from worm_model.bags.typestore import MessageTypes
from worm_model.errors import BagReadError
from fixtures.rosbag2_layouts import (
    LAYOUTS,
    FixtureTopic,
    QosProfile,
    message_definition_text,
    reindex,
    type_hash,
    write_rosbag2_bag,
    yaml_cpp_dump,
)

T0 = 1_700_000_000_000_000_000
N_SAMPLES = 120
SPLIT_NS = 25_000_000  # --max-bag-duration 25 ms: 5 files for 120 ms of samples
TOPICS = [FixtureTopic('/rig/sample', 'worm_msgs/msg/RigSample'),
          FixtureTopic('/rig/joint_states', 'sensor_msgs/msg/JointState',
                       (QosProfile(reliability=1), QosProfile(reliability=2)))]


def rig_sample(seq: int) -> RigSample:
    sample = RigSample(seq=seq, current_drive=0.25 * seq, omega_worm=-1.5 * seq, tau_load=1e-3 * seq,
                       status=RigSample.STATUS_SIMULATED)
    sample.header.frame_id = 'worm_rig'
    sample.header.stamp.sec, sample.header.stamp.nanosec = divmod(T0 + seq * 1_000_000, 10**9)
    return sample


def stream() -> list[tuple[str, int, bytes]]:
    """1 kHz RigSample (seq 0..N-1) and 100 Hz JointState (empty velocity/effort), interleaved."""
    out = []
    for seq in range(N_SAMPLES):
        out.append(('/rig/sample', T0 + seq * 1_000_000, bytes(serialize_message(rig_sample(seq)))))
        if seq % 10 == 0:
            joints = JointState(name=['worm'], position=[float(seq)])
            out.append(('/rig/joint_states', T0 + seq * 1_000_000 + 1, bytes(serialize_message(joints))))
    return out


def samples_only(n: int) -> list[tuple[str, int, bytes]]:
    """The first n RigSample messages of stream()."""
    return [m for m in stream() if m[0] == '/rig/sample'][:n]


CASES = [
    (layout, storage, compression)
    for layout in LAYOUTS
    for storage in LAYOUTS[layout].storages
    for compression in ('', 'file', 'message')
    if not (compression == 'message' and storage == 'mcap' and LAYOUTS[layout].version >= 9)
]


@pytest.mark.parametrize(('layout', 'storage', 'compression'), CASES)
def test_reads_every_rosbag2_layout(tmp_path: Path, layout: str, storage: str, compression: str) -> None:
    bag = write_rosbag2_bag(tmp_path / 'bag', layout, storage, TOPICS, stream(),
                            compression=compression, max_bagfile_duration_ns=SPLIT_NS)
    with BagReader(bag) as reader:
        assert reader.metadata is not None and reader.metadata.version == LAYOUTS[layout].version
        assert reader.file_names() == reader.metadata.relative_file_paths
        assert len(reader.file_names()) == 5
        assert reader.count_messages() == {'/rig/joint_states': 12, '/rig/sample': N_SAMPLES}
        samples = list(reader.messages(['/rig/sample']))
        assert [m.decoded.seq for m in samples] == list(range(N_SAMPLES))
        assert [m.timestamp for m in samples] == [T0 + s * 1_000_000 for s in range(N_SAMPLES)]
        assert samples[7].decoded.omega_worm == -10.5
        assert samples[7].decoded.header.frame_id == 'worm_rig'
        joints = [m.decoded for m in reader.messages(['/rig/joint_states'])]
        assert [list(j.position) for j in joints] == [[float(s)] for s in range(0, N_SAMPLES, 10)]
        assert reader.warnings == []
        if LAYOUTS[layout].version >= 7:  # definitions embedded: decoded without the local files
            assert reader.topics['/rig/sample'].definition is not None
            assert reader.topics['/rig/sample'].type_hash == type_hash('worm_msgs/msg/RigSample')


def test_file_mode_frames_have_no_content_size(tmp_path: Path) -> None:
    """rosbag2 >= 0.15 streams FILE-mode compression: a one-shot zstd decompress fails on it."""
    bag = write_rosbag2_bag(tmp_path / 'bag', 'jazzy', 'mcap', TOPICS, stream(), compression='file')
    (compressed,) = bag.glob('*.mcap.zstd')
    assert zstandard.get_frame_parameters(compressed.read_bytes()).content_size == \
        zstandard.CONTENTSIZE_UNKNOWN
    with BagReader(bag) as reader:
        assert sum(reader.count_messages().values()) == N_SAMPLES + 12


def test_metadata_yaml_is_yaml_cpp_text(tmp_path: Path) -> None:
    """metadata.yaml as Foxy (v4) and Jazzy (v9) write it, character for character."""
    foxy = write_rosbag2_bag(tmp_path / 'foxy', 'foxy', 'sqlite3', [TOPICS[0]], samples_only(2))
    assert (foxy / 'metadata.yaml').read_text() == (
        'rosbag2_bagfile_information:\n'
        '  version: 4\n'
        '  storage_identifier: sqlite3\n'
        '  relative_file_paths:\n'
        '    - foxy_0.db3\n'
        '  duration:\n'
        '    nanoseconds: 1000000\n'
        '  starting_time:\n'
        f'    nanoseconds_since_epoch: {T0}\n'
        '  message_count: 2\n'
        '  topics_with_message_count:\n'
        '    - topic_metadata:\n'
        '        name: /rig/sample\n'
        '        type: worm_msgs/msg/RigSample\n'
        '        serialization_format: cdr\n'
        '        offered_qos_profiles: "- history: 3\\n  depth: 0\\n  reliability: 2\\n'
        '  durability: 2\\n  deadline:\\n    sec: 9223372036\\n    nsec: 854775807\\n'
        '  lifespan:\\n    sec: 9223372036\\n    nsec: 854775807\\n  liveliness: 1\\n'
        '  liveliness_lease_duration:\\n    sec: 9223372036\\n    nsec: 854775807\\n'
        '  avoid_ros_namespace_conventions: false"\n'
        '      message_count: 2\n'
        '  compression_format: ""\n'
        '  compression_mode: ""')
    jazzy = write_rosbag2_bag(tmp_path / 'jazzy', 'jazzy', 'mcap', [TOPICS[0]], samples_only(2),
                              compression='file')
    text = (jazzy / 'metadata.yaml').read_text()
    assert text.startswith('rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n')
    assert ('        offered_qos_profiles:\n'
            '          - history: unknown\n'
            '            depth: 0\n'
            '            reliability: best_effort\n') in text
    assert f'        type_description_hash: {type_hash("worm_msgs/msg/RigSample")}\n' in text
    assert ('  compression_format: zstd\n  compression_mode: FILE\n'
            '  relative_file_paths:\n    - jazzy_0.mcap.zstd\n'
            '  files:\n    - path: jazzy_0.mcap\n') in text
    assert text.endswith('  custom_data: ~\n  ros_distro: jazzy')


def test_yaml_cpp_quoting() -> None:
    assert yaml_cpp_dump({'a': '', 'b': 'x: y', 'c': '/rig/sample', 'd': None, 'e': [], 'f': True}) == (
        'a: ""\nb: "x: y"\nc: /rig/sample\nd: ~\ne: []\nf: true')
    assert yaml_cpp_dump([{'k': {'s': 1}}]) == '- k:\n    s: 1'


def test_sqlite_schema_per_version(tmp_path: Path) -> None:
    """Foxy: WAL journal, no schema table; Humble: schema 3; Iron on: definitions, hashes."""
    tables = {}
    for layout in ('foxy', 'humble', 'iron'):
        bag = write_rosbag2_bag(tmp_path / layout, layout, 'sqlite3', [TOPICS[0]], samples_only(2))
        db = sqlite3.connect(next(bag.glob('*.db3')))
        tables[layout] = {row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if layout == 'foxy':
            assert db.execute('PRAGMA journal_mode').fetchone()[0] == 'wal'
        db.close()
    assert tables['foxy'] == {'topics', 'messages'}
    assert tables['humble'] == {'schema', 'metadata', 'topics', 'messages'}
    assert tables['iron'] == {'schema', 'metadata', 'topics', 'message_definitions', 'messages'}


def test_qos_disagreement_rosbags_reads_nothing_we_read_all(tmp_path: Path) -> None:
    """A Foxy bag reindexed by Jazzy: metadata.yaml and storage disagree on the offered QoS.

    The ``rosbags`` directory reader matches topics by QoS too and yields
    zero messages; ours matches by name, reads everything and says why.
    """
    topics = [FixtureTopic(t.name, t.type, (QosProfile.foxy(),)) for t in TOPICS]
    bag = write_rosbag2_bag(tmp_path / 'bag', 'foxy', 'sqlite3', topics, stream(),
                            max_bagfile_duration_ns=SPLIT_NS)
    with RosbagsReader(bag) as before:
        assert sum(1 for _ in before.messages()) == N_SAMPLES + 12
    reindex(bag)

    with RosbagsReader(bag) as library:
        assert library.message_count == N_SAMPLES + 12  # it believes metadata.yaml ...
        assert sum(1 for _ in library.messages()) == 0  # ... and reads nothing
    with BagReader(bag) as reader:
        assert reader.metadata is not None and reader.metadata.version == 9
        assert reader.count_messages() == {'/rig/joint_states': 12, '/rig/sample': N_SAMPLES}
        assert [m.decoded.seq for m in reader.messages(['/rig/sample'])] == list(range(N_SAMPLES))
        assert any('offered QoS in metadata.yaml differs' in w for w in reader.warnings)


def test_no_metadata_yaml_split_order_and_modes(tmp_path: Path) -> None:
    """A recorder killed before writing metadata.yaml: files read in split order (_2 before _10)."""
    for compression in ('', 'file', 'message'):
        bag = write_rosbag2_bag(tmp_path / f'bag{compression}', 'jazzy', 'sqlite3', TOPICS, stream(),
                                compression=compression, max_bagfile_duration_ns=8_000_000)
        (bag / 'metadata.yaml').unlink()
        files = storage_files(bag)
        assert len(files) == 14
        assert [f.name.split('_')[-1].split('.')[0] for f in files] == [str(i) for i in range(14)]
        with BagReader(bag) as reader:
            assert [m.decoded.seq for m in reader.messages(['/rig/sample'])] == list(range(N_SAMPLES))
            assert any('no metadata.yaml' in w for w in reader.warnings)


def test_single_storage_file_and_embedded_definitions_only(tmp_path: Path) -> None:
    """One .mcap file of a type nobody has installed: decoded from the bag's own definition."""
    definition = 'float64 x  # [m]\nstring label\n'
    topic = FixtureTopic('/probe', 'demo_msgs/msg/Probe', definition=definition, hash='RIHS01_' + '0' * 64)
    store = MessageTypes(search_prefixes=[tmp_path / 'nothing'])
    from rosbags.typesys import get_types_from_msg, get_typestore, Stores

    writer_store = get_typestore(Stores.EMPTY)
    writer_store.register(get_types_from_msg(definition, 'demo_msgs/msg/Probe'))
    probe = writer_store.types['demo_msgs/msg/Probe'](x=2.5, label='p')
    data = bytes(writer_store.serialize_cdr(probe, 'demo_msgs/msg/Probe'))
    bag = write_rosbag2_bag(tmp_path / 'bag', 'iron', 'mcap', [topic], [('/probe', T0, data)])
    with BagReader(next(bag.glob('*.mcap')), store) as reader:
        (message,) = list(reader.messages())
    assert (message.decoded.x, message.decoded.label) == (2.5, 'p')


def test_definition_text_is_rosbag2_concatenation() -> None:
    text = message_definition_text('worm_msgs/msg/RigSample')
    assert text.startswith('# One synchronized sample')
    separator = '\n' + '=' * 80 + '\n'
    assert f'{separator}MSG: std_msgs/Header\n' in text
    assert f'{separator}MSG: builtin_interfaces/Time\n' in text


def test_errors_name_file_and_key(tmp_path: Path) -> None:
    bag = write_rosbag2_bag(tmp_path / 'bag', 'humble', 'sqlite3', TOPICS, stream(),
                            max_bagfile_duration_ns=SPLIT_NS)
    meta = bag / 'metadata.yaml'
    original = meta.read_text()

    meta.write_text(original.replace('  storage_identifier: sqlite3\n', ''))
    with pytest.raises(BagReadError,
                       match=r"metadata.yaml: rosbag2_bagfile_information: missing key 'storage_identifier'"):
        BagReader(bag)
    meta.write_text(original.replace('  version: 5', '  version: five'))
    with pytest.raises(BagReadError, match=r"key 'version' is str 'five', expected int"):
        BagReader(bag)
    meta.write_text('rosbag2_bagfile_information: [\n')
    with pytest.raises(BagReadError, match='is not YAML'):
        BagReader(bag)
    meta.write_text(original)
    (bag / 'bag_3.db3').unlink()
    with pytest.raises(BagReadError, match=r"relative_file_paths lists 'bag_3.db3'"):
        BagReader(bag)
    (bag / 'bag_3.db3').write_bytes(b'not a database at all' * 100)
    with pytest.raises(BagReadError, match='bag_3.db3'):
        with BagReader(bag) as reader:
            reader.count_messages()
    with pytest.raises(BagReadError, match='No bag at'):
        BagReader(tmp_path / 'missing')


def test_truncated_mcap_reads_what_is_there(tmp_path: Path) -> None:
    """An MCAP file cut off (recorder killed): no summary, messages up to the cut are read."""
    bag = write_rosbag2_bag(tmp_path / 'bag', 'jazzy', 'mcap', TOPICS, stream())
    (mcap,) = bag.glob('*.mcap')
    cut = tmp_path / 'cut.mcap'
    data = mcap.read_bytes()
    # The Python writer chunks at 768 KiB, so the file is one chunk: cut inside the summary.
    cut.write_bytes(data[: len(data) - 200])
    with BagReader(cut) as reader:
        counts = reader.count_messages()
        assert any('no MCAP summary' in w for w in reader.warnings)
    assert counts['/rig/sample'] == N_SAMPLES


def test_storage_copy_untouched(tmp_path: Path) -> None:
    """Reading a Foxy bag (sqlite3 left in WAL mode) creates no -wal/-shm file in the bag."""
    bag = write_rosbag2_bag(tmp_path / 'bag', 'foxy', 'sqlite3', TOPICS, stream())
    before = sorted(p.name for p in bag.iterdir())
    with BagReader(bag) as reader:
        reader.count_messages()
    assert sorted(p.name for p in bag.iterdir()) == before
