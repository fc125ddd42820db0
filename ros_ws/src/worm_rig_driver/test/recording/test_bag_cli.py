"""The `bag` executable (installed console script, run as a process) and its cores.

Covers: info (counts read from storage, not metadata.yaml), echo (YAML like
ros2 topic echo), export/import round trip, --help of every command, and
exit code 2 with a message naming the file for bad input.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from rclpy.serialization import serialize_message
from worm_model.rig_data.schema import read_rig_csv
from worm_msgs.msg import RigSample
from worm_model.ros.ament import find_executable
from fixtures.rosbag2_layouts import FixtureTopic, write_rosbag2_bag

T0 = 1_700_000_000_000_000_000
N = 50


def run_bag(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(find_executable("bag")), *map(str, args)], capture_output=True, text=True,
                          timeout=120, env=dict(os.environ))


def sample(seq: int) -> RigSample:
    msg = RigSample(seq=seq, current_drive=0.1 * seq + 0.05, current_load_1=0.01 * seq,
                    current_load_2=0.02 * seq, omega_worm=150.0 - seq / 3, theta_worm=0.15 * seq,
                    theta_gear=0.15 * seq / 30, voltage_drive=12.0, tau_load=0.2 + 1e-3 * seq)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(T0 + seq * 1_000_000, 10**9)
    return msg


@pytest.fixture
def rig_bag(tmp_path: Path) -> Path:
    """A Jazzy sqlite3 bag of N RigSamples, split in two, whose metadata.yaml lies about the count."""
    messages = [('/rig/sample', T0 + s * 1_000_000 + 300, bytes(serialize_message(sample(s))))
                for s in range(N)]
    nan = sample(N)
    nan.omega_worm = math.nan  # not exportable: a required channel is NaN
    messages.append(('/rig/sample', T0 + N * 1_000_000 + 300, bytes(serialize_message(nan))))
    bag = write_rosbag2_bag(tmp_path / 'rig', 'jazzy', 'sqlite3',
                            [FixtureTopic('/rig/sample', 'worm_msgs/msg/RigSample')], messages,
                            max_bagfile_duration_ns=30_000_000)
    meta = bag / 'metadata.yaml'
    meta.write_text(meta.read_text().replace(f'      message_count: {N + 1}', '      message_count: 999'))
    return bag


def test_info_counts_from_storage(rig_bag: Path) -> None:
    done = run_bag('info', rig_bag)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert 'Files:             rig_0.db3, rig_1.db3' in out
    assert 'Metadata version:  9' in out
    assert (f'Topic: /rig/sample | Type: worm_msgs/msg/RigSample | Count: {N + 1} | '
            'Serialization Format: cdr') in out
    assert f'/rig/sample: seq 0..{N}: {N + 1} received, lost 0' in out
    assert f'metadata.yaml claims 999 messages, storage holds {N + 1}' in out


def test_echo_yaml_like_ros2_topic_echo(rig_bag: Path) -> None:
    done = run_bag('echo', rig_bag, '/rig/sample', '-n', '2')
    assert done.returncode == 0, done.stderr
    docs = done.stdout.split('---\n')
    assert docs[-1] == '' and len(docs) == 3
    first = yaml.safe_load(docs[0])
    assert list(first) == ['header', 'seq', 'current_drive', 'current_load_1', 'current_load_2',
                           'omega_worm', 'omega_gear', 'theta_worm', 'theta_gear', 'count_drive',
                           'count_load_1', 'count_load_2', 'voltage_drive', 'tau_load', 'status']
    assert first['header'] == {'stamp': {'sec': T0 // 10**9, 'nanosec': 0}, 'frame_id': ''}
    assert yaml.safe_load(docs[1])['current_drive'] == sample(1).current_drive
    assert docs[0].startswith('header:\n  stamp:\n    sec: ')


def test_export_import_export_round_trip(rig_bag: Path, tmp_path: Path) -> None:
    first_csv, second_csv = tmp_path / 'a.csv', tmp_path / 'b.csv'
    done = run_bag('export', rig_bag, '--out', first_csv)
    assert done.returncode == 0, done.stderr
    assert '1 non-finite' in done.stderr
    data = read_rig_csv(first_csv)
    assert len(data) == N
    assert data.names == ['t', 'current_drive', 'omega_worm', 'theta_worm', 'tau_load',
                          'voltage_drive', 'theta_gear', 'current_load']
    assert data.t[7] == pytest.approx(7e-3, abs=1e-15)
    assert data.current_load[4] == sample(4).current_load_1 + sample(4).current_load_2
    assert data.tau_load[9] == sample(9).tau_load

    for storage in ('mcap', 'sqlite3'):
        bag = tmp_path / f'imported_{storage}'
        done = run_bag('import', first_csv, '--out', bag, '--storage', storage, '--start', '1700000000')
        assert done.returncode == 0, done.stderr
        done = run_bag('export', bag, '--out', second_csv, '--force')  # the second storage replaces it
        assert done.returncode == 0, done.stderr
        assert second_csv.read_text() == first_csv.read_text()


def test_help_explains_every_option() -> None:
    for command, options in {'': ['info', 'echo', 'export', 'import'], 'info': ['bag'],
                             'echo': ['--count', 'topic'], 'export': ['--out', '--topic'],
                             'import': ['--out', '--storage', '--topic', '--start']}.items():
        done = run_bag(*([command] if command else []), '--help')
        assert done.returncode == 0
        for option in options:
            assert option in done.stdout, (command, option)


def test_bad_input_exits_2_naming_the_file(rig_bag: Path, tmp_path: Path) -> None:
    done = run_bag('info', tmp_path / 'nothing')
    assert done.returncode == 2 and 'no such file (expected a bag folder' in done.stderr and 'nothing' in done.stderr
    done = run_bag('echo', rig_bag, '/no/such/topic')
    assert done.returncode == 2 and "'/no/such/topic'" in done.stderr
    bad = tmp_path / 'bad.csv'
    bad.write_text('t,current_drive,omega_worm,theta_worm,tau_load\n0,1,2,3,4\n0.001,1,abc,3,4\n')
    done = run_bag('import', bad, '--out', tmp_path / 'never')
    assert done.returncode == 2
    assert f"{bad}: line 3, column 'omega_worm': 'abc' is not a number" in done.stderr
    assert not (tmp_path / 'never').exists()


def test_info_core_in_process(rig_bag: Path) -> None:
    """The same core without a process (what the console script calls)."""
    from io import StringIO

    from worm_rig_driver.recording.bag_cli import info

    out = StringIO()
    assert info(rig_bag, out) == 0
    assert f'Count: {N + 1}' in out.getvalue()


if __name__ == '__main__':
    sys.exit(pytest.main([__file__]))
