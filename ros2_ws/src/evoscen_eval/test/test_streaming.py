"""Scores computed in one pass (evoscen_eval.scoring.streaming): the block size changes nothing, and
nothing the stream holds grows with the run except its output lists.

* One hand-built run with something at every block boundary — an exposure that continues
  from block to block, a SUT lane change that switches direction without a gap, its PET
  window running past the change's end, an attributed rear conflict, an exposure open at the
  end, collisions, complexity windows — scored with blocks of 1, 2, 3, 7, 64 and 256 states:
  the same report (integers equal; the sums of floats, summed block by block, to 1e-12).
* The timeline keeps at most TIMELINE_POINTS points: 10 states with TTC 9 8 3 7 | 6 5 1.25 9 |
  9 9 and room for 4 points become buckets of 4 states with the lowest TTC of each (3, 1.25, 9).
* A 5,000-state run leaves only output-sized state in the stream (timeline capped, the block
  emptied).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_contract import topics as T
from evoscen_eval.scoring import plot_inputs, streaming
from evoscen_eval.scoring.metrics import evaluate, stream_run
from evoscen_eval.scoring.run_fixtures import make_run
from evoscen_sim.config.scenario_config import EvaluationConfig

EV = EvaluationConfig()


def busy_run():
    """250 states, 5 vehicles (SUT = 0 at s = 1000 m, 30 m/s, lane 2)."""
    events = [{"name": T.EVENT_COLLISION, "step": 100, "time_s": 10.0, "ids": [0, 1]},
              {"name": T.EVENT_COLLISION, "step": 120, "time_s": 12.0, "ids": [3, 4]},
              {"name": T.EVENT_COLLISION, "step": 249, "time_s": 24.9, "ids": [2, 0]},
              {"name": T.EVENT_LANE_CHANGE, "step": 61, "time_s": 6.1, "ids": [0], "duration_s": 2.1,
               "kind": "completed"}]
    run = make_run(250, 5, events=events)
    c = run.columns
    # vehicle 1 cuts in 8 m ahead, 5 m/s slower (TTC 1.6 s) for states 95..109
    c["s"][:, 1], c["speed"][:, 1], c["d"][:, 1] = 1012.8, 25.0, 3.5
    c["d"][95:110, 1] = 0.5
    # the SUT changes lanes left over 40..60, then right over 61..70 (a switch: two changes), target lane 3
    c["lane_change"][40:61, 0] = 1
    c["lane_change"][61:71, 0] = -1
    c["target_lane"][:, 0] = 2
    c["target_lane"][40:61, 0] = 3
    # vehicle 2: 20 m behind in the SUT's path and in lane 3, braking hard at 62..66 (THW 0.5 s: attributed)
    c["s"][:, 2], c["lane"][:, 2], c["speed"][:, 2] = 980.0 + 4.8, 3, 30.0
    c["accel"][62:67, 2] = -7.0
    # vehicle 3 in view, speeding up during the changes; vehicles 3 and 4 change lanes
    c["s"][:, 3] = 1050.0
    c["speed"][45:, 3] = 27.5
    c["accel"][45:55, 3] = 0.8
    c["lane_change"][50:58, 3] = 1
    c["s"][:, 4] = 1090.0
    c["lane_change"][150:160, 4] = -1
    # the SUT brakes hard over 198..203 and again from 245 to the end (open at the end)
    c["accel"][198:204, 0] = -7.0
    c["accel"][245:, 0] = -6.5
    return run


def _same(a, b, path="report"):
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and not isinstance(b, bool):
        assert b == pytest.approx(a, rel=1e-12, abs=1e-15), path
    else:
        assert a == b, path


@pytest.mark.parametrize("block", [1, 2, 3, 7, 64])
def test_block_size_changes_nothing(block, monkeypatch):
    run = busy_run()
    reference = evaluate(run, EV)
    monkeypatch.setattr(streaming, "BLOCK_STATES", block)
    _same(reference, evaluate(run, EV))
    # the run has what the test is about
    s = reference["safety"]
    assert s["collisions"] == 2 and s["collisions_all"] == 3
    assert [(x["start_state"], x["end_state"]) for x in s["exposure_list"]][:2] == [(62, 67), (95, 110)]
    assert s["exposure_list"][-1]["open_at_end"] and s["exposure_list"][-1]["start_state"] == 245
    assert s["conflicts"]["rear_conflict_states_attributed"] == 5
    pets = s["conflicts"]["lane_change_pet"]
    assert [(p["start_state"], p["end_state"], p["window_end_state"]) for p in pets] == [(40, 61, 111), (61, 71, 121)]
    # PET of the first change: vehicle 2 in lane 3, gap 20 - 4.8 = 15.2 m at 30 m/s
    assert pets[0]["follower_id"] == 2 and pets[0]["pet_s"] == pytest.approx((1000.0 - 984.8 - 4.8) / 30.0)
    assert reference["complexity"]["per_window"]["lane_changes"] == [3, 1]  # SUT at 40 and 61, vehicle 3 at 50 | vehicle 4 at 150


def test_timeline_keeps_the_lowest_ttc_of_each_bucket(monkeypatch):
    monkeypatch.setattr(plot_inputs, "TIMELINE_POINTS", 4)
    monkeypatch.setattr(streaming, "BLOCK_STATES", 3)
    run = make_run(10, 2)
    ttc = np.array([9.0, 8.0, 3.0, 7.0, 6.0, 5.0, 1.25, 9.0, 9.0, 9.0])
    run.columns["speed"][:, 1] = 20.0  # closing at 10 m/s
    run.columns["s"][:, 1] = 1000.0 + 4.8 + 10.0 * ttc  # gap = 10 m/s x TTC
    run.columns["d"][:, 1] = 0.0
    plot = stream_run(run, EV).plot_data()
    assert plot.timeline_stride == 4
    assert plot.timeline_time_s.tolist() == pytest.approx([0.0, 0.4, 0.8])
    assert plot.timeline_ttc.tolist() == pytest.approx([3.0, 1.25, 9.0])
    assert plot.timeline_speed.tolist() == [30.0, 30.0, 30.0]
    assert int(plot.ttc_hist.sum()) == 10  # every TTC is finite and at most 20 s
    assert plot.ttc_hist[2] == 1  # [1.0, 1.5) s: the 1.25 s state


def test_a_long_run_leaves_only_output_sized_state(monkeypatch):
    monkeypatch.setattr(plot_inputs, "TIMELINE_POINTS", 100)
    run = make_run(5000, 3)
    st = stream_run(run, EV)
    assert st.states == 5000 and not st._block and not st._block_t
    assert len(st.plots._tl["t"]) <= 100 and st.plots._stride == 64  # 5000 / 64 = 78.1 -> 79 buckets
    assert len(st.windows["lane_changes"]) == 50  # one count per 100-state window
    assert st.n["in_view"] == 5000 * 0  # the BVs are 500 m ahead: never in view
    assert math.isfinite(st.speed_sum) and st.speed_sum == pytest.approx(5000 * 30.0)


def _collision(step: int, other: int) -> dict:
    return {"name": T.EVENT_COLLISION, "step": step, "time_s": step / 10, "ids": [0, other]}


@pytest.mark.parametrize("block", [1, 256])
def test_collision_kinds_by_hand(block, monkeypatch):
    """Who was changing lanes within 2 s (20 states) up to the contact, else who was behind:
    vehicle 1 cuts in (lane change over 10..19, contact at 25); the SUT cuts in (30..34, contact
    at 54: 20 states after its last, still counted); both (the SUT over 60..66, vehicle 1 over
    62..65, contact at 66); vehicle 2 changed lanes at state 70, 21 states before the contact
    at 91, the SUT ahead of it: a rear-end by the other; the SUT behind vehicle 3 at 99."""
    monkeypatch.setattr(streaming, "BLOCK_STATES", block)
    events = [_collision(25, 1), _collision(54, 1), _collision(66, 1), _collision(91, 2), _collision(99, 3)]
    run = make_run(100, 4, events=events)
    c = run.columns
    c["lane_change"][10:20, 1] = -1
    c["lane_change"][30:35, 0] = 1
    c["lane_change"][60:67, 0] = 1
    c["lane_change"][62:66, 1] = 1
    c["lane_change"][70, 2] = 1
    c["s"][:, 1], c["s"][:, 2], c["s"][:, 3] = 1002.0, 996.0, 1004.0  # 1 and 3 ahead, 2 behind
    s = evaluate(run, EV)["safety"]
    assert [x["kind"] for x in s["collision_list"]] == [
        "other_cut_in", "sut_cut_in", "both_changing", "rear_ended_by_other", "sut_rear_end"]
    assert s["collisions_by_kind"] == {"sut_cut_in": 1, "other_cut_in": 1, "both_changing": 1, "sut_rear_end": 1,
                                       "rear_ended_by_other": 1, "unknown": 0}
