"""Bags of RigSample to and from the worm_rig_data schema, in process (no DDS).

The schema itself (CSV reader, writer, errors) is worm_model.rig_data.schema, tested in
worm_model's test_rig_data.py; the `bag` executable in worm_rig_driver's test_bag_cli.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from worm_model.rig_data.schema import MeasuredData, read_rig_csv
from worm_model.errors import RigDataError
from worm_model.rig_data.bags import bag_to_csv, bag_to_measured, csv_to_bag, measured_to_bag


def test_bag_round_trip_in_process(tmp_path: Path) -> None:
    data = MeasuredData(t=np.array([0.0, 0.001, 0.0025]), current_drive=np.array([1.0, 1.5, 2.0]),
                        omega_worm=np.array([3.0, 4.0, 5.0]), theta_worm=np.array([0.0, 0.1, 0.2]),
                        tau_load=np.array([0.3, 0.2, 0.1]), current_load=np.array([0.7, 0.1, 0.3]))
    assert measured_to_bag(data, tmp_path / 'bag', 'sqlite3', start_ns=1_700_000_000 * 10**9) == 3
    back = bag_to_measured(tmp_path / 'bag')
    assert back.names == data.names
    assert back.source == f'{tmp_path / "bag"}:/rig/sample' and back.skipped == {}
    for name in data.names:
        np.testing.assert_array_equal(getattr(back, name), getattr(data, name))
    with pytest.raises(RigDataError,
                       match=r"column 't': .* is beyond 2038 \(int32 seconds of builtin_interfaces/Time\)"):
        measured_to_bag(data, tmp_path / 'late', start_ns=2**31 * 10**9)


def test_csv_to_bag_to_csv_gives_the_same_file(tmp_path: Path) -> None:
    """What `bag import` then `bag export` do: the CSV comes back byte for byte (exact floats).

    t is written as export writes it, whole nanoseconds / 1e9 (stamps are integer ns).
    """
    rng = np.random.default_rng(3)
    n = 100
    first, second = tmp_path / 'a.csv', tmp_path / 'b.csv'
    first.write_text('t,current_drive,omega_worm,theta_worm,tau_load,voltage_drive,theta_gear\n' + ''.join(
        f'{k * 1_000_000 / 1e9!r},{rng.normal()!r},{rng.normal() * 100!r},{k * 0.1!r},{rng.normal()!r},12.0,'
        f'{rng.normal()!r}\n'
        for k in range(n)))
    assert csv_to_bag(first, tmp_path / 'bag', 'mcap') == n
    data = bag_to_csv(tmp_path / 'bag', second)
    assert len(data) == n and data.names == read_rig_csv(first).names
    assert second.read_text() == first.read_text()


def test_a_bad_csv_makes_no_bag(tmp_path: Path) -> None:
    bad = tmp_path / 'bad.csv'
    bad.write_text('t,current_drive,omega_worm,theta_worm,tau_load\n0,1,2,3,4\n0.001,1,abc,3,4\n')
    with pytest.raises(RigDataError, match=r"line 3, column 'omega_worm': 'abc' is not a number"):
        csv_to_bag(bad, tmp_path / 'never')
    assert not (tmp_path / 'never').exists()
