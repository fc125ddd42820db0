"""EPOS Studio exports through the tools that read rig data: a bad export is one line and exit 2 in each of
``estimate``, ``residuals`` and ``identify --from``; ``estimate`` reads a good one with the load given."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import worm_model
from worm_model.residuals.cli import main as residuals_main

from torque_estimator.identification.identify import main as identify_main
from torque_estimator.offline.estimate import main as estimate_main

DATA = Path(worm_model.__file__).resolve().parent / "data"
STEADY = DATA / "tro2021" / "driveNo3" / "steady_state" / "0.096kg"
RIG = DATA / "tro2021_worm_rig.yaml"
GOOD = (STEADY / "100.csv").read_text(encoding="utf-8")

BAD = {  # what is broken -> (the file's bytes, words of the one line)
    "truncated": ("\n".join(GOOD.splitlines()[:300]).encode(), "truncated: the header says 500 recorded samples"),
    "wrong separator": (GOOD.replace(";", ",").encode(), "separated by ',', not ';'"),
    "binary": (b"Date:;\x00\x00\x07\xff\xfe" * 100, "binary data"),
    "missing column": (GOOD.replace("Torque actual value averaged", "Following error").encode(),
                       "no torque or current channel"),
}


def run(tool: str, path: Path, tmp_path: Path) -> int:
    if tool == "estimate":
        return estimate_main([str(path), "--method", "extended_model", "--rig", str(RIG), "--out",
                              str(tmp_path / "est.csv"), "--load-torque", "0.0188", "--quiet"])
    if tool == "residuals":
        return residuals_main([str(path), "--rig", str(RIG), "--out", str(tmp_path / "res"), "--quiet"])
    return identify_main(["--from", str(path), "--rig", str(RIG), "--out", str(tmp_path / "id.yaml"),
                          "--quiet"])


@pytest.mark.parametrize("tool", ["estimate", "residuals", "identify"])
@pytest.mark.parametrize("broken", list(BAD))
def test_a_bad_export_is_one_line_and_exit_2(tool: str, broken: str, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    content, words = BAD[broken]
    path = tmp_path / "export.csv"
    path.write_bytes(content)
    assert run(tool, path, tmp_path) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{tool}: ") and str(path) in err[0] and words in err[0], err
    assert not (tmp_path / "res").exists() and not (tmp_path / "id.yaml").exists()


def test_estimate_reads_exports_with_the_load_and_refuses_dirty_rows(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "exports"
    folder.mkdir()
    for name in ("100.csv", "n100.csv", "n1.csv"):
        shutil.copy(STEADY / name, folder / name)
    argv = [str(folder), "--method", "extended_model", "--rig", str(RIG), "--out", str(tmp_path / "est.csv"),
            "--load-mass", "0.096", "--pulley-radius", "0.02", "--gravity", "9.812", "--quiet"]
    assert estimate_main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{folder / 'n1.csv'}: line 15: stray text 'was 22.1'" in err[0]
    assert "1 dirty row(s) in 1 of the folder's 3 files: refused" in err[0]
    assert estimate_main([*argv, "--skip-bad-rows"]) == 0
    out = capsys.readouterr().out
    assert f"estimate: note: skipped: {folder / 'n1.csv'}: line 15: " in out
    assert "estimate: the log has one load, 0.0188 N m: errors in % of it" in out
    assert "method=extended_model" in out.splitlines()[-1] and (tmp_path / "est.csv").stat().st_size > 0
    assert estimate_main([*argv[:-7], "--load-mass", "0.096", "--quiet", "--force"]) == 2
    assert "--pulley-radius: a hanging load needs both" in capsys.readouterr().err


@pytest.mark.parametrize("tool", ["residuals", "identify"])
def test_residuals_and_identify_take_the_load_options_and_the_skip(tool: str, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """The load the exports do not carry reaches the fit: without it the file is refused; with it (and the
    dirty row skipped, listed) the tool runs to its last line."""
    folder = tmp_path / "exports"
    folder.mkdir()
    for name in ("1.csv", "40.csv", "100.csv", "200.csv", "n4.csv", "n40.csv", "n100.csv", "n200.csv"):
        shutil.copy(STEADY / name, folder / name)
    load = ["--load-mass", "0.096", "--pulley-radius", "0.02", "--gravity", "9.812"]
    if tool == "residuals":
        argv = [str(folder), "--rig", str(RIG), "--out", str(tmp_path / "res"), "--quiet", "--no-plots",
                "--min-speed", "0.05", *load]
        main = residuals_main
    else:
        argv = ["--from", str(folder), "--rig", str(RIG), "--out", str(tmp_path / "id.yaml"), "--quiet", *load]
        main = identify_main
    assert main(argv) == 2  # 1.csv's edited first row, refused
    assert "--skip-bad-rows" in capsys.readouterr().err
    assert main([*argv, "--skip-bad-rows"]) == 0
    out = capsys.readouterr().out
    assert f"{tool}: note:" in out and "1.csv: line 15" in out
    if tool == "residuals":  # the exports carry torque, not current: K_t cannot be fitted, and is not
        assert "drive_motor.torque_constant held at its declared value" in out
        assert "drive_motor.torque_constant" not in out.split("fitted parameters:")[1].split("(")[0]
    assert (tmp_path / "res" / "report.json").exists() if tool == "residuals" else (tmp_path / "id.yaml").exists()
