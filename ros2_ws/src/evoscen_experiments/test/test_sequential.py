"""Sequential paired verdicts (evoscen_experiments.sequential): the boundaries spend exactly the alpha they
are given, and the verdicts keep their error rates over repeated looks — checked by simulation on
synthetic paired differences with known means (docs/sensitivity.md, "Sequential verdicts")."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from evoscen_experiments.sequential import boundaries, looks_of, spent, verdict

ALPHA = 0.05


def test_one_look_is_the_fixed_sample_interval_and_the_first_obf_look_is_its_closed_form():
    assert boundaries((1.0,)) == pytest.approx((norm.ppf(0.975),), abs=1e-6)
    c = boundaries((0.25, 0.5, 0.75, 1.0))
    # first look: P(|Z| >= c_1) = spent(0.25) = 2 - 2 Phi(1.96 / 0.5), so c_1 = 1.96 / 0.5
    assert c[0] == pytest.approx(norm.isf(spent(0.25, ALPHA) / 2), abs=1e-6)
    assert c[0] == pytest.approx(2 * norm.ppf(0.975), abs=1e-6)
    assert list(c) == sorted(c, reverse=True) and c[-1] > norm.ppf(0.975)  # O'Brien-Fleming: wide early
    p = boundaries((0.25, 0.5, 0.75, 1.0), spending="pocock")
    assert max(p) - min(p) < 0.06  # Pocock: nearly flat


@pytest.mark.parametrize("spending", ["obrien_fleming", "pocock"])
def test_the_boundaries_spend_alpha_under_the_null(spending):
    """Brownian motion at 5 equally spaced looks, 400,000 paths: the chance of crossing any boundary is
    alpha (within three Monte Carlo standard errors)."""
    rng = np.random.default_rng(20261206)
    t = np.arange(1, 6) / 5
    c = np.array(boundaries(tuple(t), ALPHA, spending))
    w = np.cumsum(rng.normal(size=(400_000, 5)) * math.sqrt(0.2), axis=1)
    crossed = (np.abs(w / np.sqrt(t)) >= c).any(axis=1).mean()
    assert abs(crossed - ALPHA) < 3 * math.sqrt(ALPHA * (1 - ALPHA) / 400_000)


def _rates(mean: float, draw, sims: int = 2000, delta: float = 0.02) -> dict[str, float]:
    rng = np.random.default_rng(int(1e6 * mean) + 7)
    counts = {"a_higher": 0, "b_higher": 0, "equivalent": 0, "unresolved": 0}
    for _ in range(sims):
        v = verdict(mean + draw(rng, 400), round_size=50, budget=400, delta=delta)
        assert v.episodes % 50 == 0 and (v.verdict != "unresolved" or v.episodes == 400)
        counts[v.verdict] += 1
    return {k: n / sims for k, n in counts.items()}


def normal(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.normal(0.0, 0.1, n)


def skewed(rng: np.random.Generator, n: int) -> np.ndarray:
    return 0.1 * (rng.exponential(1.0, n) - 1.0)  # mean 0, sd 0.1, skewed


LIMIT = ALPHA + 3 * math.sqrt(ALPHA * (1 - ALPHA) / 2000)


@pytest.mark.parametrize("draw", [normal, skewed], ids=["normal", "skewed"])
def test_no_difference_is_called_a_difference_more_often_than_alpha(draw):
    rates = _rates(0.0, draw)
    assert rates["a_higher"] + rates["b_higher"] <= LIMIT, rates
    assert rates["equivalent"] > 0.5, rates  # sd 0.1, n 400: the interval fits inside +-0.02 most often


def test_a_difference_at_the_margin_is_called_equivalent_at_most_alpha():
    rates = _rates(0.02, normal)
    assert rates["equivalent"] <= LIMIT and rates["b_higher"] == 0.0, rates


def test_a_real_difference_is_found_and_never_reversed():
    rates = _rates(0.03, normal)  # 6 standard errors at the budget
    assert rates["a_higher"] > 0.95 and rates["b_higher"] == 0.0, rates


def test_verdicts_on_hand_made_differences():
    ones = np.full(400, 0.05) + np.tile([0.01, -0.01], 200)  # mean 0.05, sd ~0.01: above 0 at the first look
    v = verdict(ones, round_size=50, budget=400, delta=0.02)
    assert (v.verdict, v.episodes, v.looks) == ("a_higher", 50, 1) and v.low > 0
    v = verdict(-ones, round_size=50, budget=400, delta=0.02)
    assert v.verdict == "b_higher" and v.high < 0
    noisy = np.tile([0.5, -0.5], 200)  # mean 0, sd 0.5: neither side nor inside +-0.02 at 400
    v = verdict(noisy, round_size=50, budget=400, delta=0.02)
    assert (v.verdict, v.episodes, v.looks) == ("unresolved", 400, 8) and v.low < 0 < v.high
    assert verdict(noisy[:120], round_size=50, budget=400, delta=0.02).verdict == "continue"
    assert looks_of(50, 120) == (50, 100, 120)
    with pytest.raises(ValueError, match="round_size 1"):
        looks_of(1, 10)
