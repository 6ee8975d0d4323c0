"""AD's acceleration (complexity, docs/evaluation.md "AD"): smoothed over a trailing window vs literal."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from evoscen_eval.scoring.metrics import activity_accel, evaluate
from evoscen_eval.scoring.run_fixtures import make_run
from evoscen_eval.scoring.rundata import RunData
from evoscen_sim.config.scenario_config import EvaluationConfig


def test_trailing_mean_by_hand() -> None:
    a = np.array([1.0, -1.0, 1.0, -1.0, 3.0, 3.0, 3.0])[:, None]
    # dt 0.1 s, window 0.3 s -> 3 states; the first states average what there is
    got = activity_accel(a, 0.1, "smoothed", 0.3)[:, 0]
    assert got == pytest.approx([1.0, 0.0, 1.0 / 3.0, -1.0 / 3.0, 1.0, 5.0 / 3.0, 3.0])
    assert activity_accel(a, 0.1, "literal", 0.3) is not None
    assert np.array_equal(activity_accel(a, 0.1, "literal", 0.3), a)
    # a window shorter than a step is the step itself
    assert np.array_equal(activity_accel(a, 0.1, "smoothed", 0.01), a)
    with pytest.raises(ValueError, match="expected 'smoothed' or 'literal'"):
        activity_accel(a, 0.1, "median", 1.0)


def _run(states: int, accel: np.ndarray) -> RunData:
    run = make_run(states, accel.shape[1])
    run.columns["s"][:] = 1000.0 + 200.0 * np.arange(accel.shape[1])
    run.columns["accel"][:] = accel
    return run


def test_dawdling_noise_is_not_activity_but_a_manoeuvre_is() -> None:
    # vehicle 1 alternates +0.5 / -0.5 m/s^2 every step (noise: the 1 s mean is 0 or +-0.05);
    # vehicle 2 brakes at -0.5 m/s^2 for 2 s from state 20 (a manoeuvre)
    states = 100
    acc = np.zeros((states, 3))
    acc[:, 1] = np.where(np.arange(states) % 2 == 0, 0.5, -0.5)
    acc[20:40, 2] = -0.5
    ev = EvaluationConfig()
    lit = evaluate(_run(states, acc), replace(ev, accel_activity_form="literal"))["complexity"]
    smo = evaluate(_run(states, acc), ev)["complexity"]
    assert lit["accel_decel"] == 100 + 20
    # smoothed (10 states): vehicle 1: state 0 alone = 0.5 (> 0.1), state 1: 0, state 2: 1/6, state 4: 0.1
    # (not above), 6: 0.5/7, ... -> states 0 and 2 count; vehicle 2: the mean over 11..20 is -0.05,
    # 21..29 reach -0.1 at 21 (2 of 10: -0.1, not above), -0.15 at 22 ... -0.5 at 29..39, then the
    # window leaves the braking: 40 -> -0.45 ... 47 -> -0.1 (not above): states 22..46 = 25 states
    assert smo["accel_decel"] == 2 + 25
    assert smo["accel_activity_form"] == "smoothed" and smo["accel_activity_window_s"] == 1.0
    expected = 0.4 * 0.0 + 0.3 * (2 - 1.0 - math.exp(-27 / 1400))
    assert smo["score"] == pytest.approx(expected)
