"""Paired differences, detection and seeds needed (evoscen_experiments.sensitivity), values by hand."""

from __future__ import annotations

import math

import pytest

from evoscen_experiments.sensitivity import (Design, design_compute, mutation_score, paired, pairing, score_of,
                                         seeds_needed, sharper_design, summarise_design)

T975_DF1 = 12.706204736   # Student-t 0.975 quantile, 1 degree of freedom
T975_DF2 = 4.302652730    # 2 degrees of freedom
T975_DF3 = 3.182446305    # 3 degrees of freedom


def test_paired_two_seeds_by_hand() -> None:
    # d = [1.0, 1.1]: mean 1.05, sd = 0.1/sqrt(2), half = t(1) * sd / sqrt(2) = t(1) * 0.05
    p = paired({0: 3.0, 1: 3.1}, {0: 2.0, 1: 2.0})
    assert p.n == 2
    assert p.mean == pytest.approx(1.05)
    assert p.half == pytest.approx(T975_DF1 * 0.05, rel=1e-9)
    assert p.above_zero


def test_paired_uses_only_shared_seeds_and_is_not_detected_when_interval_straddles_zero() -> None:
    # shared seeds 0, 1, 2: d = [1, 1, 2]; mean 4/3, sd = sqrt(1/3), half = t(2) * sqrt(1/3) / sqrt(3) = t(2) / 3
    p = paired({0: 1.0, 1: 2.0, 2: 3.0, 7: 9.0}, {0: 0.0, 1: 1.0, 2: 1.0, 8: 0.0})
    assert p.n == 3
    assert p.mean == pytest.approx(4.0 / 3.0)
    assert p.half == pytest.approx(T975_DF2 / 3.0, rel=1e-9)
    assert p.low == pytest.approx(4.0 / 3.0 - T975_DF2 / 3.0)
    assert not p.above_zero  # 1.333 - 1.434 < 0


def test_paired_skips_seeds_where_a_score_is_undefined() -> None:
    # seed 1's mutant value is undefined (nan): d over seeds 0 and 2 = [1.0, 1.1]
    p = paired({0: 3.0, 1: 5.0, 2: 3.1}, {0: 2.0, 1: math.nan, 2: 2.0})
    assert p.n == 2 and p.mean == pytest.approx(1.05) and p.half == pytest.approx(T975_DF1 * 0.05, rel=1e-9)


def test_paired_degenerate_cases() -> None:
    one = paired({0: 2.0}, {0: 1.0})
    assert one.n == 1 and one.mean == 1.0 and math.isnan(one.half) and not one.above_zero
    none = paired({0: 2.0}, {1: 1.0})
    assert none.n == 0 and math.isnan(none.mean) and not none.above_zero
    # identical values: zero spread, zero half-width, mean 0 -> not above zero
    same = paired({0: 1.0, 1: 1.0}, {0: 1.0, 1: 1.0})
    assert same.mean == 0.0 and same.half == 0.0 and not same.above_zero


def test_seeds_needed_counts_only_a_settled_detection() -> None:
    # d = [1, 1.1, -2, 1 x 9]: the first 2 seeds are detected (1.05 - 0.635 > 0), seeds 3..9 are not
    # (the -2 widens the interval), from 10 on every prefix is (10: mean 0.71, half 0.68)
    d = [1.0, 1.1, -2.0] + [1.0] * 9
    intact = {s: v for s, v in enumerate(d)}
    mutant = dict.fromkeys(range(len(d)), 0.0)
    assert seeds_needed(intact, mutant) == 10
    assert seeds_needed({0: 1.0, 1: 1.1}, {0: 0.0, 1: 0.0}) == 2
    assert seeds_needed({0: 1.0, 1: 1.0, 2: 2.0}, {0: 0.0, 1: 0.0, 2: 0.0}) is None  # not detected with all
    assert seeds_needed({0: 1.0}, {0: 0.0}) is None


def test_mutation_score_and_score_of() -> None:
    assert mutation_score([True, False, True, True]) == 0.75
    assert math.isnan(mutation_score([]))
    rep = {"intelligence": {"score": 0.7}, "safety": {"score": 0.9}, "efficiency": {"score": 0.2},
           "interaction": {"score": 0.5}}
    assert score_of(rep, "safety") == 0.9
    assert math.isnan(score_of({**rep, "interaction": {"score": None}}, "interaction"))  # undefined I_i
    with pytest.raises(ValueError, match="score 'bogus': expected one of intelligence"):
        score_of(rep, "bogus")


def test_pairing_by_hand() -> None:
    # intact [1, 2, 3], mutant [2, 4, 7]: deviations [-1, 0, 1] and [-2.33, -0.33, 2.67];
    # r = 5 / sqrt(2 * 12.6667) = 0.99339
    assert pairing({0: 1.0, 1: 2.0, 2: 3.0}, {0: 2.0, 1: 4.0, 2: 7.0}) == pytest.approx(5.0 / math.sqrt(2 * 38 / 3))
    # perfectly opposite; only the shared, finite seeds count (seed 9 only on one side, seed 3 undefined)
    assert pairing({0: 1.0, 1: 2.0, 2: 3.0, 3: math.nan, 9: 5.0}, {0: 3.0, 1: 2.0, 2: 1.0, 3: 4.0}) == pytest.approx(-1.0)
    # fewer than 3 seeds, or a side that does not vary: undefined
    assert math.isnan(pairing({0: 1.0, 1: 2.0}, {0: 1.0, 1: 3.0}))
    assert math.isnan(pairing({0: 1.0, 1: 2.0, 2: 3.0}, {0: 0.5, 1: 0.5, 2: 0.5}))


def test_equal_compute_by_hand() -> None:
    # 100 episodes x 300 steps and 10 seeds x 3,000 steps: 30,000 SUT steps per variant each; the warm-up
    # (20 s at dt 0.1 s = 200 steps) comes before every run: 100 x 200 = 20,000 and 10 x 200 = 2,000 extra
    episodes, long = Design("episodes", 100, 300, 20000), Design("long", 10, 3000, 30000)
    ce, cl = design_compute(episodes, 200), design_compute(long, 200)
    assert ce.sut_steps == cl.sut_steps == 30_000
    assert (ce.warmup_steps, ce.total) == (20_000, 50_000)
    assert (cl.warmup_steps, cl.total) == (2_000, 32_000)
    assert design_compute(episodes, 0).total == 30_000  # no warm-up: nothing extra
    assert episodes.seeds == range(20000, 20100) and long.seeds == range(30000, 30010)
    assert (episodes.unit, long.unit) == ("episode", "seed")


def _synthetic() -> dict:
    """Per-seed intelligence of two designs on one scenario, two mutants each (values chosen by hand)."""
    intact = {0: 1.0, 1: 2.0, 2: 3.0, 3: 4.0}
    episodes = summarise_design(intact, {
        "m1": {0: 0.0, 1: 1.0, 2: 2.0, 3: 3.0},   # d = [1, 1, 1, 1]: mean 1, half 0 -> detected; r = 1
        "m2": {0: 0.0, 1: 3.0, 2: 2.0, 3: 5.0},   # d = [1, -1, 1, -1]: mean 0, sd 2/sqrt(3) -> half t3/sqrt(3)
    })
    long = summarise_design({10: 0.8, 11: 0.6}, {
        "m1": {10: 0.7, 11: 0.4},                 # d = [0.1, 0.2]: mean 0.15, half t1 * 0.05 = 0.635 -> not detected
        "m2": {10: 0.5, 11: 0.2},                 # d = [0.3, 0.4]: mean 0.35, half t1 * 0.05 -> not detected
    })
    return {"episodes": episodes, "long": long}


def test_design_summary_by_hand() -> None:
    s = _synthetic()
    ep, lg = s["episodes"], s["long"]
    assert ep.per_mutant["m1"].mean == pytest.approx(1.0) and ep.per_mutant["m1"].half == pytest.approx(0.0)
    assert ep.per_mutant["m2"].mean == pytest.approx(0.0)
    assert ep.per_mutant["m2"].half == pytest.approx(T975_DF3 / math.sqrt(3), rel=1e-9)
    assert [p.n for p in ep.per_mutant.values()] == [4, 4]
    assert (ep.detected, ep.mutants, ep.score) == (1, 2, 0.5)
    assert ep.median_half == pytest.approx(T975_DF3 / math.sqrt(3) / 2, rel=1e-9)  # median of 0 and t3/sqrt(3)
    # r(m2): intact deviations [-1.5, -0.5, 0.5, 1.5], m2's [-2.5, 0.5, -0.5, 2.5]: 7 / sqrt(5 * 13)
    assert ep.pairing_r["m1"] == pytest.approx(1.0)
    assert ep.median_r == pytest.approx((1.0 + 7.0 / math.sqrt(65.0)) / 2)
    assert lg.per_mutant["m1"].mean == pytest.approx(0.15) and lg.per_mutant["m2"].mean == pytest.approx(0.35)
    assert lg.per_mutant["m1"].half == pytest.approx(T975_DF1 * 0.05, rel=1e-9)
    assert (lg.detected, lg.score) == (0, 0.0)
    assert lg.median_half == pytest.approx(T975_DF1 * 0.05, rel=1e-9)
    assert math.isnan(lg.median_r)  # two seeds: no pairing r


def test_sharper_design_detections_first_then_narrower_interval() -> None:
    s = _synthetic()
    assert sharper_design({"episodes": [s["episodes"]], "long": [s["long"]]}) == "episodes"  # 1 detected vs 0
    # both detect none: the narrower median half-width wins (0.05 * t1 over two mutants vs 0.3 * t1)
    narrow = summarise_design({0: 1.0, 1: 1.0}, {"m": {0: 1.0, 1: 0.9}})     # d = [0, 0.1]: half t1 * 0.05
    wide = summarise_design({0: 1.0, 1: 1.0}, {"m": {0: 1.3, 1: 0.7}})       # d = [-0.3, 0.3]: half t1 * 0.3
    assert narrow.detected == wide.detected == 0
    assert sharper_design({"episodes": [wide], "long": [narrow]}) == "long"
    assert sharper_design({"episodes": [narrow], "long": [narrow]}) is None  # a tie on both
    # detections add up over scenarios: 1 + 0 against 0 + 0
    assert sharper_design({"episodes": [s["episodes"], wide], "long": [narrow, narrow]}) == "episodes"


def test_design_summary_medians_are_medians() -> None:
    # three mutants on seeds 0..2, intact [1, 2, 3]:
    #   a [0, 1, 2]: d = [1, 1, 1], half 0, r 1
    #   b [1, 0, 3]: d = [0, 2, 0], sd sqrt(4/3), half t2 * 2/3; r = 2 / sqrt(2 * 42/9)
    #   c [3, 2, 1]: d = [-2, 0, 2], sd 2, half t2 * 2/sqrt(3); r -1
    s = summarise_design({0: 1.0, 1: 2.0, 2: 3.0}, {"a": {0: 0.0, 1: 1.0, 2: 2.0}, "b": {0: 1.0, 1: 0.0, 2: 3.0},
                                                     "c": {0: 3.0, 1: 2.0, 2: 1.0}})
    assert s.median_half == pytest.approx(T975_DF2 * 2.0 / 3.0, rel=1e-9)      # not the mean of the three
    assert s.median_r == pytest.approx(2.0 / math.sqrt(2.0 * 42.0 / 9.0))
    assert (s.detected, s.mutants) == (1, 3)
