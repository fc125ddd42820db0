"""docs/foxglove_health_layout.json plots what worm_msgs/GearboxHealth carries, and its indicator knows its levels."""
from __future__ import annotations

import json
from pathlib import Path

from worm_msgs.msg import GearboxHealth

LAYOUT = Path(__file__).resolve().parents[5] / "docs" / "foxglove_health_layout.json"


def test_every_panel_reads_a_field_of_the_health_message() -> None:
    layout = json.loads(LAYOUT.read_text(encoding="utf-8"))
    fields = GearboxHealth.get_fields_and_field_types()
    panels = layout["configById"]
    paths = [p["value"] for panel in panels.values() for p in panel.get("paths", [])]
    paths += [panel["path"] for panel in panels.values() if "path" in panel]
    assert paths and all(p.startswith("/health.") for p in paths)
    for path in paths:
        assert fields.get(path[len("/health."):]) in ("double", "uint8"), path
    rules = panels["Indicator!health_level"]["rules"]
    assert [int(r["rawValue"]) for r in rules] == [GearboxHealth.LEVEL_OK, GearboxHealth.LEVEL_WARN,
                                                   GearboxHealth.LEVEL_ERROR]
    assert panels["DiagnosticSummary!health"]["topicToRender"] == "/diagnostics"

    def leaves(node) -> set[str]:
        return {node} if isinstance(node, str) else leaves(node["first"]) | leaves(node["second"])

    assert leaves(layout["layout"]) == set(panels)  # every panel placed, none missing
