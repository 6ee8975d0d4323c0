"""``evaluation.count_normalisation`` (docs/evaluation.md §1.1): the safety score's counts C and E
scaled to the method's run length, C·N_ref/N and E·N_ref/N (N = steps scored = states − 1,
N_ref = ``count_reference_steps`` [3000]), or taken as counted (``literal``).

The runs are written down state by state: the SUT at 30 m/s, a BV 8 m ahead (bumper to bumper)
at 25 m/s in the next lane cuts into the SUT's path twice (states 10..19 and 30..39: TTC 1.6 s,
two exposures), and one collision event with the SUT at state 50: C = 1, E = 2 whatever the
run's length."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from evoscen_contract import topics as T
from evoscen_eval.scoring.metrics import evaluate, safety_score, scored_counts
from evoscen_eval.scoring.report import markdown, report_of
from evoscen_eval.scoring.run_fixtures import make_run
from evoscen_eval.scoring.rundata import RECORDED_BEFORE_KEYS, evaluation_settings_of
from evoscen_sim.config.scenario_config import EvaluationConfig, ScenarioConfig, config_to_dict, evaluation_from_dict
from evoscen_sim.errors import InputError

EV = EvaluationConfig()
LITERAL = replace(EV, count_normalisation="literal")


def counted_run(steps: int, cut_ins: tuple[int, ...] = (10, 30), collisions: tuple[int, ...] = (50,)):
    """A run of ``steps`` steps (``steps + 1`` states) with one exposure per cut-in start and the collisions."""
    events = [{"name": T.EVENT_COLLISION, "step": k, "time_s": k * 0.1, "ids": [0, 1]} for k in collisions]
    run = make_run(steps + 1, 2, events)
    c = run.columns
    c["s"][:, 1] = 1012.8  # gap 12.8 - 4.8 = 8 m
    c["speed"][:, 1] = 25.0  # closing at 5 m/s: TTC 1.6 s < 2 s while in the path
    c["d"][:, 1] = 3.5  # the next lane: not in the path
    for k in cut_ins:
        c["d"][k:k + 10, 1] = 0.5  # in the path (bodies overlap laterally) for 10 states
    return run


def test_the_defaults():
    assert (EV.count_normalisation, EV.count_reference_steps) == ("method_length", 3000)


def test_half_the_method_length_doubles_the_counts_by_hand():
    """C = 1, E = 2 over 1,500 steps enter I_s as 2 and 4."""
    s = evaluate(counted_run(1500), EV)["safety"]
    assert (s["collisions"], s["exposures"], s["steps"]) == (1, 2, 1500)  # the raw counts and the run length
    assert (s["count_normalisation"], s["count_reference_steps"], s["count_factor"]) == ("method_length", 3000, 2.0)
    assert (s["collisions_used"], s["exposures_used"]) == (2.0, 4.0)
    assert s["score"] == pytest.approx(0.7 * (1 - 2 / 10) + 0.3 * math.exp(-4), rel=1e-12)
    assert s["score"] == pytest.approx(0.5654947, abs=1e-7)  # 0.56 + 0.3 · 0.0183156


def test_twice_the_method_length_halves_the_counts_by_hand():
    s = evaluate(counted_run(6000), EV)["safety"]
    assert (s["collisions"], s["exposures"], s["steps"], s["count_factor"]) == (1, 2, 6000, 0.5)
    assert (s["collisions_used"], s["exposures_used"]) == (0.5, 1.0)
    assert s["score"] == pytest.approx(0.7 * (1 - 0.5 / 10) + 0.3 * math.exp(-1), rel=1e-12)
    assert s["score"] == pytest.approx(0.7753638, abs=1e-7)


def test_a_run_of_the_method_length_scores_exactly_the_literal_counts():
    """3,000 steps (3,001 states): the factor is 1 and every number is the literal one, to the bit."""
    run = counted_run(3000)
    scaled, literal = evaluate(run, EV), evaluate(run, LITERAL)
    s = scaled["safety"]
    assert (s["steps"], s["count_factor"], s["collisions_used"], s["exposures_used"]) == (3000, 1.0, 1, 2)
    assert s["score"] == literal["safety"]["score"] == safety_score(1, 2, 10)
    assert s["score"] == 0.7 * (1 - 1 / 10) + 0.3 * math.exp(-2)
    assert scaled["intelligence"] == literal["intelligence"]
    for key in ("count_normalisation", "count_factor", "collisions_used", "exposures_used"):
        s.pop(key), literal["safety"].pop(key)
    assert s == literal["safety"]


def test_literal_is_selectable():
    s = evaluate(counted_run(1500), LITERAL)["safety"]
    assert (s["count_normalisation"], s["steps"], s["count_factor"]) == ("literal", 1500, 1.0)
    assert (s["collisions_used"], s["exposures_used"]) == (1, 2)
    assert s["score"] == pytest.approx(0.7 * (1 - 1 / 10) + 0.3 * math.exp(-2), rel=1e-12)
    assert s["score"] == pytest.approx(0.6706006, abs=1e-7)


def test_the_same_rate_scores_the_same_whatever_the_length():
    """1 collision and 2 exposures in 1,500 steps, 2 and 4 in 3,000: the same counts enter I_s."""
    short = evaluate(counted_run(1500), EV)["safety"]
    long = evaluate(counted_run(3000, cut_ins=(10, 30, 1510, 1530), collisions=(50, 1550)), EV)["safety"]
    assert (long["collisions"], long["exposures"]) == (2, 4)
    assert (short["collisions_used"], short["exposures_used"]) == (long["collisions_used"], long["exposures_used"])
    assert short["score"] == long["score"]
    # counted per run, the longer run scores lower
    lit_short = evaluate(counted_run(1500), LITERAL)["safety"]["score"]
    lit_long = evaluate(counted_run(3000, cut_ins=(10, 30, 1510, 1530), collisions=(50, 1550)), LITERAL)
    assert lit_long["safety"]["score"] < lit_short


def test_the_reference_length_is_a_key():
    run = counted_run(1500)
    s = evaluate(run, replace(EV, count_reference_steps=1500))["safety"]
    assert s["count_factor"] == 1.0 and s["score"] == evaluate(run, LITERAL)["safety"]["score"]
    s = evaluate(run, replace(EV, count_reference_steps=300))["safety"]  # 1 and 2 per 1,500 steps: 0.2, 0.4 per 300
    assert (s["collisions_used"], s["exposures_used"]) == pytest.approx((0.2, 0.4))
    assert s["score"] == pytest.approx(0.7 * (1 - 0.2 / 10) + 0.3 * math.exp(-0.4), rel=1e-12)


def test_scored_counts_arithmetic():
    assert scored_counts(1, 2, 1500, "method_length", 3000) == (2.0, 4.0, 2.0, None)
    assert scored_counts(3, 7, 3000, "method_length", 3000) == (3.0, 7.0, 1.0, None)
    assert scored_counts(3, 7, 1234, "literal", 3000) == (3, 7, 1.0, None)
    c, e, factor, warning = scored_counts(0, 1, 0, "method_length", 3000)  # a single state: no length to scale by
    assert (c, e, factor) == (0, 1, 1.0) and "0 steps" in warning
    with pytest.raises(ValueError, match="count normalisation 'per_run'"):
        scored_counts(0, 0, 10, "per_run", 3000)


def test_a_single_state_run_scores_its_counts_as_counted_with_a_warning():
    run = make_run(1, 2)
    run.columns["s"][:, 1] = 1012.8
    run.columns["speed"][:, 1] = 25.0  # in the path (d = 0 for both): one exposure in state 0
    rep = evaluate(run, EV)
    s = rep["safety"]
    assert (s["steps"], s["exposures"], s["exposures_used"], s["count_factor"]) == (0, 1, 1, 1.0)
    assert s["score"] == pytest.approx(0.7 + 0.3 * math.exp(-1))
    assert any("0 steps" in w and "count_normalisation" in w for w in rep["warnings"])


def test_the_report_shows_the_raw_counts_the_length_and_the_counts_used():
    md = markdown(evaluate(counted_run(1500), EV), [])
    assert "C' = C·N_ref/N, E' = E·N_ref/N" in md
    for row in ("| C | 1 | count |", "| E | 2 | count |", "| count normalisation | method_length | – |",
                "| N | 1500 | steps |", "| N_ref | 3000 | steps |", "| C' | 2 | count | C as it enters I_s (C·2) |",
                "| E' | 4 | count | E as it enters I_s (E·2) |"):
        assert row in md, row
    lit = markdown(evaluate(counted_run(1500), LITERAL), [])
    assert "I_s = 0.7·(1 − min(C, C_max)/C_max) + 0.3·e^(−E)\n" in lit
    assert "| N_ref | 3000 | steps | reference length, unused |" in lit and "| C' | 1 | count | C as it enters I_s |" in lit


def test_keys_are_validated():
    message = "'evaluation.count_normalisation' = 'per_step'"
    with pytest.raises(InputError, match=message) as info:
        evaluation_from_dict({"count_normalisation": "per_step"}, "file")
    assert "method_length, literal" in str(info.value)
    with pytest.raises(InputError, match=r"'evaluation.count_reference_steps' = 0"):
        evaluation_from_dict({"count_reference_steps": 0}, "file")
    ev = evaluation_from_dict({"count_normalisation": "literal", "count_reference_steps": 1500}, "file")
    assert (ev.count_normalisation, ev.count_reference_steps) == ("literal", 1500)


def test_a_bag_recorded_before_the_key_scores_the_counts_as_counted():
    """A bag records its run's whole resolved evaluation section: one without count_normalisation
    was recorded before the key existed and is scored as it was then (literal)."""
    assert RECORDED_BEFORE_KEYS["count_normalisation"] == "literal"
    now = config_to_dict(ScenarioConfig())
    older = {**now, "evaluation": {k: v for k, v in now["evaluation"].items()
                                   if k not in ("count_normalisation", "count_reference_steps")}}
    assert evaluation_settings_of(now) == EV
    assert evaluation_settings_of(older) == LITERAL
    run = counted_run(1500)
    run.scenario = older
    s = report_of(run)["safety"]
    assert (s["count_normalisation"], s["collisions_used"], s["exposures_used"]) == ("literal", 1, 2)
    assert s["score"] == pytest.approx(0.7 * 0.9 + 0.3 * math.exp(-2), rel=1e-12)
    run.scenario = now
    assert report_of(run)["safety"]["score"] == pytest.approx(0.7 * 0.8 + 0.3 * math.exp(-4), rel=1e-12)
