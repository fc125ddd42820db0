"""The input policy (worm_model.files.reading): regular files only, a FIFO refused without being opened,
UTF-8 with or without a byte-order mark, YAML and JSON within limits, ROS parameter files as rcl reads them."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from worm_model.errors import InputError
from worm_model.cli.options import existing_file, existing_input
from worm_model.files.reading import (MAX_YAML_DEPTH, MAX_YAML_NODES, check_input, inputs_read, load_json,
                                      load_parameter_file, load_yaml, parse_json, parse_yaml, read_text)
from worm_model.physics.parameters import default_rig_path, load_rig


def bomb(levels: int, fan_out: int = 10) -> str:
    """A 'billion laughs' document: ``levels`` anchors of ``fan_out`` aliases each (fan_out**levels values)."""
    lines = [f"l0: &l0 [{', '.join(['lol'] * fan_out)}]"]
    lines += [f"l{k}: &l{k} [{', '.join([f'*l{k - 1}'] * fan_out)}]" for k in range(1, levels)]
    return "\n".join(lines) + "\n"


def test_a_fifo_is_refused_without_being_opened(tmp_path: Path) -> None:
    """Opening a FIFO for reading waits for a writer: the reader must refuse it from its stat alone (this
    test would hang otherwise)."""
    fifo = tmp_path / "rig.yaml"
    os.mkfifo(fifo)
    for read in (lambda: read_text(fifo), lambda: load_yaml(fifo), lambda: load_json(fifo),
                 lambda: load_parameter_file(fifo), lambda: load_rig(fifo)):
        with pytest.raises(ValueError, match="FIFO"):
            read()
    with pytest.raises(Exception, match="FIFO"):
        existing_file(str(fifo))


def test_devices_and_folders_where_a_file_is_expected(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="character device"):
        read_text("/dev/null")
    with pytest.raises(InputError, match="is a folder, expected a rig file"):
        check_input(tmp_path, "rig file")
    assert check_input(tmp_path, "bag", folder=True) == tmp_path  # a bag folder is fine where a bag is expected
    assert existing_input(str(tmp_path)) == tmp_path
    with pytest.raises(InputError, match="no such file"):
        check_input(tmp_path / "missing.yaml")
    with pytest.raises(InputError, match="empty path"):
        check_input("")


def test_files_read_are_remembered_for_the_output_policy(tmp_path: Path) -> None:
    path = tmp_path / "a.yaml"
    path.write_text("a: 1\n")
    load_yaml(path)
    assert path.resolve() in inputs_read()


def test_a_byte_order_mark_is_dropped(tmp_path: Path) -> None:
    """Editors and spreadsheets write UTF-8 with a BOM: the text, the YAML and the JSON read as without it."""
    path = tmp_path / "f"
    path.write_bytes(b"\xef\xbb\xbfa: 1\n")
    assert read_text(path) == "a: 1\n" and load_yaml(path) == {"a": 1}
    path.write_bytes(b"\xef\xbb\xbf{\"a\": 1}")
    assert load_json(path) == {"a": 1}
    rig = tmp_path / "rig.yaml"
    rig.write_bytes(b"\xef\xbb\xbf" + default_rig_path().read_bytes())
    assert load_rig(rig).name == load_rig().name


def test_anchors_and_merge_keys_are_read_in_tool_files() -> None:
    """The bundled rig file shares its motor section by an anchor and a merge key."""
    text = default_rig_path().read_text()
    assert "&dp20" in text and "<<: *dp20" in text
    rig = load_rig()
    assert rig.load_motor.torque_constant == rig.drive_motor.torque_constant
    assert rig.load_motor.viscous_drag != rig.drive_motor.viscous_drag  # the merge's own key wins


def test_a_billion_laughs_is_refused_where_it_starts() -> None:
    """10^9 values from 9 lines: refused at the alias that passes the limit, naming its line, before any
    expansion (PyYAML builds shared references, but every consumer that copies or dumps them expands)."""
    with pytest.raises(InputError, match=r"bomb.yaml: line 6, column 5: refused: .*billion laughs"):
        parse_yaml(bomb(9), "bomb.yaml")  # 10^6 at l5 (line 6) is the first node past 200 000
    assert parse_yaml(bomb(5), "ok.yaml")["l4"][0][0][0][0][0] == "lol"  # 10^5 values: within the limit
    with pytest.raises(InputError, match="billion laughs"):
        parse_yaml(bomb(40, fan_out=2), "wide.yaml")  # 2^40 by doubling


def test_nesting_is_limited_before_python_runs_out_of_stack() -> None:
    deep = "a: " + "[" * MAX_YAML_DEPTH + "]" * MAX_YAML_DEPTH
    with pytest.raises(InputError, match=f"nested deeper than {MAX_YAML_DEPTH}"):
        parse_yaml(deep, "deep.yaml")
    parse_yaml("a: " + "[" * (MAX_YAML_DEPTH - 1) + "]" * (MAX_YAML_DEPTH - 1), "ok.yaml")
    with pytest.raises(InputError, match="nested"):
        parse_yaml("a: " + "[" * 100_000 + "]" * 100_000, "deeper.yaml")
    with pytest.raises(InputError, match="nested too deeply"):
        parse_json("[" * 100_000 + "]" * 100_000, "deep.json")
    assert MAX_YAML_NODES >= 100 * 400  # a rig file has ~400 nodes


def test_a_parameter_file_is_read_as_rcl_reads_it(tmp_path: Path) -> None:
    path = tmp_path / "graph.yaml"
    path.write_text("estimator_node:\n  ros__parameters:\n    k: 4\n    filter:\n      tau: 0.1\n"
                    "ns:\n  model_node:\n    ros__parameters: {use_acceleration: true}\n"
                    "/**:\n  ros__parameters: {use_sim_time: false}\n")
    assert load_parameter_file(path) == {"estimator_node": {"k": 4, "filter.tau": 0.1},
                                         "ns/model_node": {"use_acceleration": True},
                                         "/**": {"use_sim_time": False}}
    refused = {
        "estimator_node:\n  ros__parameters: &p {k: 4}\nmodel_node:\n  ros__parameters: *p\n": "line 2.*&p.*anchors",
        "a:\n  ros__parameters: &p {k: 4}\nb:\n  ros__parameters:\n    <<: *p\n": "anchors, aliases or merge keys",
        "estimator_node:\n  ros__parameters:\n    exclude: [1, two]\n": "one type",
        "estimator_node:\n  k: 4\n  ros__parameters: {method: knn}\n": "'k' beside ros__parameters",
        "estimator_node: 4\n": "expected 'ros__parameters:'",
        "- a\n- b\n": "node names at the top level",
        "estimator_node: {ros__parameters: {k: 4}\n": "not valid YAML",
    }
    for text, message in refused.items():
        path.write_text(text)
        with pytest.raises(InputError, match=message):
            load_parameter_file(path)


def test_the_users_page_states_the_limits_in_force() -> None:
    from worm_model.files.reading import MAX_YAML_BYTES
    page = (Path(__file__).resolve().parents[5] / "docs" / "files-and-inputs.md").read_text(encoding="utf-8")
    for figure in (f"at most {MAX_YAML_BYTES} bytes", f"at most {MAX_YAML_DEPTH} levels",
                   f"at most {MAX_YAML_NODES} values"):
        assert figure in page, figure
