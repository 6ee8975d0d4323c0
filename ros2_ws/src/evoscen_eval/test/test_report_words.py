"""What a person reads of a run's scores (docs/evaluation.md, "Symbols"): D, the comparative score, first with
its terms, the method's I labelled as such; a lane change under way at the end said; every number of
report.md's tables with its unit, or said to be a count or a ratio.

Hand-built runs (``make_run``: SUT vehicle 0 at s = 1000 m, 30 m/s, the BVs 500 m ahead, out of its view;
dt 0.1 s): every number below follows from the definitions by hand.
"""

from __future__ import annotations

import math
import re

import pytest
from evoscen_contract import topics as T
from evoscen_eval.scoring.metrics import evaluate
from evoscen_eval.scoring.report_text import markdown, score_lines
from evoscen_eval.scoring.run_fixtures import make_run, rear_run
from evoscen_sim.config.scenario_config import EvaluationConfig

EV = EvaluationConfig()


def two_changes(states: int = 40, under_way: bool = True):
    """The SUT changes lanes in states 5..9 (completed at step 10 in 0.5 s) and, with ``under_way``, again from
    state 30 to the end (no completion: the run ends first)."""
    events = [{"name": T.EVENT_LANE_CHANGE, "step": 10, "time_s": 1.0, "ids": [0], "duration_s": 0.5,
               "kind": "completed"}]
    run = make_run(states, 2, events)
    run.columns["lane_change"][5:10, 0] = 1
    if under_way:
        run.columns["lane_change"][30:, 0] = 1
    return run


# By hand for two_changes(40): nothing in view, so v_ref = v_max = 33.33 m/s and P = 40·30 / (40·33.33);
# no exposure: S = 1; L = e^(−0.5/3); X = I_i = (1/3)·(2 − 0 − 0 + e^0) = 1 (no BV in view of either change).
P = 30.0 / 33.33
L = math.exp(-0.5 / 3.0)
D = P * (0.6 * 1.0 + 0.2 * L + 0.2 * 1.0)
# I: I_s = 1, I_e = 0.5·(Q + L) with Q = 0 (h̄ = 0), I_i = 1
I_METHOD = 0.6 + 0.2 * 0.5 * L + 0.2


def test_a_lane_change_under_way_at_the_end_is_said():
    rep = evaluate(two_changes(), EV)
    assert (rep["efficiency"]["lane_changes"], rep["interaction"]["sut_lane_changes"]) == (1, 2)
    md = markdown(rep, [])
    assert ("| SUT lane changes completed | 1 | count | those T̄_l averages over (0 aborted; 1 still under way "
            "at the end, not in T̄_l) |") in md
    assert ("| SUT lane changes | 2 | count | lane changes the SUT started; the averages run over them "
            "(1 still under way at the end) |") in md
    done = markdown(evaluate(two_changes(under_way=False), EV), [])
    assert "under way" not in done and "| SUT lane changes | 1 | count |" in done


def test_d_comes_first_with_its_terms_and_the_methods_i_is_labelled():
    rep = evaluate(two_changes(), EV)
    assert rep["comparative"]["score"] == pytest.approx(D) and rep["intelligence"]["score"] == pytest.approx(I_METHOD)
    md = markdown(rep, [])
    d_at, i_at = md.index("## D, the comparative score\n"), md.index("## The method's intelligence I (for reproducing "
                                                                       "the paper)\n")
    assert d_at < i_at < md.index("## Safety I_s")
    d_part = md[d_at:i_at]
    assert (f"D = P·(0.6·S + 0.2·L + 0.2·X) = {P:.4g} × (0.6 × 1 + 0.2 × {L:.4g} + 0.2 × 1) = **{D:.4g}**"
            in d_part)
    assert f"| progress P | {P:.4g} | min(1, d_SUT/d_ref) = min(1, 120 m / 133.3 m) |" in d_part
    assert "| safety S | 1 | 1/(1 + r/r0), r = (E + κ·C)/km = (0 + 10·0) / 0.12 km = 0 per km" in d_part
    assert f"| lane-change time L | {L:.4g} | e^(−T̄_l/3 s), T̄_l = 0.5 s |" in d_part
    assert "| interaction X | 1 | I_i (below) |" in d_part
    assert f"| **I** | | | **{I_METHOD:.4g}** |" in md[i_at:]
    # the lines a run prints: D first, then I, named as such; then the scenario's K and the SUT's counts
    lines = score_lines(rep)
    assert lines[0] == (f"D, the comparative score: {D:.4f} = P·(0.6·S + 0.2·L + 0.2·X): progress P {P:.4f}, safety "
                        f"per SUT-km S 1.0000, lane-change time L {L:.4f}, interaction X 1.0000")
    assert lines[1] == (f"the method's intelligence I (for reproducing the paper): {I_METHOD:.4f} = 0.6 × safety I_s "
                        f"1.0000 + 0.2 × efficiency I_e {0.5 * L:.4f} + 0.2 × interaction I_i 1.0000")
    assert lines[2] == "complexity K (the scenario's): –  SUT collisions: 0  SUT exposures: 0"


def test_report_json_puts_d_first_by_its_name():
    rep = evaluate(two_changes(), EV)
    assert list(rep)[:4] == ["run", "warnings", "comparative", "intelligence"]
    assert rep["comparative"]["name"] == "D, the comparative score"
    assert rep["comparative"]["formula"] == "D = P·(0.6·S + 0.2·L + 0.2·X)"


def _tables(md: str) -> list[tuple[list[str], list[list[str]]]]:
    """Every markdown table of ``md``: its header's cells and its rows' cells."""
    split = lambda line: [c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]  # noqa: E731
    out, lines = [], md.splitlines()
    for n, line in enumerate(lines):
        if line.startswith("|") and n + 1 < len(lines) and re.fullmatch(r"\|(---\|)+", lines[n + 1]):
            body = []
            for row in lines[n + 2:]:
                if not row.startswith("|"):
                    break
                body.append(split(row))
            out.append((split(line), body))
    return out


def _numeric(cell: str) -> bool:
    """A number, maybe bold, with a note (``30 (open)``) or more numbers (``0 / 0``, ``5, 3``); not a formula."""
    return re.fullmatch(r"\**-?[\d.]+(e[-+]?\d+)?\**( \(.*\)|( / |, )-?[\d.]+.*)?", cell) is not None


def test_every_number_of_a_table_names_its_unit_or_says_count_or_ratio():
    """rear_run over 400 states: an exposure, the conflicts, surrogate safety, complexity windows and traffic
    windows — every table report.md has. A column of numbers names its unit in its header, ``(s)``, or says
    ``count``, ``ratio`` or ``no.``; in a table with a ``unit`` column each row with a number names its unit."""
    md = markdown(evaluate(rear_run(400), EV), [])
    tables = _tables(md)
    assert len(tables) >= 9  # D, I, safety, conflicts, exposures, surrogate, efficiency, interaction, complexity, ...
    for header, body in tables:
        if "unit" in header:
            u = header.index("unit")
            for row in body:
                if any(_numeric(c) for j, c in enumerate(row) if j not in (0, u)):
                    assert row[u] not in ("", "–"), (header, row)
            continue
        for j, name in enumerate(header):
            if any(_numeric(row[j]) for row in body):
                assert re.search(r"\(.+\)|count|ratio", name), (header, name)


def test_no_heading_or_table_names_d_intelligence():
    md = markdown(evaluate(two_changes(), EV), [])
    for header, body in _tables(md):
        for cells in (header, *body):
            text = " ".join(cells)
            assert not ("intelligence" in text.lower() and re.search(r"\bD\b|comparative", text)), text
    for line in md.splitlines():
        if line.startswith("#"):
            assert not ("intelligence" in line.lower() and re.search(r"\bD\b|comparative", line)), line


def test_a_tail_of_one_state_is_said_in_the_singular():
    """301 states: one 30-s window of 300 states, the last one state left out of the windows."""
    md = markdown(evaluate(make_run(301, 2), EV), [])
    assert "the last state (under half a window) is in the mean, not in a window" in md
    assert "the last 1 states" not in md
    md = markdown(evaluate(make_run(302, 2), EV), [])
    assert "the last 2 states (under half a window) are in the mean, not in a window" in md
