"""``scripts/exposure_rules.py`` and ``scripts/repeat_tests.py``: their figures from what they read, and
bad input as one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _script(name: str, *args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(REPO / "scripts" / name), *map(str, args)], cwd=REPO,
                          capture_output=True, text=True, timeout=600, check=False)


@pytest.mark.e2e
def test_exposure_rules_counts_the_reports_rules(tmp_path):
    """Two episodes of MOBIL: every per-rule mean is the mean of the episodes' counts in the JSON, and the
    exposure count of each episode is at most the sum of its per-rule counts (one exposure may name several)."""
    out = tmp_path / "e.json"
    res = _script("exposure_rules.py", "--suts", "mobil", "--seeds", "473018:473019", "--episode-steps", 150,
                  "--out", out)
    assert res.returncode == 0, res.stderr
    eps = json.loads(out.read_text())["mobil"]
    assert sorted(eps) == ["473018", "473019"]
    row = next(line for line in res.stdout.splitlines() if line.startswith("| mobil |")).split(" | ")
    assert row[-1] == "2 |"
    mean = sum(e["exposures"] for e in eps.values()) / 2
    assert row[1].split()[0] == f"{mean:.3f}"
    for e in eps.values():
        assert e["exposures"] <= sum(e["by_rule"].values())
        assert (e["exposures"] == 0) == (sum(e["by_rule"].values()) == 0)


@pytest.mark.parametrize("args, expected", [
    (["--suts", "mobil", "--seeds", "5:3"], "error: --seeds"),
    (["--suts", "mobil", "--seeds", "1:2", "--episode-steps", "0"], "error: --episode-steps"),
    (["--suts", "mobil", "--seeds", "1:2", "--set", "nokey"], "error: --set 'nokey': expected KEY=VALUE"),
    (["--suts", "nobody", "--seeds", "1:1", "--episode-steps", "5"], "error: "),
])
def test_exposure_rules_bad_input_is_one_line(args, expected):
    res = _script("exposure_rules.py", *args)
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(expected), lines


def test_repeat_tests_reads_outcomes_from_junit(tmp_path):
    """A failure and a setup error of one test count once, as failed; skipped and passed as they are."""
    sys.path.insert(0, str(REPO / "scripts"))
    try:
        from repeat_tests import outcomes, parse_args
    finally:
        sys.path.pop(0)
    xml = tmp_path / "r.xml"
    xml.write_text('<testsuites><testsuite>'
                   '<testcase classname="t" name="a"/>'
                   '<testcase classname="t" name="b"><failure message="boom&#10;more">x</failure></testcase>'
                   '<testcase classname="t" name="b"><error message="teardown">y</error></testcase>'
                   '<testcase classname="t" name="c"><skipped message="no sumo"/></testcase>'
                   '</testsuite></testsuites>', encoding="utf-8")
    assert outcomes(xml) == {"t::a": ("passed", ""), "t::b": ("failed", "boom"), "t::c": ("skipped", "no sumo")}
    args = parse_args(["--times", "3", "--", "tests/x.py", "-k", "y"])
    assert (args.times, args.pytest_args) == (3, ["tests/x.py", "-k", "y"])


@pytest.mark.parametrize("args, expected", [(["--times", "0", "--", "x"], "error: --times = '0': expected an integer >= 1"),
                                            (["--times", "2"], "expected the tests to repeat after --")])
def test_repeat_tests_bad_arguments(args, expected):
    res = _script("repeat_tests.py", *args)
    assert res.returncode == 2 and expected in res.stderr and "Traceback" not in res.stderr, res.stderr
