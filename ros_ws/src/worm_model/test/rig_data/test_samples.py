"""The batched streams' layout as worm_model.rig_data.samples reads it: RigSamples' and SimTruths' fields, stamps."""

from __future__ import annotations

from worm_msgs.msg import RigSample, RigSamples, SimTruth, SimTruths

from worm_model.rig_data.samples import FIELDS, TRUTH_FIELDS, batch_stamps_ns, stamp_ns, unbatch


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
