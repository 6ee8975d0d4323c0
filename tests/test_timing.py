"""An experiment's start-up and throughput line (evoscen_experiments.timing): its arithmetic, by hand."""

from __future__ import annotations

import pytest
from evoscen_experiments.timing import Timing, first_task_overheads, line, summary


def test_the_line_of_hand_figures():
    # 3,900 runs of 300 SUT steps in 376 s: 1,170,000 / 376 = 3,111.7 SUT-steps/s; start-up 2 + 6 + 13 = 21 s
    d = summary(376.0, 2.0, 6.0, 13.0, 3900, 1_170_000, [300] * 3900)
    assert d["startup_s"] == 21.0 and d["steps_per_run"] == 300
    assert d["sut_steps_per_s"] == pytest.approx(3111.702, abs=1e-3)
    assert line(d) == ("wall 376 s: start-up 21 s (set-up 2.0 s, Ray 6.0 s, workers' first task 13 s), "
                       "3,900 runs × 300 SUT steps = 3,112 SUT-steps/s")
    # runs of different lengths: the total; none computed: said so
    mixed = summary(10.0, 1.0, 4.0, 2.5, 3, 600, [100, 200, 300])
    assert line(mixed).endswith("3 runs, 600 SUT steps = 60 SUT-steps/s") and mixed["steps_per_run"] is None
    assert line(summary(2.5, 2.5, 0.0, 0.0, 0, 0)) == ("wall 2.5 s: start-up 2.5 s (set-up 2.5 s, Ray 0.0 s, "
                                                       "workers' first task 0.0 s), no run computed")


def test_a_commands_figures_add_up():
    t = Timing(start=100.0, ray_at=101.5, ray_s=4.0, first_task_s=1.25)
    for steps in (200, 200, 200):
        t.ran(steps)
    d = t.summary(now=110.0)
    assert (d["wall_s"], d["setup_s"], d["startup_s"]) == (10.0, 1.5, 6.75)  # 1.5 + 4 + 1.25 <= 10
    assert d["sut_steps"] == 600 and d["sut_steps_per_s"] == 60.0
    assert t.rates(now=110.0) == (0.3, 60.0)  # the progress bar's figures: 3 runs and 600 steps over 10 s
    assert Timing(start=100.0).summary(now=103.0)["setup_s"] == 3.0  # no Ray: all set-up


def test_first_task_overhead_is_the_first_runs_extra_over_steady_runs():
    runs = [  # worker a: its first run built a start (3.0 s for 200 steps), then a copy
        {"worker": "a", "first": True, "wait_s": 0.5, "wall_s": 3.0, "steps": 200, "built": True},
        {"worker": "a", "first": False, "wait_s": 0.5, "wall_s": 0.2, "steps": 200, "built": False},
        # worker b: a built start later costs 0.4 s / 200 steps = 2 ms a step: the reference for a's first run
        {"worker": "b", "first": True, "wait_s": -0.1, "wall_s": 1.0, "steps": 100, "built": False},
        {"worker": "b", "first": False, "wait_s": 0.0, "wall_s": 0.4, "steps": 200, "built": True},
    ]
    got = first_task_overheads(runs)
    assert got["a"] == pytest.approx(0.5 + 3.0 - 200 * 0.002)  # 3.1
    assert got["b"] == pytest.approx(0.0 + 1.0 - 100 * 0.001)  # copies: 0.2 s / 200 steps; a clock skew wait counts 0
    assert first_task_overheads([{**runs[0]}]) == {"a": 0.5}  # no other run to compare: the wait alone
