"""The README stays true: its quick start and results table match the code and the stored results; the topic
contract of docs/topics.md matches the code."""

from __future__ import annotations

import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))


def test_the_contract_table_of_docs_topics_equals_the_code():
    from contract_table import contract_section
    from evoscen_contract.topics import contract_markdown

    section = contract_section((REPO / "docs" / "topics.md").read_text(encoding="utf-8"))
    assert section == contract_markdown().strip(), "run: python scripts/contract_table.py --write"


def test_quick_start_is_exactly_make_demo_and_make_test():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    quick = text.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    block = re.search(r"```(?:sh|bash)?\n(.*?)```", quick, re.S).group(1)
    assert [line.strip() for line in block.strip().splitlines()] == ["make demo", "make test"]


def test_the_foxglove_layout_shows_contract_topics_and_fields():
    """docs/foxglove/evoscen-layout.json: every panel in the layout tree has a config, and the topics and
    message paths it reads exist in the contract (a renamed topic or field fails here)."""
    import json

    from evoscen_contract import contract as C

    layout = json.loads((REPO / "docs" / "foxglove" / "evoscen-layout.json").read_text(encoding="utf-8"))
    panels = layout["configById"]

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(panels) == ["3D!evoscen", "Plot!evoscen", "RawMessages!evoscen"]
    assert set(panels["3D!evoscen"]["topics"]) == {C.TOPIC_MAP_MARKERS, C.TOPIC_MARKERS}
    assert [p["value"] for p in panels["Plot!evoscen"]["paths"]] == [f"{C.TOPIC_SUT_ODOM}.twist.twist.linear.x"]
    assert C.TOPIC_TYPES[C.TOPIC_SUT_ODOM] == "nav_msgs/msg/Odometry"  # twist: TwistWithCovariance, .twist.linear.x
    assert panels["RawMessages!evoscen"]["topicPath"] == C.TOPIC_EVENTS
    assert "docs/foxglove/evoscen-layout.json" in (REPO / "README.md").read_text(encoding="utf-8")
