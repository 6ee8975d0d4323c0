"""Scripts are thin doors (docs/development.md, "Scripts"): each parses its arguments with the one shared
argument module, :mod:`evoscen.cli`, and calls a package; no script over 150 lines and no function in a
script over 80; a door that ranks or compares says by which score in its ``--help``."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_rooms import size_offenders

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = sorted(p for p in (REPO / "scripts").glob("*.py") if p.name != "_bootstrap.py")
MAX_SCRIPT_LINES = 150
MAX_SCRIPT_FUNCTION_LINES = 80
RANKING = {"experiment_sensitivity", "leaderboard", "experiment_intelligence", "campaign"}
"""Doors whose output ranks or compares SUTs, scenarios or mutants by a score."""


def test_every_script_is_within_the_door_limits() -> None:
    import test_rooms

    assert len(SCRIPTS) >= 30
    saved = test_rooms.MAX_FUNCTION_LINES, test_rooms.MAX_MODULE_LINES
    try:
        test_rooms.MAX_FUNCTION_LINES, test_rooms.MAX_MODULE_LINES = MAX_SCRIPT_FUNCTION_LINES, MAX_SCRIPT_LINES
        offenders = size_offenders({f"scripts.{p.stem}": p for p in SCRIPTS})
    finally:
        test_rooms.MAX_FUNCTION_LINES, test_rooms.MAX_MODULE_LINES = saved
    assert offenders == [], "doors too long: " + "; ".join(offenders)


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_every_script_parses_with_the_shared_module(script: Path) -> None:
    tree = ast.parse(script.read_text(encoding="utf-8"))
    imports = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    froms = {(node.module, alias.name) for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
             for alias in node.names}
    assert ("evoscen", "cli") in froms or "evoscen.cli" in imports, f"{script.name} does not use evoscen.cli"
    assert "ArgumentParser(" not in script.read_text(encoding="utf-8"), f"{script.name} builds its own parser"


@pytest.mark.parametrize("name", sorted(RANKING))
def test_a_ranking_door_names_its_score_in_help(name: str) -> None:
    import subprocess

    res = subprocess.run([sys.executable, str(REPO / "scripts" / f"{name}.py"), "--help"], capture_output=True,
                         text=True, timeout=120, cwd=REPO)
    assert res.returncode == 0, res.stderr
    assert "Ranks by: D, the comparative score" in " ".join(res.stdout.split()), res.stdout
