"""Paired differences in words, one sign convention (this − reference) everywhere; intervals by hand."""

from __future__ import annotations

import math
from pathlib import Path

from evoscen_experiments.campaign_summary import summary_markdown
from evoscen_experiments.campaign_spec import Spec
from evoscen_experiments.stats import difference_words


def test_an_interval_in_words():
    assert difference_words(0.5, 0.2, 3) == "significantly higher"  # [0.3, 0.7] above 0
    assert difference_words(-0.170, 0.028, 10) == "significantly lower"  # [-0.198, -0.142] below 0
    assert difference_words(0.1, 0.2, 3) == "no significant difference"  # [-0.1, 0.3] holds 0
    assert difference_words(0.2, 0.2, 3) == "no significant difference"  # touching 0 is not above it
    assert difference_words(1.0, math.nan, 1) == "– (n < 2)"


def test_the_campaign_pairs_each_cell_minus_the_reference():
    """mobil D = 0.5, 0.6, 0.7 and level0 D = 0.3, 0.45, 0.5 on seeds 0..2: level0 − mobil = −0.2, −0.15,
    −0.2, mean −0.18333, s = 0.028868, half = t(0.975, 2) · s / √3 = 4.3027 · 0.016667 = 0.07171: the
    interval [−0.2550, −0.1116] lies below 0, level0 significantly lower than mobil."""
    spec = Spec(path=Path("c.yaml"), name="c", config=None, steps=None, seeds=(0, 1, 2), fixed={},
                grid={"sut.model": ("mobil", "level0")}, compare=("sut.model", "mobil"))
    rows = []
    for model, values in (("mobil", (0.5, 0.6, 0.7)), ("level0", (0.3, 0.45, 0.5))):
        for seed, value in enumerate(values):
            rows.append({"sut.model": model, "seed": seed, "comparative": value, "comparative_safety": 1.0,
                         "comparative_progress": 0.5, "comparative_lane_change_time": 0.5,
                         "comparative_interaction": 0.5, "intelligence": 0.9, "complexity": 0.2, "collisions": 0,
                         "exposures": 0, "score_form": "comparative"})
    text = summary_markdown(spec, [None] * 6, rows)
    assert "## Paired by seed: each other sut.model − mobil (D, the comparative score)" in text
    assert "| level0 | 3 | -0.1833 ± 0.0717 | significantly lower |" in text
    # scored with evaluation.score_form: method, the cells are compared by the method's I (0.9 everywhere: no difference)
    method = [{**row, "score_form": "method"} for row in rows]
    text = summary_markdown(spec, [None] * 6, method)
    assert "## Paired by seed: each other sut.model − mobil (I, the method's intelligence)" in text
    assert "| level0 | 3 | 0.0000 ± 0.0000 | no significant difference |" in text
