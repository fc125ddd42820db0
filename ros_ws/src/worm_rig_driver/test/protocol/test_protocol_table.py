"""The protocol table: the committed C header and docs table are generated from it; link arithmetic."""
from __future__ import annotations

from pathlib import Path

import pytest

import worm_rig_driver.protocol.table as table
from worm_rig_driver.protocol.codec import encode_frame

PACKAGE = Path(__file__).resolve().parents[2]
HEADER = PACKAGE / "firmware" / "protocol_frames.h"
DOC = PACKAGE.parents[2] / "docs" / "protocol.md"


def test_committed_c_header_is_the_generated_one() -> None:
    assert HEADER.read_text() == table.c_header(), (
        f"{HEADER} differs from the table: run `python -m worm_rig_driver.protocol.table --header {HEADER}`")


def test_docs_frame_table_is_the_generated_one() -> None:
    text = DOC.read_text()
    assert text == table.splice_markdown(text), (
        f"{DOC}: the frame table differs from the table: run "
        f"`python -m worm_rig_driver.protocol.table --markdown {DOC}`")


def test_check_mode_reports_a_stale_header(tmp_path: Path) -> None:
    stale = tmp_path / "protocol_frames.h"
    stale.write_text(table.c_header().replace("PROTO_WATCHDOG_MS 50u", "PROTO_WATCHDOG_MS 500u"))
    assert table.main(["--header", str(stale), "--check"]) == 1
    assert table.main(["--header", str(stale)]) == 0
    assert table.main(["--header", str(stale), "--check"]) == 0


def test_baud_rate_is_exact_at_16_mhz() -> None:
    assert table.U2X == 1 and table.UBRR == 1
    assert table.F_CPU_HZ / (8 * (table.UBRR + 1)) == table.BAUD  # 0 % error


def test_telemetry_at_1_khz_takes_45_percent_of_the_line() -> None:
    telemetry = table.BY_NAME["TELEMETRY"]
    assert table.encoded_frame_bytes(telemetry) == 45 == len(encode_frame(
        "TELEMETRY", 1, **{x.name: 1 for x in telemetry.fields}))
    assert table.line_utilisation(telemetry, 1000) == pytest.approx(0.45)
    # Commands at 1 kHz fit the other direction with room to spare.
    assert table.line_utilisation(table.BY_NAME["SETPOINT"], 1000) == pytest.approx(0.14)


def test_every_frame_fits_the_receivers_buffer() -> None:
    for f in table.FRAMES:
        assert table.encoded_frame_bytes(f) - 1 <= table.MAX_ENCODED_LEN
    assert table.MAX_ENCODED_LEN < 255  # uint8_t lengths in the firmware


def test_frame_codes_say_who_sends_them() -> None:
    for f in table.FRAMES:
        assert (f.code < 0x80) == (f.sender == "host")
    assert len({f.code for f in table.FRAMES}) == len(table.FRAMES)


def test_table_crc_changes_with_the_table() -> None:
    assert table.TABLE_CRC == table.binascii.crc_hqx(table.table_text().encode(), 0)
    assert "TELEMETRY" in table.table_text() and "count_drive:int32_t" in table.table_text()
