"""Where a recording goes: a new folder, beside a bag whose recorder was killed, never over anything. The bags
are real ones (BagWriter), left unclosed as a killed recorder leaves them; the recorder process killed and
started again over DDS: tests/test_respawn_dds.py."""
from __future__ import annotations

import os
from datetime import datetime
from pathlib import Path

import pytest
from rclpy.serialization import serialize_message
from worm_msgs.msg import RigSample

from worm_model.bags.writer import BagWriter, read_bag_counts
from worm_model.errors import BagRecordingError
from worm_rig_driver.recording.bag_folder import bag_folder, beside, hold, unclosed

TOPIC = '/rig/sample'


def unclosed_bag(path: Path, storage: str = 'mcap') -> BagWriter:
    """A bag with 3 messages written and flushed, not closed (no metadata.yaml): what a killed recorder leaves."""
    writer = BagWriter(path, storage)
    handle = writer.add_topic(TOPIC, 'worm_msgs/msg/RigSample')
    for seq in range(3):
        writer.write(handle, 1000 + seq, bytes(serialize_message(RigSample(seq=seq))))
    writer.flush()
    return writer


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_killed_recorders_bag_gets_a_new_folder_beside_it(tmp_path: Path, storage: str) -> None:
    """Its bag left exactly as it is (readable up to the flush); .1, then .2 once .1 exists too."""
    bag = tmp_path / 'bag'
    writer = unclosed_bag(bag, storage)
    held = hold(bag)  # the recorder that writes it, still alive
    with pytest.raises(BagRecordingError, match='another recorder is recording into it now'):
        bag_folder(str(bag))
    os.close(held)  # killed: the kernel lets go of its lock
    before = sorted((p.name, p.stat().st_size) for p in bag.iterdir())
    assert unclosed(bag)
    path, why = bag_folder(str(bag))
    assert path == tmp_path / 'bag.1' and 'no metadata.yaml' in why
    path.mkdir()
    assert bag_folder(str(bag))[0] == tmp_path / 'bag.2'
    assert sorted((p.name, p.stat().st_size) for p in bag.iterdir()) == before
    assert read_bag_counts(bag) == {TOPIC: 3}
    writer.close()  # closed: metadata.yaml written; an existing closed bag is the caller's to refuse
    assert not unclosed(bag) and bag_folder(str(bag)) == (bag, None)


def test_anything_else_is_returned_for_the_callers_check(tmp_path: Path) -> None:
    """A new name, a folder of other files, an empty folder, a file: as given (the recorder refuses what exists)."""
    (tmp_path / 'other').mkdir()
    (tmp_path / 'other' / 'notes.txt').write_text('x', encoding='utf-8')
    (tmp_path / 'empty').mkdir()
    (tmp_path / 'file.mcap').write_text('x', encoding='utf-8')
    for name in ('new', 'other', 'empty', 'file.mcap'):
        assert bag_folder(str(tmp_path / name)) == (tmp_path / name, None)


def test_the_default_name_never_meets_an_existing_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    now = datetime(2026, 1, 2, 3, 4, 5)
    assert bag_folder('', now) == (Path('rosbag2_2026_01_02-03_04_05'), None)
    Path('rosbag2_2026_01_02-03_04_05').mkdir()
    Path('rosbag2_2026_01_02-03_04_05.1').symlink_to('nowhere')  # a dangling link is taken too
    assert bag_folder('', now)[0] == Path('rosbag2_2026_01_02-03_04_05.2')
    assert beside(Path('x')) == Path('x.1')
