"""What the report says about an exposure, and the animation (docs/evaluation.md §2.1, §7.1).

Hand-built runs (``make_run``: SUT vehicle 0 at s = 1000 m, 30 m/s; bodies 4.8 x 1.9 m; dt 0.1 s;
``rear_run``: a SUT lane change in front of a faster vehicle, follower TTC 1.04 s, cut-in gap 5.2 m):
every number below follows from the definitions by hand.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from evoscen_eval.scoring.animation import FrameSeries, frame_notes, pick, write_animation
from evoscen_eval.scenes.clips import clip_frames, events_of
from evoscen_eval.scoring.exposure_rules import involved, rule_text
from evoscen_eval.scoring.metrics import evaluate
from evoscen_eval.scoring.report import (
    exposure_rows,
    exposure_spans,
    markdown,
    worst_exposure_title,
    write_report,
)
from evoscen_eval.scoring.run_fixtures import make_run, rear_run
from evoscen_sim.config.scenario_config import EvaluationConfig

EV = EvaluationConfig()
EVL = replace(EV, headway_threshold_s=0.0)
"""For :func:`leader_run`: without the tailgating rule (its headway 16.1 / 30 = 0.54 s would count after the 2-s grace)."""


def leader_run(states: int = 30):
    """Vehicle 1 ahead of the SUT in its lane at 20 m/s (closing at 10 m/s); the gap shrinks from 19 m
    by 0.1 m a state, so TTC = gap / 10 goes 1.9, 1.89, ... 1.61 s: every state dangerous (< 2 s),
    one exposure open at the end, lowest TTC 1.61 s at the last state (the worst: 2 / 1.61)."""
    run = make_run(states, 2)
    gap = 19.0 - 0.1 * np.arange(states)
    run.columns["s"][:, 1] = 1000.0 + 4.8 + gap
    run.columns["speed"][:, 1] = 20.0
    return run


def test_an_exposure_with_a_known_ttc_says_it_in_the_table_and_on_the_plot(tmp_path):
    run = leader_run()
    rep = write_report(run, tmp_path, override=EVL, animation_frames=5)
    (x,) = rep["safety"]["exposure_list"]
    assert (x["start_state"], x["end_state"], x["worst_state"]) == (0, 30, 29)
    assert x["min_ttc_s"] == pytest.approx(1.61)
    assert x["severity"] == pytest.approx(2.0 / 1.61)
    front = x["rules"][0]
    assert (front["rule"], front["measure"], front["vehicle_id"], front["states"], front["state"]) == \
        ("front_ttc", "TTC to the leader", 1, 30, 29)
    assert front["value"] == pytest.approx(1.61) and front["threshold"] == 2.0
    # the table's row and the worst-exposure snapshot's title print the same TTC of the same entry
    row = next(line for line in (tmp_path / "report.md").read_text().splitlines() if line.startswith("| 1 | 0.0 |"))
    assert row == "| 1 | 0.0 | 30 (open) | TTC ahead: TTC to the leader 1.61 s < 2 s (vehicle 1) | 1.61 | 1.24 |"
    title = worst_exposure_title(rep, 29, 2.9)
    assert "TTC to the leader 1.61 s < 2 s (vehicle 1)" in title and "lowest TTC ahead 1.61 s" in title
    assert "worst exposure (no. 1 of report.md)" in title
    assert (tmp_path / "worst_exposure.png").stat().st_size > 0


def test_the_worst_state_is_not_the_lowest_ttc_state_yet_one_ttc_is_shown():
    """rear_run with a leader in the SUT's path at 24 m/s, 30 m ahead at state 0 and 0.2 m nearer each
    state (closing at 1 m/s as far as TTC goes: TTC(k) = 25.2 − 0.2·k s, never dangerous): the exposure
    (7, 40) is the rear conflict and the cut-in, its worst state 7 (TTC 23.8 s there); its lowest TTC
    ahead, 25.2 − 0.2·39 = 17.4 s at state 39, is the one TTC the table and the snapshot print (the
    snapshot once printed the TTC of its own state)."""
    run = rear_run()
    c = {f: np.concatenate([v, np.zeros((v.shape[0], 1))], axis=1) for f, v in run.columns.items()}
    c["id"][:, 2], c["length"][:, 2], c["width"][:, 2] = 2, 4.8, 1.9
    c["s"][:, 2], c["speed"][:, 2], c["lane"][:, 2], c["target_lane"][:, 2] = 130.0 - 0.2 * np.arange(40), 24.0, 2, 2
    c["d"][:, 2] = c["d"][:, 0]  # in the SUT's path all along
    run.columns, run.ids = c, np.arange(3)
    rep = evaluate(run, EV)
    (x,) = rep["safety"]["exposure_list"]
    assert x["worst_state"] == 7 and x["min_ttc_s"] == pytest.approx(17.4)
    line = exposure_rows([x])[2]
    assert "| 17.4 |" in line
    title = worst_exposure_title(rep, x["worst_state"], 0.7)
    assert "lowest TTC ahead 17.4 s" in title and "23.8" not in title


def test_each_rule_by_name_with_its_value_and_vehicle():
    """rear_run, default rules: from state 7 the follower (vehicle 1) is in the SUT's path, TTC
    5.2 / 5 = 1.04 s (rear conflict, attributed: the SUT is changing lanes) and 5.2 m behind it while
    the SUT changes lanes (cut-in < 10 m, states 7..9); the exposure runs to the end (7, 40)."""
    rep = evaluate(rear_run(), EV)
    (x,) = rep["safety"]["exposure_list"]
    assert (x["start_state"], x["end_state"]) == (7, 40)
    by = {(r["rule"], r["measure"]): r for r in x["rules"]}
    assert set(by) == {("rear", "follower TTC"), ("cut_in", "gap to the new follower")}
    rear, cut = by["rear", "follower TTC"], by["cut_in", "gap to the new follower"]
    assert rear["value"] == pytest.approx(1.04) and rear["vehicle_id"] == 1 and rear["states"] == 33
    assert cut["value"] == pytest.approx(5.2) and cut["vehicle_id"] == 1 and cut["states"] == 3
    assert x["rule_states"] == {"front_ttc": 0, "hard_braking": 0, "rear": 33, "cut_in": 3, "beside": 0,
                                "tailgating": 0}
    assert rule_text(cut) == "cut-in: gap to the new follower 5.2 m < 10 m (vehicle 1)"
    # severity: the largest ratio of the rules that hold, 2 / 1.04 (rear) over 10 / 5.2 (cut-in)
    assert x["severity"] == pytest.approx(max(2.0 / 1.04, 10.0 / 5.2))
    # the clips name the involved vehicle
    (event,) = events_of(rep)
    assert event["ids"] == [1] == involved(x)


def test_severity_counts_only_rules_that_hold():
    """leader_run with the SUT braking at −9 m/s² throughout: under hard_braking conflict (no follower:
    not imposed, DRAC 10² / (2·gap) ≤ 100 / 32.2 = 3.1 < 6: not needed) the braking is no rule, so the
    severity stays the TTC's 2 / 1.61; under own it is one, severity 9 / 6."""
    run = leader_run()
    run.columns["accel"][:, 0] = -9.0
    (x,) = evaluate(run, EVL)["safety"]["exposure_list"]
    assert x["severity"] == pytest.approx(2.0 / 1.61)
    assert [r["rule"] for r in x["rules"]] == ["front_ttc"]
    (own,) = evaluate(run, replace(EVL, hard_braking="own"))["safety"]["exposure_list"]
    assert own["severity"] == pytest.approx(9.0 / 6.0)
    braking = next(r for r in own["rules"] if r["rule"] == "hard_braking")
    assert (braking["measure"], braking["value"], braking["threshold"], braking["vehicle_id"]) == \
        ("SUT acceleration", -9.0, -6.0, None)


def test_the_rules_in_words_follow_the_settings():
    text = markdown(evaluate(leader_run(), EV), [], EV)
    assert "- tailgating: time headway to the leader < 1 s, not falling back, for more than 2 s" in text
    assert "- TTC ahead: the SUT's TTC to the leader in its path < 2 s" in text
    assert "- cut-in: the SUT changing lanes with its new follower closer than 10 m" in text
    assert "acceleration < −6 m/s²)" not in text  # the method's words alone are not the rules
    off = markdown(evaluate(leader_run(), EV), [], replace(EV, cut_in_gap_m=0.0, hard_braking="own"))
    assert "cut-in" not in off.split("## Safety")[1].split("| quantity")[0]
    assert "- hard braking: the SUT's acceleration < −6 m/s²" in off


def test_a_short_exposure_is_drawn_at_least_the_minimum_width():
    """A one-state exposure at 10 s of a 300-s run: 0.1 s wide by itself, drawn 0.4 % of 300 s = 1.2 s
    about its middle (10.05 s); a 20-s exposure keeps its width."""
    rep = {"run": {"dt_s": 0.1, "duration_s": 300.0},
           "safety": {"exposure_list": [{"start_time_s": 10.0, "states": 1}, {"start_time_s": 100.0, "states": 200}]}}
    (a0, b0), (a1, b1) = exposure_spans(rep)
    assert (a0, b0) == pytest.approx((10.05 - 0.6, 10.05 + 0.6))
    assert (a1, b1) == pytest.approx((100.0, 120.0))


def test_the_animation_has_the_frames_asked_for(tmp_path):
    from PIL import Image

    run = rear_run()
    rep = evaluate(run, EV)
    series = clip_frames(run, 100)
    assert len(series.frames) == 40 and [f.lane_change for f in series.frames[4:11]] == [0, 1, 1, 1, 1, 1, 0]
    # one frame a second of driving (every 10th state of 0.1 s): 4 of the 4-s run; at most ``frames``,
    # more spread evenly
    assert write_animation(series, None, rep, tmp_path / "a.gif") == 4
    assert [n.state for n in frame_notes(series, rep, 600, frame_s=1.0)] == [0, 10, 20, 30]
    assert write_animation(series, None, rep, tmp_path / "b.gif", frames=7, frame_s=None) == 7
    with Image.open(tmp_path / "b.gif") as im:
        assert im.n_frames == 7 and im.size[0] == 1280
    assert pick(40, 7) == [0, 6, 13, 20, 26, 32, 39]  # round(i * 39 / 6): 32.5 rounds to even
    assert pick(5, 7) == [0, 1, 2, 3, 4] and pick(5, 0) == []


def test_frames_stay_bounded_and_keep_a_lane_change_between_them():
    """40 states kept at most 8 frames: the stride doubles to 8 (states 0, 8, ..., 32: 5 frames); the
    SUT's change in states 5..9 is kept by the frames standing for them (0 for 5..7, 8 for 8..9)."""
    run = rear_run()
    series = clip_frames(run, 8)
    assert isinstance(series, FrameSeries) and series.stride == 8
    assert [f.state for f in series.frames] == [0, 8, 16, 24, 32]
    assert [f.lane_change for f in series.frames] == [1, 1, 0, 0, 0]


def test_no_plots_writes_no_animation_and_zero_frames_none(tmp_path):
    run = leader_run(12)
    write_report(run, tmp_path / "none", override=EVL, plots=False)
    assert sorted(p.name for p in (tmp_path / "none").iterdir()) == ["report.json", "report.md"]
    write_report(run, tmp_path / "zero", override=EVL, animation_frames=0)
    assert not (tmp_path / "zero" / "run.gif").exists() and (tmp_path / "zero" / "timeline.png").exists()


def test_the_printed_scores_are_weight_times_score():
    from evoscen_eval.scoring.report import score_line

    rep = {"intelligence": {"score": 0.6889, "weights": {"safety": 0.6, "efficiency": 0.2, "interaction": 0.2}},
           "safety": {"score": 0.8104, "collisions": 0, "exposures": 1}, "efficiency": {"score": 0.1874},
           "interaction": {"score": None}, "complexity": {"score": None}}
    rep["intelligence"]["effective_weights"] = {"safety": 0.75, "efficiency": 0.25, "interaction": 0.0}
    assert score_line(rep) == ("the method's intelligence I (for reproducing the paper): 0.6889 = 0.75 × safety I_s "
                               "0.8104 + 0.25 × efficiency I_e 0.1874 + interaction I_i undefined (left out)")


def test_each_drawn_frame_marks_the_lane_change_and_exposure_of_its_states():
    """rear_run, 40 frames kept, 4 drawn (pick: 0, 13, 26, 39): frame 0 stands for states 0..12, which
    hold the SUT's left change (5..9) and the exposure's start (7, the rear conflict and cut-in by
    vehicle 1); frames 13 and 26 hold the exposure (to 40) but no change; the last stands for 39."""
    run = rear_run()
    rep = evaluate(run, EV)
    notes = frame_notes(clip_frames(run, 100), rep, 4)
    assert [(n.state, n.until, n.lane_change) for n in notes] == [(0, 13, 1), (13, 26, 0), (26, 39, 0), (39, 40, 0)]
    assert all(n.exposure is rep["safety"]["exposure_list"][0] for n in notes)
    assert involved(notes[0].exposure) == [1] and all(n.collision is None for n in notes)
    (early,) = frame_notes(clip_frames(run, 100), {"safety": {"exposure_list": [], "collision_list": [
        {"state": 3, "ids": [0, 1]}]}}, 1)
    assert early.collision == {"state": 3, "ids": [0, 1]} and early.lane_change == 1


def test_frames_keep_the_vehicles_within_the_window_of_the_sut():
    """A frame keeps the vehicles whose x is within window + 10 m of the SUT's (here 90 m), their
    fields and ids, the SUT's row among them and the sign of its lane change."""
    from evoscen_contract import contract as C

    f = {name: j for j, name in enumerate(C.WORLD_FIELDS)}
    tables = np.zeros((2, 4, len(C.WORLD_FIELDS)))
    tables[0, :, f["x"]] = [0.0, 50.0, 141.0, -41.0]  # |x - 50| = 50, 0, 91, 91
    tables[1, :, f["x"]] = [0.0, 50.0, 139.0, -39.0]  # 50, 0, 89, 89
    tables[:, :, f["speed"]] = [20.0, 25.0, 30.0, 35.0]
    tables[1, 1, f["lane_change"]] = -1.0
    series = FrameSeries(window_m=80.0)
    series.add_block(np.arange(2), np.array([0.0, 0.1]), tables, np.array([10, 11, 12, 13]), 1)
    first, second = series.frames
    assert first.ids.tolist() == [10, 11] and first.sut_row == 1 and first.lane_change == 0
    assert first.columns["speed"].tolist() == [20.0, 25.0] and first.columns["x"].tolist() == [0.0, 50.0]
    assert second.ids.tolist() == [10, 11, 12, 13] and second.sut_row == 1 and second.lane_change == -1
    assert second.columns["x"].tolist() == [0.0, 50.0, 139.0, -39.0] and second.time_s == 0.1
