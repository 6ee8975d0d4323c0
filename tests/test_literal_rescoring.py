"""A bag evoscen 0.5.1 recorded, scored again now, gives the report 0.5.1 wrote: every value of it
to the last digit (docs/evaluation.md §10: the method's intelligence is in every report whatever
``evaluation.score_form`` selects for the experiments; the comparative score is added beside it).

Fixture: tests/data/v0.5.1_mobil_seed1 (its README says how it was recorded).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data" / "v0.5.1_mobil_seed1"


def _leaves(d, path=""):
    """Every leaf of a JSON document, keyed by its path."""
    if isinstance(d, dict):
        return {k: v for key, val in d.items() for k, v in _leaves(val, f"{path}/{key}").items()}
    if isinstance(d, list):
        return {k: v for i, val in enumerate(d) for k, v in _leaves(val, f"{path}[{i}]").items()}
    return {path: d}


@pytest.mark.parametrize("form", ["method", "comparative"])
def test_a_0_5_1_bag_scored_again_gives_the_0_5_1_report(tmp_path, form):
    from evoscen_eval.scoring.report import write_stream_report
    from evoscen_eval.scoring.rundata import score_bag
    from evoscen_sim.config.scenario_config import load_scenario_config

    (tmp_path / "form.yaml").write_text(f"evaluation:\n  score_form: {form}\n")
    override = load_scenario_config(tmp_path / "form.yaml").evaluation
    bag = DATA / "bag"
    run = score_bag(bag, override)
    assert run.warnings == []
    write_stream_report(run.stream, run.info, run.warnings, tmp_path / "out", plots=False, source=str(bag),
                        lane_segments=run.lane_segments)
    old = _leaves(json.loads((DATA / "report.json").read_text()))
    new = _leaves(json.loads((tmp_path / "out" / "report.json").read_text()))
    # the 0.5.1 report has the method's terms defined: safety with one exposure, a lane change
    assert old["/safety/exposures"] == 1 and old["/interaction/defined"] is True and old["/interaction/sut_lane_changes"] == 3
    assert old["/intelligence/score"] == pytest.approx(0.6223, abs=5e-5)  # what the 0.5.1 run printed
    changed = {k: (v, new.get(k, "<missing>")) for k, v in old.items() if new.get(k, "<missing>") != v}
    assert changed == {}
    # what is new is beside it: the comparative score, the run's source, the settings, and which rules
    # made each exposure (the same exposure, explained)
    assert {_where(k) for k in new if k not in old} <= {"/comparative", "/run", "/settings",
                                                         "/safety/exposure_list[]/rules",
                                                         "/safety/exposure_list[]/rule_states"}


def _where(key: str) -> str:
    """A leaf's section: its first part, or under the exposure list the exposure's field (indices dropped)."""
    parts = re.sub(r"\[\d+\]", "[]", key).split("/")
    return "/".join(parts[:4]).removesuffix("[]") if parts[1] == "safety" else "/" + parts[1]
