"""The README stays true: its contract table and quick start match the code."""

from __future__ import annotations

import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))


def test_readme_contract_table_equals_the_code():
    from contract_table import readme_section
    from evoscen_contract.topics import contract_markdown

    section = readme_section((REPO / "README.md").read_text(encoding="utf-8"))
    assert section == contract_markdown().strip(), "run: python scripts/contract_table.py --write"


def test_quick_start_is_exactly_make_demo_and_make_test():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    quick = text.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    block = re.search(r"```(?:sh|bash)?\n(.*?)```", quick, re.S).group(1)
    assert [line.strip() for line in block.strip().splitlines()] == ["make demo", "make test"]
