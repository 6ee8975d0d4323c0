"""The traffic around the SUT (report.json's ``traffic``, report.md's section, ``traffic.png``),
with values derived by hand.

In every state the BVs with |s_BV − s_SUT| ≤ 100 m count (same road, any lane; the SUT is the
vehicle with role SUT); the counts are averaged per 30-s window (300 states at dt 0.1 s) from
state 0; a last partial window is reported when it holds at least half a window.

* 600 states, 4 BVs: over states 0..299 one BV exactly 100 m ahead, one exactly 100 m behind,
  one 50 m ahead two lanes over (3 count) and one 100.1 m ahead (does not count); from state
  300 only the one 100 m ahead: window means 3 and 1, run mean 2, lowest window 1, no empty state.
* The same run with the SUT driving (s grows 3 m per state, the BVs with it) and every
  vehicle's s shifted by −400 m from state 450 on: the same figures.
* 750 states (the last window 150 = half a window: reported, partial) and 749 (a tail of 149:
  only in the mean and the empty share), the tail without a BV near: every tail state is empty.
* dt 0.2 s: windows of 150 states.
* Blocks of 1, 7 and 256 states give the same section; the timeline's buckets hold the mean count.
"""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_eval.scoring import plot_inputs, streaming
from evoscen_eval.scoring.metrics import evaluate, stream_run
from evoscen_eval.scoring.report import write_report
from evoscen_eval.scoring.run_fixtures import make_run
from evoscen_sim.config.scenario_config import EvaluationConfig

EV = EvaluationConfig()


def three_then_one(states: int = 600):
    """SUT (vehicle 0) at s = 1000 m; BVs 1..4 as in the module docstring, then vehicle 1 alone."""
    run = make_run(states, 5)
    s, lane = run.columns["s"], run.columns["lane"]
    s[:300, 1] = 1100.0  # exactly 100 m ahead: counts
    s[:300, 2] = 900.0  # exactly 100 m behind: counts
    s[:300, 3], lane[:300, 3] = 1050.0, 4  # another lane: counts
    s[:300, 4] = 1100.1  # 100.1 m ahead: does not count
    s[300:600, 1] = 1100.0  # from state 300 only vehicle 1 (BVs 2..4 at 1550, 1600, 1650 m: make_run's)
    return run


def test_three_then_one_by_hand():
    tr = evaluate(three_then_one(), EV)["traffic"]
    assert (tr["range_m"], tr["window_s"], tr["window_states"]) == (100.0, 30.0, 300)
    assert tr["per_window_mean_bvs"] == [3.0, 1.0]
    assert [(w["start_state"], w["states"], w["start_time_s"], w["partial"]) for w in tr["windows"]] == [
        (0, 300, 0.0, False), (300, 300, pytest.approx(30.0), False)]
    assert tr["mean_bvs"] == 2.0  # (300·3 + 300·1) / 600
    assert tr["min_window_mean_bvs"] == 1.0
    assert (tr["empty_states"], tr["empty_share"]) == (0, 0.0)
    assert tr["last_window_partial"] is False and tr["tail_states_left_out"] == 0


def test_a_shift_of_every_s_changes_nothing():
    """Relative positions kept: the SUT drives 3 m per state with the BVs, every s jumps back
    400 m from state 450 (the traffic window moved along the road)."""
    run = three_then_one()
    run.columns["s"] += 3.0 * np.arange(600)[:, None]
    run.columns["s"][450:] -= 400.0
    assert evaluate(run, EV)["traffic"] == evaluate(three_then_one(), EV)["traffic"]


@pytest.mark.parametrize("states, windows, partial, tail", [(750, [3.0, 1.0, 0.0], True, 0),
                                                            (749, [3.0, 1.0], False, 149)])
def test_the_last_window_counts_from_half_a_window(states, windows, partial, tail):
    tr = evaluate(three_then_one(states), EV)["traffic"]  # from state 600 no BV within 100 m
    assert tr["per_window_mean_bvs"] == windows
    assert tr["last_window_partial"] is partial and tr["tail_states_left_out"] == tail
    assert tr["windows"][-1]["states"] == (150 if partial else 300)
    assert tr["empty_states"] == states - 600
    assert tr["empty_share"] == (states - 600) / states
    assert tr["mean_bvs"] == 1200 / states  # the tail is in the run's mean either way
    assert tr["min_window_mean_bvs"] == min(windows)


def test_a_run_under_half_a_window_has_no_window():
    tr = evaluate(three_then_one(149), EV)["traffic"]
    assert tr["windows"] == [] and tr["min_window_mean_bvs"] is None and tr["tail_states_left_out"] == 149
    assert tr["mean_bvs"] == 3.0 and tr["empty_states"] == 0


def test_the_window_follows_dt():
    run = three_then_one()
    run.time_s, run.dt_s = np.arange(600) * 0.2, 0.2  # 30 s = 150 states: 3, 3, 1, 1
    tr = evaluate(run, EV)["traffic"]
    assert tr["window_states"] == 150 and tr["per_window_mean_bvs"] == [3.0, 3.0, 1.0, 1.0]
    assert [w["start_time_s"] for w in tr["windows"]] == pytest.approx([0.0, 30.0, 60.0, 90.0])


@pytest.mark.parametrize("block", [1, 7, 256])
def test_block_size_changes_nothing_and_the_timeline_holds_bucket_means(block, monkeypatch):
    monkeypatch.setattr(streaming, "BLOCK_STATES", block)
    monkeypatch.setattr(plot_inputs, "TIMELINE_POINTS", 5)  # 750 states -> buckets of 256: 3 points
    run = three_then_one(750)
    tr = evaluate(run, EV)["traffic"]
    assert tr["per_window_mean_bvs"] == [3.0, 1.0, 0.0] and tr["empty_states"] == 150
    plot = stream_run(run, EV).plot_data()
    assert plot.timeline_stride == 256
    # bucket 0: states 0..255, all 3; bucket 1: 256..511, 44 x 3 + 212 x 1; bucket 2: 512..749, 88 x 1 + 150 x 0
    assert plot.timeline_bvs.tolist() == [3.0, (44 * 3 + 212) / 256, 88 / 238]


def test_report_md_and_plot(tmp_path):
    report = write_report(three_then_one(750), tmp_path)
    md = (tmp_path / "report.md").read_text()
    assert "## Traffic around the SUT" in md
    assert "| mean BVs | 1.6 | count |" in md  # 1200 / 750
    assert "| lowest window mean | 0 | count |" in md and "| states with none | 150 (20.0 %) | count (share) |" in md
    assert "| 1 | 0.0 | 300 | 3 |" in md and "| 2 | 30.0 | 300 | 1 |" in md and "| 3 | 60.0 | 150 (partial) | 0 |" in md
    assert "![traffic](traffic.png)" in md and (tmp_path / "traffic.png").stat().st_size > 0
    assert report["traffic"]["windows"][-1]["partial"] is True
