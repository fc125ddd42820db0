"""The output policy (worm_model.files.writing): an output never is, holds or lies inside an input; never the
root, home or working folder; --force only over the same tool's earlier output; atomic, naming the user's path."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from worm_model.files.reading import read_text
from worm_model.files.writing import MARKER, Output, atomic_dir, atomic_file, check_output, write_text_atomically
from worm_model.errors import OutputError

TOOL = Output("mytool", recognise=lambda path: path.read_text().startswith("mytool"), names=("*.png",))


@pytest.fixture()
def here(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A working folder holding the user's files: data.csv, bag/ (a folder input), notes.txt."""
    work = tmp_path / "work"
    (work / "bag").mkdir(parents=True)
    (work / "bag" / "b.mcap").write_bytes(b"mcap")
    (work / "data.csv").write_text("t\n0\n")
    (work / "notes.txt").write_text("mine\n")
    monkeypatch.chdir(work)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    (tmp_path / "home").mkdir()
    return work


def refused(path: str | Path, message: str, **kwargs) -> None:
    with pytest.raises(OutputError, match=message) as info:
        check_output(path, output=TOOL, **kwargs)
    assert str(info.value).startswith(kwargs.get("option", "--out"))


def test_never_an_input_a_folder_holding_one_or_a_place_inside_one(here: Path) -> None:
    inputs = ["data.csv", "bag"]
    refused("data.csv", "is an input", force=True, inputs=inputs)
    refused(here, "working folder", force=True, folder=True, inputs=inputs)
    refused("bag", "is an input", force=True, folder=True, inputs=inputs)
    refused("bag/out.csv", "inside the input folder bag", inputs=inputs)
    os.symlink("data.csv", "link.csv")
    refused("link.csv", "is an input", force=True, inputs=inputs)  # the same file by another name
    os.link("data.csv", "hard.csv")
    refused("hard.csv", "is an input", force=True, inputs=inputs)
    (here / "d").mkdir()
    (here / "d" / "in.csv").write_text("t\n")
    refused("d", "holds an input", force=True, folder=True, inputs=["d/in.csv"])
    read_text(here / "notes.txt")  # a file the run has read counts as an input without being named
    refused("notes.txt", "is an input", force=True)


def test_never_empty_the_root_home_or_working_folder_or_above(here: Path) -> None:
    for path, message in (("", "empty path"), (".", "working folder"), ("..", "holds the working folder"),
                          ("/", "root"), (os.environ["HOME"], "home folder")):
        refused(path, message, force=True, folder=True)


def test_force_replaces_only_the_tools_own_earlier_output(here: Path) -> None:
    (here / "mine").mkdir()
    (here / "mine" / "thesis.tex").write_text("years of work\n")
    refused("mine", "exists; pass --force", folder=True)
    refused("mine", "not a folder written by mytool", force=True, folder=True)
    (here / "mine" / MARKER).write_text("othertool\n")
    refused("mine", "not a folder written by mytool", force=True, folder=True)
    (here / "ours").mkdir()
    (here / "ours" / MARKER).write_text("mytool\n")
    (here / "ours" / "fig.png").write_bytes(b"png")
    assert check_output("ours", True, folder=True, output=TOOL) == Path("ours")
    (here / "old").mkdir()  # written before folders carried the marker: only names the tool writes
    (here / "old" / "fig.png").write_bytes(b"png")
    assert check_output("old", True, folder=True, output=TOOL) == Path("old")
    (here / "empty").mkdir()
    assert check_output("empty", True, folder=True, output=TOOL) == Path("empty")
    refused("notes.txt", "not a file written by mytool", force=True)
    (here / "result.txt").write_text("mytool result\n")
    assert check_output("result.txt", True, output=TOOL) == Path("result.txt")
    with pytest.raises(OutputError, match="not a file one this tool writes"):
        check_output("result.txt", True)  # a tool that says nothing of its output never replaces a file


def test_a_folder_output_appears_whole_with_its_marker_or_not_at_all(here: Path) -> None:
    with atomic_dir("out", output=TOOL) as tmp:
        (tmp / "fig.png").write_bytes(b"png")
    assert sorted(p.name for p in (here / "out").iterdir()) == [MARKER, "fig.png"]
    assert (here / "out" / MARKER).read_text() == "mytool\n"
    with pytest.raises(KeyboardInterrupt), atomic_dir("out", True, output=TOOL) as tmp:
        (tmp / "fig.png").write_bytes(b"new")
        raise KeyboardInterrupt  # Ctrl-C half way: the old output stays, no temporary folder is left
    assert (here / "out" / "fig.png").read_bytes() == b"png"
    assert sorted(p.name for p in here.iterdir()) == ["bag", "data.csv", "notes.txt", "out"]
    with atomic_dir("out", True, output=TOOL) as tmp:
        (tmp / "fig.png").write_bytes(b"new")
    assert (here / "out" / "fig.png").read_bytes() == b"new"


def test_an_input_read_during_the_run_is_checked_again_before_the_output_is_put_in_place(here: Path) -> None:
    (here / "result.txt").write_text("mytool result\n")
    with pytest.raises(OutputError, match="is an input"), atomic_file("result.txt", True, output=TOOL) as tmp:
        tmp.write_text("mytool new\n")
        read_text(here / "result.txt")  # the run read it after all
    assert (here / "result.txt").read_text() == "mytool result\n"
    assert sorted(p.name for p in here.iterdir()) == ["bag", "data.csv", "notes.txt", "result.txt"]


def test_an_unwritable_place_is_refused_before_any_work_naming_the_option_and_path() -> None:
    """Permissions do not tell for root or a read-only file system: the folder is tried."""
    with pytest.raises(OutputError, match=r"^--out /proc/out: folder /proc: cannot write there"):
        check_output("/proc/out", folder=True)
    with pytest.raises(OutputError, match=r"^--template /proc/t.yaml"):
        with atomic_file("/proc/t.yaml", option="--template") as tmp:
            tmp.write_text("never")


def test_a_failed_write_names_the_file_meant_not_the_temporary_one(tmp_path: Path) -> None:
    with pytest.raises(OSError) as info:
        write_text_atomically("/proc/journal.partial", "x")
    assert info.value.filename == "/proc/journal.partial"
