"""The batched streams' layout as worm_model.rig_data.samples reads it: RigSamples' and SimTruths' fields, stamps."""

from __future__ import annotations

from worm_msgs.msg import RigSample, RigSamples, SimTruth, SimTruths

from worm_model.rig_data.samples import FIELDS, TRUTH_FIELDS, batch_stamps_ns, command_latencies, stamp_ns, unbatch


def test_batched_fields_are_the_single_messages_fields_in_order() -> None:
    """A batch holds one array per field of its single-sample message, in that message's order (header and seq
    aside), and nothing else but first_seq, sample_period (and RigSamples' command_seq)."""
    for single, batch, fields, extra in ((RigSample, RigSamples, FIELDS, ["command_seq"]),
                                         (SimTruth, SimTruths, TRUTH_FIELDS, [])):
        one = single.get_fields_and_field_types()
        many = batch.get_fields_and_field_types()
        assert list(one) == ["header", "seq", *fields]
        assert list(many) == ["header", "first_seq", "sample_period", *fields, *extra]
        assert all(many[name] == f"sequence<{one[name]}>" for name in fields), batch.__name__


def test_sample_k_of_a_batch_is_stamped_k_periods_after_the_first() -> None:
    truths = SimTruths(first_seq=41, sample_period=1e-3, tau_load=[0.0] * 5)
    truths.header.stamp.sec, truths.header.stamp.nanosec = 7, 999_500_000
    assert batch_stamps_ns(truths, 5) == [7_999_500_000 + k * 1_000_000 for k in range(5)]
    samples = RigSamples(first_seq=41, sample_period=1e-3, **{name: [0] * 5 for name in FIELDS})
    samples.header.stamp = truths.header.stamp
    assert [stamp_ns(s.header.stamp) for s in unbatch(samples)] == batch_stamps_ns(truths, 5)
    assert [s.seq for s in unbatch(samples)] == list(range(41, 46))


def test_command_latency_is_counted_from_the_source_sample_to_the_first_period_it_drove() -> None:
    # (seq, command_seq): command 3 was in force before the window (skipped: its first period is unknown),
    # command 5 first drives the period of sample 7 (1 period late), command 9 that of sample 10 (0)
    stream = [(4, 3), (5, 3), (6, 3), (7, 5), (8, 5), (9, 5), (10, 9), (11, 9)]
    batch = RigSamples(first_seq=4, sample_period=1e-3, command_seq=[command for _, command in stream],
                       **{name: [0] * len(stream) for name in FIELDS})
    assert [s.seq for s in unbatch(batch)] == [seq for seq, _ in stream]
    assert command_latencies(unbatch(batch)) == [1, 0]
    # a run from its start: no command at first (command_seq 0), then each one counted
    start = RigSamples(first_seq=1, sample_period=1e-3, command_seq=[0, 1], **{name: [0] * 2 for name in FIELDS})
    assert command_latencies(unbatch(start)) == [0]
