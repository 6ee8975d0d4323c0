"""The README stays true: its quick start and results table match the code and the stored results; the topic
contract of docs/topics.md matches the code."""

from __future__ import annotations

import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))


def test_the_contract_table_of_docs_topics_equals_the_code():
    from evoscen_contract.topics import contract_markdown, contract_section

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


def test_the_results_table_equals_the_one_generated_from_the_results_file():
    from evoscen_experiments.results_table import load_results, readme_table, results_file, results_markdown

    text = (REPO / "README.md").read_text(encoding="utf-8")
    name = results_file(text)
    assert name == "results/readme.yaml"
    assert readme_table(text) == results_markdown(load_results(REPO / name, name)), "run: make readme-table"


TINY = """\
commands: {score: python scripts/experiment_intelligence.py --seeds 3, defects: python scripts/experiment_sensitivity.py}
defects_n: 4
defects_seeds: 10-13
rows:
  - {sut: mobil, score: 0.6691, score_ci: 0.0768, n: 3, seeds: 7-9, defects: 8 of 12, makeup: highd, version: "9.9"}
  - {sut: level0, note: the lane keeper, score: 0.7805, score_ci: 0.02949, n: 3, seeds: 7-9, defects: null,
     makeup: uniform, version: "9.9"}
"""


def test_the_generator_by_hand(tmp_path):
    """Means and half-widths to 3 decimals, 'k of m' or a dash, the one design named under the table."""
    from evoscen_experiments.results_table import load_results, results_markdown, rewrite_readme

    (tmp_path / "r.yaml").write_text(TINY, encoding="utf-8")
    lines = results_markdown(load_results(tmp_path / "r.yaml", "r.yaml")).splitlines()
    assert lines[:4] == ["| SUT | score ± 95 % interval | defects detected | make-up | version |",
                         "|---|---|---|---|---|",
                         "| `mobil` | 0.669 ± 0.077 | 8 of 12 | `highd` | 9.9 |",
                         "| `level0` (the lane keeper) | 0.781 ± 0.029 | – | `uniform` | 9.9 |"]
    assert lines[4] == "" and len(lines) == 6
    assert lines[5].startswith("Score: D (comparative score")
    for part in ("n = 3 seeds (7–9)", "paired by seed", "n = 4 paired episodes (10–13)", "the commands: [r.yaml](r.yaml)."):
        assert part in lines[5], part
    readme = "# x\n\n<!-- results-table: r.yaml -->\nold\n<!-- /results-table -->\n\nafter\n"
    new = rewrite_readme(readme, tmp_path)
    assert new == "# x\n\n<!-- results-table: r.yaml -->\n" + "\n".join(lines) + "\n<!-- /results-table -->\n\nafter\n"
    assert rewrite_readme(new, tmp_path) == new


def test_a_missing_or_malformed_field_is_one_line_naming_the_file_and_the_field(tmp_path):
    import pytest
    from evoscen_experiments.results_table import load_results
    from evoscen_sim.errors import InputError

    path = tmp_path / "r.yaml"
    cases = {
        TINY.replace("score_ci: 0.02949, ", ""): "r.yaml: rows[1].score_ci: expected a number >= 0 (missing)",
        TINY.replace("score: 0.6691", "score: high"): "r.yaml: rows[0].score: expected a number (got 'high')",
        TINY.replace("defects: 8 of 12", "defects: 13 of 12"): "r.yaml: rows[0].defects: expected 'k of m' (k <= m) "
                                                              "or null (got '13 of 12')",
        TINY.replace("seeds: 7-9, defects: 8", "seeds: 7-10, defects: 8"): "r.yaml: rows[0].seeds: 7-10 holds 4 "
                                                                          "seeds, expected n = 3",
        TINY.replace("defects_n: 4\n", ""): "r.yaml: defects_n: expected a positive integer (missing)",
        TINY.replace("rows:", "rows: ["): "r.yaml: not valid YAML (line 5): ",  # then PyYAML's problem
    }
    for text, message in cases.items():
        path.write_text(text, encoding="utf-8")
        with pytest.raises(InputError) as err:
            load_results(path, "r.yaml")
        assert str(err.value) == message or (message.endswith(": ") and str(err.value).startswith(message))
        assert "\n" not in str(err.value)


def test_the_script_checks_writes_and_says_one_line(tmp_path, monkeypatch, capsys):
    """scripts/readme_table.py on a copy of the README and the results file: --check exits 1 on a table that
    differs (one line), writing makes it equal, a malformed results file is one error line and status 2."""
    import readme_table

    (tmp_path / "results").mkdir()
    good = (REPO / "results" / "readme.yaml").read_text(encoding="utf-8")
    (tmp_path / "results" / "readme.yaml").write_text(good.replace("score: 0.669", "score: 0.5", 1), encoding="utf-8")
    (tmp_path / "README.md").write_text((REPO / "README.md").read_text(encoding="utf-8"), encoding="utf-8")
    monkeypatch.setattr(readme_table, "REPO", tmp_path)
    monkeypatch.setattr(readme_table, "README", tmp_path / "README.md")
    assert readme_table.main(["--check"]) == 1
    assert capsys.readouterr().err == ("README.md: the results table differs from results/readme.yaml: "
                                       "run make readme-table\n")
    assert readme_table.main([]) == 0 and readme_table.main(["--check"]) == 0
    assert "| `nilsson` | 0.500 ± 0.077 |" in (tmp_path / "README.md").read_text(encoding="utf-8")
    capsys.readouterr()
    (tmp_path / "results" / "readme.yaml").write_text(good.replace("    score_ci: 0.081\n", "", 1), encoding="utf-8")
    assert readme_table.main(["--check"]) == 2
    assert capsys.readouterr() == ("", "error: results/readme.yaml: rows[1].score_ci: expected a number >= 0 (missing)\n")
