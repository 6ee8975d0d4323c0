"""The scores (docs/method.md §5.1-5.2) against hand-computed numbers, on hand-built runs.

Each run is written down state by state (``make_run``): positions, speeds, accelerations and
lane-change flags are set where the test says, so every expected number below follows from
the formulas by hand.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from evoscen_contract import topics as T
from evoscen_eval.scoring.metrics import (
    complexity_score,
    efficiency_score,
    evaluate,
    interaction_score,
    max_in_view,
    safety_score,
)
from evoscen_eval.scoring.run_fixtures import make_run
from evoscen_sim.config.scenario_config import EvaluationConfig

EV = EvaluationConfig()
OWN = EvaluationConfig(hard_braking="own")
"""The method's braking criterion (every SUT deceleration beyond 6 m/s²): the hand-built hard brakings
below have nobody around, which the default (``conflict``) does not count (test_detection_scenarios.py)."""
#: the method's arithmetic taken literally for undefined terms (T_l = 0 s, I_i = 1 without a lane change)
EV_LIT = EvaluationConfig(undefined_terms="literal")


# ---------------------------------------------------------------------- formulas


def test_safety_formula_by_hand():
    assert safety_score(0, 0, 10) == pytest.approx(1.0)
    assert safety_score(3, 2, 10) == pytest.approx(0.7 * 0.7 + 0.3 * math.exp(-2))  # 0.5306006
    assert safety_score(3, 2, 10) == pytest.approx(0.5306006, abs=1e-7)
    # C above C_max: the collision term is used up (0), only the exposure term is left
    assert safety_score(15, 0, 10) == pytest.approx(0.3)
    assert safety_score(10, 1, 10) == pytest.approx(0.3 * math.exp(-1))


def test_efficiency_formula_by_hand():
    # literal: sqrt(4) * 30 / (85 * 33.33) = 60 / 2833.05; T_l = 3 s -> e^-1
    score, t1, t2 = efficiency_score(4.0, 85, 30.0, 33.33, 3.0, 3.0, "literal")
    assert t1 == pytest.approx(60.0 / 2833.05)
    assert t2 == pytest.approx(math.exp(-1.0))
    assert score == pytest.approx(0.5 * (60.0 / 2833.05 + 0.36787944), abs=1e-8)
    score, t1, _ = efficiency_score(4.0, 85, 30.0, 33.33, 3.0, 3.0, "normalised")
    assert t1 == pytest.approx(math.sqrt(4.0 / 85.0) * 30.0 / 33.33)
    # zero vehicles in view: the density-speed term is 0
    assert efficiency_score(0.0, 85, 30.0, 33.33, 0.0, 3.0)[0] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="density"):
        efficiency_score(1.0, 85, 30.0, 33.33, 0.0, 3.0, "other")


def test_interaction_formula_by_hand():
    # (2 - 1/5 - 0.6/3 + e^-sqrt(4)) / 3
    assert interaction_score(1.0, 0.6, 4.0, 5.0, 3.0) == pytest.approx((1.6 + math.exp(-2.0)) / 3.0)
    assert interaction_score(1.0, 0.6, 4.0, 5.0, 3.0) == pytest.approx(0.5784451, abs=1e-7)
    # clipped at the normalisers, L = 0 gives e^0 = 1
    assert interaction_score(10.0, 5.0, 0.0, 5.0, 3.0) == pytest.approx(1.0 / 3.0)
    # nothing disturbed
    assert interaction_score(0.0, 0.0, 0.0, 5.0, 3.0) == pytest.approx(1.0)


def test_complexity_formula_by_hand():
    # E = k1, LC = k2, AD = k3: 0.4 (1 - e^-1) + 0.3 (2 - 2 e^-1) = 0.6321206
    assert complexity_score(25.0, 8.0, 1400.0, 25.0, 8.0, 1400.0) == pytest.approx(0.6321206, abs=1e-7)
    assert complexity_score(0.0, 0.0, 0.0, 25.0, 8.0, 1400.0) == pytest.approx(0.0)
    assert complexity_score(1e9, 1e9, 1e9, 25.0, 8.0, 1400.0) == pytest.approx(1.0)


def test_view_capacity_H():
    assert max_in_view(EV) == 5 * 17  # floor(120 / 6.8) = 17 per lane


@pytest.mark.parametrize("split", [False, True])
def test_lane_change_starts_and_intervals(split, monkeypatch):
    """A change starts where the SUT's column becomes non-zero or switches sign and lasts while
    it keeps its value; a change open at the end counts. With blocks of 3 states (``split``)
    every change and the complexity window's LC count straddle block boundaries: same result."""
    if split:
        monkeypatch.setattr("evoscen_eval.scoring.streaming.BLOCK_STATES", 3)
    lc = np.array([0, 1, 1, 0, -1, -1, 1, 0, 0, 1])
    run = make_run(10, 2)
    run.columns["lane_change"][:, 0] = lc
    ev = EvaluationConfig(window_steps=10)
    report = evaluate(run, ev)
    changes = [(c["start_state"], c["end_state"]) for c in report["interaction"]["changes"]]
    assert changes == [(1, 3), (4, 6), (6, 7), (9, 10)]
    assert [(p["start_state"], p["end_state"]) for p in report["safety"]["conflicts"]["lane_change_pet"]] == changes
    assert report["complexity"]["per_window"]["lane_changes"] == [4]  # starts at states 1, 4, 6, 9


# ---------------------------------------------------------------------- runs


def test_cut_in_is_one_exposure_and_ttc_uses_the_vehicle_in_the_path():
    run = make_run(40, 2)
    c = run.columns
    c["s"][:, 1] = 1012.8  # bumper-to-bumper gap 12.8 - 4.8 = 8 m
    c["speed"][:, 1] = 25.0  # closing at 5 m/s: TTC 1.6 s once in the path
    c["d"][:, 1] = 3.5  # the next lane: not in the path
    c["d"][10:20, 1] = 0.5  # cut in (bodies overlap laterally: 0.5 < 1.9) for states 10..19
    rep = evaluate(run, EV_LIT)
    s = rep["safety"]
    assert s["exposures"] == 1 and s["dangerous_states"] == 10
    ex = s["exposure_list"][0]
    assert (ex["start_state"], ex["end_state"], ex["open_at_end"]) == (10, 20, False)
    assert ex["min_ttc_s"] == pytest.approx(8.0 / 5.0)
    # 39 steps: E = 1 enters I_s as 3000/39 (count_normalisation: method_length); as counted under literal
    assert s["steps"] == 39 and s["exposures_used"] == pytest.approx(3000 / 39)
    assert s["score"] == pytest.approx(0.7 + 0.3 * math.exp(-3000 / 39))
    lit = evaluate(run, replace(EV_LIT, count_normalisation="literal"))["safety"]
    assert lit["score"] == pytest.approx(0.7 + 0.3 * math.exp(-1))
    # the BV 12.8 m ahead is in view in every state: h = 1; no lane change: T_l = 0 -> e^0 = 1
    e = rep["efficiency"]
    assert e["mean_vehicles_in_view"] == 1.0 and e["max_vehicles_in_view"] == 85
    assert e["mean_lane_change_time_s"] == 0.0 and e["lane_change_time_defined"] is False
    assert e["score"] == pytest.approx(0.5 * (1.0 * 30.0 / (85 * 33.33) + 1.0))
    # no SUT lane change: nothing disturbed, I_i = 1
    assert rep["interaction"]["sut_lane_changes"] == 0 and rep["interaction"]["score"] == pytest.approx(1.0)
    w = rep["intelligence"]["weighted"]
    assert w["safety"] == pytest.approx(0.6 * s["score"])
    assert rep["intelligence"]["score"] == pytest.approx(0.6 * s["score"] + 0.2 * e["score"] + 0.2 * 1.0)


def test_opening_gap_and_vehicles_behind_are_not_dangerous():
    run = make_run(20, 3)
    c = run.columns
    c["s"][:, 1], c["speed"][:, 1] = 1006.0, 35.0  # 1.2 m gap but pulling away: TTC infinite
    c["s"][:, 2], c["speed"][:, 2] = 994.0, 40.0  # close behind and faster: not ahead
    rep = evaluate(run, EV)
    assert rep["safety"]["exposures"] == 0 and rep["safety"]["min_ttc_s"] is None


def test_hard_brake_is_one_exposure():
    run = make_run(40, 2)
    run.columns["accel"][12:15, 0] = -7.0
    run.columns["accel"][15, 0] = -5.9  # above -6: not dangerous
    assert evaluate(run, EV)["safety"]["exposures"] == 0  # conflict: nothing ahead, nobody behind
    rep = evaluate(run, OWN)
    assert rep["safety"]["exposures"] == 1
    assert rep["safety"]["exposure_list"][0]["states"] == 3
    assert rep["safety"]["min_accel_mps2"] == -7.0


def test_exposure_spanning_the_end_of_the_run_counts_once():
    run = make_run(30, 2)
    run.columns["accel"][27:, 0] = -6.5
    s = evaluate(run, OWN)["safety"]
    assert s["exposures"] == 1 and s["exposures_open_at_end"] == 1
    assert s["exposure_list"][0]["end_state"] == 30


def test_collisions_only_with_the_sut_count_and_above_the_cap():
    sut_hits = [{"name": T.EVENT_COLLISION, "step": k, "time_s": k * 0.1, "ids": [0, 1]} for k in range(12)]
    other = [{"name": T.EVENT_COLLISION, "step": 3, "time_s": 0.3, "ids": [1, 2]}]
    run = make_run(20, 3, events=sut_hits + other)
    s = evaluate(run, EV)["safety"]
    assert s["collisions"] == 12 and s["collisions_all"] == 13
    assert s["score"] == pytest.approx(0.3)  # C > C_max: 0.7 * 0 + 0.3 * e^0


def test_zero_vehicles_in_view():
    run = make_run(20, 3)  # BVs 500 m and 550 m ahead
    e = evaluate(run, EV_LIT)["efficiency"]
    assert e["mean_vehicles_in_view"] == 0.0 and e["density_speed_term"] == 0.0
    assert e["score"] == pytest.approx(0.5)


def test_interaction_during_a_sut_lane_change_by_hand():
    events = [{"name": T.EVENT_LANE_CHANGE, "step": 15, "time_s": 1.5, "ids": [0], "duration_s": 1.0,
               "kind": "completed"}]
    run = make_run(30, 4, events=events)
    c = run.columns
    c["lane_change"][5:15, 0] = 1  # the SUT changes lanes over states 5..14: k0 = 5
    c["s"][:, 1] = 1030.0  # BV 1 in view: speed 25 -> 26 and accel 0 -> 0.5 after k0, one lane change
    c["speed"][:, 1] = 25.0
    c["speed"][6:, 1] = 26.0
    c["accel"][6:, 1] = 0.5
    c["lane_change"][8:13, 1] = -1
    c["s"][:, 2] = 1300.0  # BV 2 out of view: its lane change must not count
    c["lane_change"][7:12, 2] = 1
    c["s"][:, 3] = 1050.0  # BV 3 in view, steady
    i = evaluate(run, EV)["interaction"]
    assert i["sut_lane_changes"] == 1
    # samples: 10 states x BVs 1 and 3 = 20; BV 1 deviates by 1 m/s in 9 of them
    assert i["speed_fluctuation_mps"] == pytest.approx(9.0 / 20.0)
    assert i["accel_fluctuation_mps2"] == pytest.approx(4.5 / 20.0)
    assert i["bv_lane_changes"] == pytest.approx(0.5)  # (1 + 0) / 2 BVs in view
    assert i["score"] == pytest.approx((2.0 - 0.45 / 5.0 - 0.225 / 3.0 + math.exp(-math.sqrt(0.5))) / 3.0)
    assert i["score"] == pytest.approx(0.7760229, abs=1e-7)
    e = evaluate(run, EV)["efficiency"]
    assert e["lane_changes"] == 1 and e["mean_lane_change_time_s"] == 1.0
    assert e["lane_change_term"] == pytest.approx(math.exp(-1.0 / 3.0))


def test_sut_lane_change_with_nobody_in_view():
    run = make_run(20, 2)
    run.columns["lane_change"][3:8, 0] = 1
    i = evaluate(run, EV)["interaction"]
    assert i["sut_lane_changes"] == 1 and i["changes"][0]["bvs_in_view"] == 0
    assert i["speed_fluctuation_mps"] == 0.0 and i["bv_lane_changes"] == 0.0 and i["score"] == pytest.approx(1.0)


def test_complexity_windows_by_hand():
    run = make_run(250, 3)  # 2 whole windows of 100 states (0..199); states 200..249 are left out
    c = run.columns
    c["lane_change"][10:20, 1] = 1  # starts at 10 and 50 (window 0), 150 (window 1), 220 (left out)
    c["lane_change"][50:60, 1] = -1
    c["lane_change"][150:160, 2] = 1
    c["lane_change"][220:230, 2] = 1
    c["accel"][0:100, 1] = 0.5  # 100 active vehicle-states in window 0
    c["accel"][0:100, 2] = 0.1  # not above the 0.1 threshold
    c["accel"][120:122, 0] = -7.0  # an exposure starting in window 1 (2 more active states)
    from dataclasses import replace

    cx = evaluate(run, replace(OWN, accel_activity_form="literal"))["complexity"]  # per-step accelerations
    assert cx["windows"] == 2
    assert cx["per_window"] == {"lane_changes": [2, 1], "accel_decel": [100, 2], "exposures": [0, 1]}
    assert (cx["lane_changes"], cx["accel_decel"], cx["exposures"]) == (1.5, 51.0, 0.5)
    expected = 0.4 * (1 - math.exp(-0.5 / 25)) + 0.3 * (2 - math.exp(-1.5 / 8) - math.exp(-51 / 1400))
    assert cx["score"] == pytest.approx(expected)


def test_run_shorter_than_a_window_has_no_complexity():
    rep = evaluate(make_run(50, 2), EV)
    assert rep["complexity"]["score"] is None and rep["complexity"]["windows"] == 0
    assert any("shorter than one complexity window" in w for w in rep["warnings"])


def test_settings_change_the_scores():
    from dataclasses import replace

    run = make_run(40, 2)
    run.columns["accel"][12:15, 0] = -5.0
    assert evaluate(run, OWN)["safety"]["exposures"] == 0
    assert evaluate(run, replace(OWN, hard_brake_mps2=4.5))["safety"]["exposures"] == 1
    rep = evaluate(run, replace(EV, weight_safety=1.0, weight_efficiency=0.0, weight_interaction=0.0))
    assert rep["intelligence"]["score"] == pytest.approx(rep["safety"]["score"])


def test_markdown_tables_are_well_formed():
    import re

    from evoscen_eval.scoring.report import markdown

    run = make_run(120, 3)
    run.columns["lane_change"][3:8, 0] = 1
    run.columns["accel"][20:23, 0] = -7.0
    text = markdown(evaluate(run, EV), ["ttc.png"])
    cells = None
    for line in text.splitlines():
        if not line.startswith("|"):
            cells = None
            continue
        n = len(re.findall(r"(?<!\\)\|", line))  # unescaped cell separators
        cells = n if cells is None else cells
        assert n == cells, line
    assert "\\|v~\\|" in text and "![ttc](ttc.png)" in text
