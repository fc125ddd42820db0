"""Sequence-number loss accounting (the recorder's end-of-run verdict) without DDS."""

from __future__ import annotations

from rclpy.serialization import serialize_message
from worm_msgs.msg import GearboxForces, RigSample, RigSamples, SimTruths, TorqueEstimate
from worm_model.bags.typestore import MessageTypes
from worm_model.bags.seq_check import DeliveryCheck, SequenceTracker, StreamCheck, header_seq


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


def test_stream_check_counts_the_samples_of_both_batched_types() -> None:
    """RigSamples and SimTruths (the simulator's truth of every sample) carry first_seq and one array element
    per sample: a batch is that many consecutive seqs, counted from the length of its first array."""
    types = MessageTypes()
    check = StreamCheck()
    for topic, msg_type, first_field in (('/rig/samples', RigSamples, 'current_drive'),
                                         ('/sim/truth_samples', SimTruths, 'tau_load')):
        assert check.watch(topic, types.typestore, types.ensure(f'worm_msgs/msg/{msg_type.__name__}'))
        for first_seq in (1, 6, 16):  # 11..15 never came
            msg = msg_type(first_seq=first_seq, sample_period=1e-3, **{first_field: [0.1] * 5})
            msg.header.frame_id = 'worm_rig'
            check.add(topic, bytes(serialize_message(msg)))
    assert check.report() == ['/rig/samples: seq 1..20: 15 received, lost 5, gaps 11-15',
                              '/sim/truth_samples: seq 1..20: 15 received, lost 5, gaps 11-15']


def test_delivery_check_per_publisher() -> None:
    """DDS publication numbers are per publisher: two interleaved publishers are no gap."""
    check = DeliveryCheck()
    a, b = {'data': b'A'}, {'data': b'B'}
    for number, gid in [(1, a), (1, b), (2, a), (2, b), (4, a), (3, b)]:
        check.add('/rig/sample', {'publication_sequence_number': number, 'publisher_gid': gid})
    check.add('/rig/sample', None)
    assert check.lost == 1  # a's 3
    assert check.report() == [
        '/rig/sample: 6 received from 2 publisher(s), 1 missing in their DDS sequence numbers',
        '/rig/sample: 1 messages without DDS sequence numbers (not checked)']


def test_a_stream_of_every_fifth_seq_loses_nothing_by_its_step() -> None:
    """estimator_node publishes one estimate per batch of 5 samples, model_node about one force per
    20 ms: their seqs step by 5 and ~20. A missed message is a step too many, timer jitter none."""
    estimates = SequenceTracker()
    for seq in [4, 9, 14, 19, 29, 34, 39]:
        estimates.add(seq)
    assert (estimates.step, estimates.lost, estimates.gaps) == (5, 1, [(24, 24)])
    assert estimates.summary() == 'seq 4..39 (every 5): 7 received, lost 1, gaps 24'
    forces = SequenceTracker()
    for seq in [19, 39, 59, 74, 99, 119, 159, 179]:
        forces.add(seq)
    assert (forces.step, forces.lost) == (20, 1)


def test_delivery_check_without_publisher_gid() -> None:
    """rclpy < Kilted gives no publisher_gid: a topic's only publisher is tracked; with two, nothing is."""
    check = DeliveryCheck()
    check.publishers_seen('/one', 1)
    check.publishers_seen('/two', 1)
    for number in (1, 2, 4):
        check.add('/one', {'publication_sequence_number': number})
    for number in (1, 1, 2, 2):  # interleaved from two publishers, the second not yet seen
        check.add('/two', {'publication_sequence_number': number})
    check.publishers_seen('/two', 2)
    check.publishers_seen('/two', 1)  # a publisher left: still not one publisher's numbers
    check.add('/two', {'publication_sequence_number': 5})
    check.add('/unknown', {'publication_sequence_number': 1})  # never told how many
    assert check.lost == 1  # /one's 3
    assert check.report() == [
        '/one: 3 received from 1 publisher(s), 1 missing in their DDS sequence numbers'
        ' (not named by this rclpy: the only one the topic had)',
        '/two: 5 messages without DDS sequence numbers (not checked)',
        '/unknown: 1 messages without DDS sequence numbers (not checked)']


def test_a_topic_whose_publisher_sent_nothing_is_named() -> None:
    """A subscription matched to a publisher that delivered nothing (a publisher with nothing to say, or a
    middleware that matched and never fed it) is a line of the report, not an absence."""
    check = DeliveryCheck()
    check.publishers_seen('/rig/samples', 1)
    check.publishers_seen('/rig/speed_command', 1)
    check.publishers_seen('/gone', 0)
    check.add('/rig/samples', {'publication_sequence_number': 1, 'publisher_gid': {'data': b'A'}})
    assert check.report() == ['/rig/samples: 1 received from 1 publisher(s), 0 missing in their DDS sequence numbers',
                              '/rig/speed_command: nothing received from its 1 publisher(s)']
