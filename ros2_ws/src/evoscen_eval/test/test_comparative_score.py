"""The comparative score D = P·(i_s·S + i_e·L + i_i·X) (docs/evaluation.md §10), by hand on runs
written down state by state (:func:`evoscen_eval.scoring.run_fixtures.make_run`: the SUT at s = 1000 m, lane
2, 30 m/s, dt 0.1 s; its distance is dt·Σ speed over the states, as surrogate safety's SUT-km).

A run of 300 steps has 301 states: at 30 m/s the SUT covers 0.1·30·301 = 903 m = 0.903 km."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from evoscen_contract import topics as T
from evoscen_eval.scoring.metrics import compared_scores, comparative_safety_score, evaluate, progress_score
from evoscen_eval.scoring.run_fixtures import make_run, rear_run
from evoscen_eval.scoring.rundata import evaluation_settings_of
from evoscen_sim.config.scenario_config import EvaluationConfig, ScenarioConfig, evaluation_from_dict
from evoscen_sim.errors import InputError

EV = EvaluationConfig()
KM = 0.903


def exposed_run(exposures: int, collisions: tuple[int, ...] = (), steps: int = 300):
    """``exposures`` cut-ins of a BV 8 m ahead at 25 m/s into the SUT's path (TTC 1.6 s, 10 states
    each, from states 10, 30, 50, ...): one exposure each; a collision event per entry of ``collisions``."""
    events = [{"name": T.EVENT_COLLISION, "step": k, "time_s": k * 0.1, "ids": [0, 1]} for k in collisions]
    run = make_run(steps + 1, 2, events)
    c = run.columns
    c["s"][:, 1] = 1012.8
    c["speed"][:, 1] = 25.0
    c["d"][:, 1] = 3.5
    for i in range(exposures):
        k = 10 + 20 * i
        c["d"][k:k + 10, 1] = 0.5
    return run


def test_the_defaults():
    assert (EV.score_form, EV.no_lane_change_value, EV.safety_rate_scale_per_km, EV.collision_exposures) \
        == ("comparative", 0.5, 1.0, 10.0)


@pytest.mark.parametrize("n", [0, 1, 2, 3])
def test_safety_by_hand(n):
    """S = 1/(1 + (E/km)/1): 1, 0.903/1.903, 0.903/2.903, 0.903/3.903."""
    comp = evaluate(exposed_run(n), EV)["comparative"]
    s = comp["safety"]
    assert (s["exposures"], s["collisions"]) == (n, 0)
    assert s["sut_km"] == pytest.approx(KM, rel=1e-12)
    assert s["score"] == pytest.approx(KM / (KM + n), rel=1e-12)
    assert s["rate_per_km"] == pytest.approx(n / KM, rel=1e-12)


def test_each_further_exposure_costs():
    """0, 1, 2, 3 exposures: strictly decreasing safety and D (no saturation at the first), where the
    method's I_s (counts scaled ×10 to 3,000 steps, e^(−10) ≈ 0) has nothing left after the first."""
    reports = [evaluate(exposed_run(n), EV) for n in range(4)]
    s = [r["comparative"]["safety"]["score"] for r in reports]
    d = [r["comparative"]["score"] for r in reports]
    assert s[0] > s[1] > s[2] > s[3]
    assert d[0] > d[1] > d[2] > d[3]
    assert [round(x, 6) for x in s] == [1.0, 0.474514, 0.311058, 0.231360]
    method = [r["safety"]["score"] for r in reports]
    assert method[1] - method[2] < 1.5e-5  # e^(-10) - e^(-20): the second exposure costs the method nothing


def test_a_collision_counts_as_ten_exposures():
    comp = evaluate(exposed_run(1, collisions=(150,)), EV)["comparative"]
    assert (comp["safety"]["exposures"], comp["safety"]["collisions"]) == (1, 1)
    assert comp["safety"]["score"] == pytest.approx(1.0 / (1.0 + 11.0 / KM), rel=1e-12)
    two = evaluate(exposed_run(1, collisions=(150, 250)), EV)["comparative"]["safety"]["score"]
    assert two == pytest.approx(1.0 / (1.0 + 21.0 / KM), rel=1e-12) and two < comp["safety"]["score"]


def test_safety_function_edges():
    assert comparative_safety_score(0, 0, 0.0, 1.0, 10.0) == (1.0, 0.0)  # nothing counted: safe, even at 0 km
    assert comparative_safety_score(0, 1, 0.0, 1.0, 10.0) == (0.0, math.inf)  # an exposure standing still
    assert comparative_safety_score(1, 2, 2.0, 4.0, 10.0)[0] == pytest.approx(1.0 / (1.0 + (12 / 2) / 4))


def test_a_lane_keeper_gets_the_neutral_value_and_the_weights_stay():
    """No SUT lane change: L = X = 0.5 (no_lane_change_value), the weights as configured, D by hand;
    the method's exclude rule renormalises its weights on the same run."""
    rep = evaluate(exposed_run(0), EV)
    comp = rep["comparative"]
    assert comp["lane_change_time"] == {"score": 0.5, "defined": False, "mean_lane_change_time_s": None,
                                        "lane_change_time_scale_s": 3.0}
    assert comp["interaction"] == {"score": 0.5, "defined": False}
    assert comp["weights"] == {"safety": 0.6, "lane_change_time": 0.2, "interaction": 0.2}
    # BV 1 12.8 m ahead in view at 25 m/s all along, the SUT at 30 m/s: P = min(1, 30/25) = 1
    assert comp["progress"]["score"] == 1.0
    assert comp["score"] == pytest.approx(0.6 * 1.0 + 0.2 * 0.5 + 0.2 * 0.5, rel=1e-12)
    assert sum(comp["weighted"].values()) == pytest.approx(comp["score"], rel=1e-12)
    assert rep["intelligence"]["effective_weights"]["interaction"] == 0.0  # the method's rule renormalises
    other = evaluate(exposed_run(0), replace(EV, no_lane_change_value=0.25))["comparative"]
    assert (other["lane_change_time"]["score"], other["interaction"]["score"]) == (0.25, 0.25)
    assert other["score"] == pytest.approx(0.6 + 0.2 * 0.25 + 0.2 * 0.25, rel=1e-12)


def test_a_lane_change_is_scored_and_the_weights_do_not_move():
    """rear_run: one completed change of 0.5 s: L = e^(−0.5/3), X = the method's I_i of the change."""
    rep = evaluate(rear_run(), EV)
    comp = rep["comparative"]
    assert comp["lane_change_time"]["defined"] and comp["interaction"]["defined"]
    assert comp["lane_change_time"]["score"] == pytest.approx(math.exp(-0.5 / 3.0), rel=1e-12)
    assert comp["interaction"]["score"] == rep["interaction"]["score"]
    assert comp["weights"] == {"safety": 0.6, "lane_change_time": 0.2, "interaction": 0.2}
    p, s = comp["progress"]["score"], comp["safety"]["score"]
    assert comp["score"] == pytest.approx(p * (0.6 * s + 0.2 * math.exp(-0.5 / 3.0) + 0.2 * comp["interaction"]["score"]),
                                          rel=1e-12)


def test_progress_by_hand():
    """The SUT at 18 m/s beside a BV at 30 m/s in view all along: P = 18/30 = 0.6, D = 0.6·(0.6 + 0.1 + 0.1)."""
    run = make_run(301, 2)
    c = run.columns
    c["speed"][:, 0] = 18.0
    c["s"][:, 1], c["d"][:, 1], c["lane"][:, 1] = 1050.0, 3.5, 3
    comp = evaluate(run, EV)["comparative"]
    assert comp["progress"]["score"] == pytest.approx(0.6, rel=1e-12)
    assert comp["progress"]["reference_mean_speed_mps"] == pytest.approx(30.0, rel=1e-12)
    assert comp["progress"]["sut_distance_m"] == pytest.approx(0.1 * 18 * 301, rel=1e-12)
    assert comp["progress"]["reference_distance_m"] == pytest.approx(0.1 * 30 * 301, rel=1e-12)
    assert comp["safety"]["score"] == 1.0
    assert comp["score"] == pytest.approx(0.6 * (0.6 + 0.2 * 0.5 + 0.2 * 0.5), rel=1e-12)
    assert comp["score"] == pytest.approx(0.48, rel=1e-12)


def test_progress_without_traffic_in_view_and_the_cap():
    run = make_run(101, 2)  # the BV 500 m ahead: never in view, the reference is v_max (33.33 m/s)
    comp = evaluate(run, EV)["comparative"]["progress"]
    assert comp["states_without_vehicle_in_view"] == 101
    assert comp["score"] == pytest.approx(30.0 / 33.33, rel=1e-12)
    run.columns["s"][:, 1], run.columns["speed"][:, 1] = 1050.0, 20.0  # a slower BV in view: capped at 1
    assert evaluate(run, EV)["comparative"]["progress"]["score"] == 1.0
    assert progress_score(10.0, 0.0) == 1.0 and progress_score(5.0, 10.0) == 0.5


def test_compared_scores_follow_the_form():
    rep = evaluate(exposed_run(2), EV)
    comp = rep["comparative"]
    assert compared_scores(rep) == {"intelligence": comp["score"], "safety": comp["safety"]["score"],
                                    "efficiency": comp["progress"]["score"], "interaction": 0.5}
    method = evaluate(exposed_run(2), replace(EV, score_form="method"))
    assert method["comparative"]["score"] == comp["score"]  # every report carries both
    assert method["intelligence"] == rep["intelligence"]  # the method's numbers do not depend on the form
    assert compared_scores(method) == {name: method[name]["score"]
                                       for name in ("intelligence", "safety", "efficiency", "interaction")}
    older = {k: v for k, v in method.items() if k != "comparative"}  # a report from before the section
    older["settings"] = {k: v for k, v in method["settings"].items() if k != "score_form"}
    assert compared_scores(older)["intelligence"] == method["intelligence"]["score"]


def test_bad_keys_are_one_line_errors():
    with pytest.raises(InputError, match=r"'evaluation.score_form' = 'best'.*comparative, method"):
        evaluation_from_dict({"score_form": "best"}, "file")
    with pytest.raises(InputError, match=r"'evaluation.no_lane_change_value' = 1.5"):
        evaluation_from_dict({"no_lane_change_value": 1.5}, "file")
    with pytest.raises(InputError, match=r"'evaluation.safety_rate_scale_per_km' = 0"):
        evaluation_from_dict({"safety_rate_scale_per_km": 0}, "file")


def test_the_record_carries_the_keys_only_when_set():
    """A bag's scenario record leaves the comparative score's keys out at their defaults (the bytes of
    a default run do not change) and carries a set one, so the bag is scored again as it ran."""
    import yaml
    from evoscen_record.scenario_record import SCENARIO_KEY, scenario_metadata

    recorded = yaml.safe_load(scenario_metadata(ScenarioConfig())[SCENARIO_KEY])["evaluation"]
    assert not {"score_form", "no_lane_change_value", "safety_rate_scale_per_km", "collision_exposures"} & set(recorded)
    assert evaluation_settings_of({"evaluation": recorded}) == EV
    cfg = replace(ScenarioConfig(), evaluation=replace(EV, score_form="method", no_lane_change_value=0.3))
    recorded = yaml.safe_load(scenario_metadata(cfg)[SCENARIO_KEY])["evaluation"]
    assert (recorded["score_form"], recorded["no_lane_change_value"]) == ("method", 0.3)
    assert "collision_exposures" not in recorded
    assert evaluation_settings_of({"evaluation": recorded}) == cfg.evaluation
