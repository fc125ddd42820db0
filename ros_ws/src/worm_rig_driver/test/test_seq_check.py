"""Sequence-number loss accounting (the recorder's end-of-run verdict) without DDS."""

from __future__ import annotations

from rclpy.serialization import serialize_message
from worm_msgs.msg import GearboxForces, RigSample, TorqueEstimate
from worm_rig_driver.bag_types import MessageTypes
from worm_rig_driver.seq_check import SequenceTracker, StreamCheck, header_seq


def test_header_seq_reads_cdr_of_every_frame_id_length() -> None:
    for frame_id in ('', 'a', 'rig', 'worm_rig', 'a' * 13):
        for msg_type in (RigSample, GearboxForces, TorqueEstimate):
            msg = msg_type(seq=2**40 + 7)
            msg.header.frame_id = frame_id
            assert header_seq(bytes(serialize_message(msg))) == 2**40 + 7


def test_tracker_counts_gaps_and_repeats() -> None:
    tracker = SequenceTracker()
    for seq in [5, 6, 7, 10, 11, 11, 9, 12, 20]:
        tracker.add(seq)
    assert (tracker.first, tracker.last, tracker.count) == (5, 20, 9)
    assert tracker.lost == 2 + 7
    assert tracker.repeated == 2
    assert tracker.gaps == [(8, 9), (13, 19)]
    assert 'lost 9' in tracker.summary() and 'gaps 8-9, 13-19' in tracker.summary()


def test_stream_check_tracks_only_types_with_seq() -> None:
    types = MessageTypes()
    check = StreamCheck()
    assert check.watch('/rig/sample', types.typestore, types.ensure('worm_msgs/msg/RigSample'))
    assert not check.watch('/rig/load_command', types.typestore, types.ensure('worm_msgs/msg/LoadCommand'))
    for seq in (0, 1, 3):
        check.add('/rig/sample', bytes(serialize_message(RigSample(seq=seq))))
    check.add('/rig/load_command', b'\x00\x01\x00\x00')
    check.add('/rig/sample', b'\x00\x01\x00\x00')  # truncated
    assert check.lost == 1
    assert check.report() == ['/rig/sample: seq 0..3: 3 received, lost 1, gaps 2',
                              '/rig/sample: 1 messages too short to hold a seq']
