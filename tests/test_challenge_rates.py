"""The weighted ratio estimator of scripts/challenge_rates.py (docs/challenges.md, "The estimator"), by hand,
and its door's one-line errors."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from evoscen_experiments.challenge_rates import Z95, episode_values, weighted_rate

REPO = Path(__file__).resolve().parents[1]


def test_plain_ratio_by_hand():
    r = weighted_rate([1, 0, 2], [1, 1, 2], [1, 1, 1])
    assert r.value == pytest.approx(0.75)  # 3 / 4
    # z = y - R x = (0.25, -0.75, 0.5); var = 3/2 * 0.875 / 4^2
    assert r.half == pytest.approx(Z95 * math.sqrt(1.5 * 0.875 / 16.0))
    assert r.n == 3 and r.n_eff == pytest.approx(3.0)


def test_weighted_ratio_by_hand():
    r = weighted_rate([1, 0, 2], [1, 1, 2], [2.0, 0.5, 1.0])
    assert r.value == pytest.approx(4.0 / 4.5)
    rr = 4.0 / 4.5
    z2 = (2 * (1 - rr)) ** 2 + (0.5 * (0 - rr)) ** 2 + (1 * (2 - 2 * rr)) ** 2
    assert r.half == pytest.approx(Z95 * math.sqrt(1.5 * z2 / 4.5**2))
    assert r.n_eff == pytest.approx(3.5**2 / 5.25)


def test_too_few_episodes():
    with pytest.raises(ValueError):
        weighted_rate([1], [1], [1])


def test_episode_values_of_a_report():
    rep = {"safety": {"exposures": 3, "collisions": 1}, "surrogate_safety": {"front": {"ttc_episodes": 2}},
           "comparative": {"safety": {"sut_km": 0.8}}}
    assert episode_values(rep) == {"exposures": 3.0, "collisions": 1.0, "front_ttc_episodes": 2.0, "km": 0.8,
                                   "weight": 1.0}
    assert episode_values({**rep, "challenge": {"weight": 0.25}})["weight"] == 0.25


@pytest.mark.parametrize("args, text", [
    (["--mode", "sometimes"], "--mode: expected one of none, naturalistic, nade, got 'sometimes'"),
    (["--episodes", "5", "--first-seed", "10", "--reference-episodes", "5", "--reference-first-seed", "12"],
     "the blocks 10..14 and 12..16 overlap"),
    (["--episodes", "0"], "--episodes"),
])
def test_bad_input_one_line(args, text, tmp_path):
    p = subprocess.run([sys.executable, str(REPO / "scripts" / "challenge_rates.py"), *args, "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and text in p.stderr and p.stderr.startswith("error: ")


def test_weighted_mean_by_hand():
    """(1·2 + 3·0.5) / 2.5 = 1.4; z = w (x − m) = (−0.8, 0.8); var = 2/1 · 1.28 / 2.5² (None left out)."""
    from evoscen_experiments.stats import mean_ci_weighted

    m, half = mean_ci_weighted([1.0, None, 3.0], [2.0, 7.0, 0.5])
    assert m == pytest.approx(1.4)
    assert half == pytest.approx(Z95 * math.sqrt(2.0 * (0.8**2 + 0.8**2) / 2.5**2))
    assert mean_ci_weighted([1.0, 3.0], [1.0, 1.0])[0] == 2.0


def test_intelligence_means_are_weighted_only_for_challenge_runs():
    from evoscen_experiments.intelligence_experiment import _estimator

    plain = _estimator([{"x": 1}, {"x": 2}])
    assert plain([1.0, 3.0])[0] == 2.0
    weighted = _estimator([{"challenge": {"weight": 3.0}}, {"challenge": {"weight": 1.0}}])
    assert weighted([1.0, 3.0])[0] == pytest.approx((3.0 + 3.0) / 4.0)
