"""The worm_rig_data CSV schema: reader, writer and bag conversion (no DDS)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from worm_rig_driver.rig_csv import (
    RigCsvError,
    RigTrace,
    bag_to_trace,
    read_rig_csv,
    trace_to_bag,
    write_rig_csv,
)

HEADER = 't,current_drive,omega_worm,theta_worm,tau_load'


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / 'data.csv'
    path.write_text(text)
    return path


def test_reads_required_and_optional_columns_in_any_order(tmp_path: Path) -> None:
    path = write(tmp_path, 'tau_load,t,omega_worm,current_drive,theta_worm,temperature,note\n'
                           '0.5,0.0,10,1.25,0.1,,x\n0.5,0.001,10.5,1.5,0.2,41.5,y\n')
    trace = read_rig_csv(path)
    assert trace.names == ['t', 'current_drive', 'omega_worm', 'theta_worm', 'tau_load', 'temperature']
    assert trace['omega_worm'].tolist() == [10.0, 10.5]
    assert math.isnan(trace['temperature'][0]) and trace['temperature'][1] == 41.5


@pytest.mark.parametrize(('body', 'where'), [
    ('0,1,2,3,4\n0.001,1,,3,4\n', "line 3, column 'omega_worm': empty cell in a required column"),
    ('0,1,2,3,4\n0.001,1,2,3,inf\n', "line 3, column 'tau_load': 'inf' is not finite"),
    ('0,1,2,3,4\n0,1,2,3,4\n', "line 3, column 't': time 0.0 is not after"),
    ('0,1,2,3\n', 'line 2: 4 cells, the header has 5'),
    ('', 'no data rows'),
])
def test_errors_name_line_and_column(tmp_path: Path, body: str, where: str) -> None:
    path = write(tmp_path, HEADER + '\n' + body)
    with pytest.raises(RigCsvError) as err:
        read_rig_csv(path)
    assert str(err.value).startswith(f'{path}: ')
    assert where in str(err.value)


def test_missing_required_column_named(tmp_path: Path) -> None:
    path = write(tmp_path, 't,current_drive,omega_worm,theta_worm\n0,1,2,3\n')
    with pytest.raises(RigCsvError, match=r"line 1, column 'tau_load': missing required"):
        read_rig_csv(path)


def test_write_read_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    n = 200
    columns = {'t': np.arange(n) / 1000.0, 'current_drive': rng.normal(size=n),
               'omega_worm': rng.normal(size=n) * 100, 'theta_worm': np.cumsum(rng.random(n)),
               'tau_load': rng.normal(size=n), 'theta_gear': rng.normal(size=n)}
    columns['theta_gear'][5] = math.nan
    path = tmp_path / 'out.csv'
    write_rig_csv(path, RigTrace(columns))
    back = read_rig_csv(path)
    for name, values in columns.items():
        np.testing.assert_array_equal(back[name], values)  # bit-exact, NaN where NaN


def test_bag_round_trip_in_process(tmp_path: Path) -> None:
    trace = RigTrace({'t': np.array([0.0, 0.001, 0.0025]), 'current_drive': np.array([1.0, 1.5, 2.0]),
                      'omega_worm': np.array([3.0, 4.0, 5.0]), 'theta_worm': np.array([0.0, 0.1, 0.2]),
                      'tau_load': np.array([0.3, 0.2, 0.1]), 'current_load': np.array([0.7, 0.1, 0.3])})
    assert trace_to_bag(trace, tmp_path / 'bag', 'sqlite3', start_ns=1_700_000_000 * 10**9) == 3
    back = bag_to_trace(tmp_path / 'bag')
    assert back.names == trace.names
    for name in trace.names:
        np.testing.assert_array_equal(back[name], trace[name])
    with pytest.raises(RigCsvError, match='builtin_interfaces/Time'):
        trace_to_bag(trace, tmp_path / 'late', start_ns=2**31 * 10**9)
