"""BV realism figures (evoscen_eval.naturalistic.bv_realism) on a hand-built run."""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_contract import topics as T
from evoscen_eval.naturalistic.bv_realism import bv_realism, combine, time_headways
from evoscen_eval.scoring.rundata import RunData


def _run() -> RunData:
    """Vehicles 10 (SUT), 11, 12, 13 (BVs); three states 0.5 s apart, nothing moves in the table.

    Lane 2: SUT at s = 100, BV 11 at 70 (20 m/s), BV 12 at 60 (10 m/s); lane 3: BV 13 at 80 (25 m/s), alone.
    Lengths 5 m: BV 11's gap to the SUT is 25 m (THW 1.25 s), BV 12's to BV 11 is 5 m (THW 0.5 s)."""
    k, v = 3, 4
    base = {name: np.zeros((k, v)) for name in T.WORLD_FIELDS}
    base["id"][:] = [10, 11, 12, 13]
    base["role"][:] = [1, 0, 0, 0]
    base["s"][:] = [100.0, 70.0, 60.0, 80.0]
    base["lane"][:] = [2, 2, 2, 3]
    base["speed"][:] = [30.0, 20.0, 10.0, 25.0]
    base["length"][:] = 5.0
    base["policy"][:] = [0, 2, 3, 2]  # BVs 11 and 13 competitive, 12 cooperative
    events = [
        {"name": "evoscen/collision", "ids": [11, 12]},
        {"name": "evoscen/collision", "ids": [10, 11]},
        {"name": "evoscen/lane_change", "kind": "completed", "ids": [11]},
        {"name": "evoscen/lane_change", "kind": "completed", "ids": [10]},  # the SUT's: not counted
        {"name": "evoscen/lane_change", "kind": "aborted", "ids": [12]},  # not completed: not counted
    ]
    return RunData(time_s=np.array([0.0, 0.5, 1.0]), columns=base, ids=base["id"][0].astype(np.int64), sut_index=0,
                   events=events, dt_s=0.5)


def test_figures_by_hand():
    f = bv_realism(_run())
    # 3 BVs x 2 steps x 0.5 s = 3 s; (20 + 10 + 25) m/s x 1 s = 55 m
    assert f["bv_vehicle_hours"] == pytest.approx(3.0 / 3600.0)
    assert f["bv_vehicle_km"] == pytest.approx(0.055)
    assert f["bv_bv_collisions"] == 1 and f["sut_collisions"] == 1
    assert f["bv_bv_collisions_per_vehicle_hour"] == pytest.approx(1200.0)
    assert f["bv_lane_changes"] == 1
    assert f["bv_lane_changes_per_vehicle_km"] == pytest.approx(1.0 / 0.055)
    # THW samples: 1.25 and 0.5 at each of the 3 states (BV 13 has no leader)
    assert f["thw_samples"] == 6
    assert f["thw_median_s"] == pytest.approx(0.875)
    assert f["thw_share_below_1s"] == pytest.approx(0.5)
    assert f["thw_share_below_0_5s"] == 0.0  # 0.5 is not below 0.5
    # per type: competitive = BVs 11 + 13, (20 + 25) m/s x 1 s = 45 m, one change (BV 11); cooperative = BV 12, 10 m
    assert f["by_policy"] == {"competitive": {"lane_changes": 1, "vehicle_km": pytest.approx(0.045)},
                              "cooperative": {"lane_changes": 0, "vehicle_km": pytest.approx(0.010)}}
    from evoscen_eval.naturalistic.bv_realism import lane_changes_per_km_by_policy

    assert lane_changes_per_km_by_policy(f) == {"competitive": pytest.approx(1.0 / 0.045), "cooperative": 0.0}
    assert lane_changes_per_km_by_policy(combine([f, f])) == {"competitive": pytest.approx(1.0 / 0.045),
                                                              "cooperative": 0.0}


def test_thw_filters_slow_vehicles_and_far_leaders():
    s = np.array([[0.0, 105.0 + 5.0, 200.0]])
    lane = np.array([[1, 1, 2]])
    speed = np.array([[4.0, 20.0, 20.0]])
    length = np.full((1, 3), 5.0)
    bv = np.array([True, True, True])
    # vehicle 0: 4 m/s < 5 m/s, no sample; vehicle 1 has no leader in lane 1; vehicle 2 none in lane 2
    assert time_headways(s, lane, speed, length, bv).size == 0
    speed[0, 0] = 10.0  # now it counts, but its leader is 105 m away (> 100 m)
    assert time_headways(s, lane, speed, length, bv).size == 0
    s[0, 1] = 105.0  # gap 100 m: within range, THW 100 / 10 = 10 s
    assert time_headways(s, lane, speed, length, bv).tolist() == pytest.approx([10.0])


def test_combine_pools_counts_and_recomputes_rates():
    f = bv_realism(_run())
    c = combine([f, f])
    assert c["runs"] == 2 and c["bv_bv_collisions"] == 2 and c["bv_lane_changes"] == 2
    assert c["bv_bv_collisions_per_vehicle_hour"] == pytest.approx(1200.0)
    assert c["bv_lane_changes_per_vehicle_km"] == pytest.approx(1.0 / 0.055)
    assert c["thw_samples"] == 12 and c["thw_share_below_1s"] == pytest.approx(0.5)


def test_driving_figures_by_hand():
    """SUT 10 (lane 2, s 100); BV 11 (lane 2, s 70, 20 m/s) accel -4, 2, -2, 0; BV 12 (lane 1, s 0, 10 m/s, alone
    in its lane) accel -5, -5, 0, 0; BV 13 on the merge lane (lane 0) at 1 m/s. Four states; the figures use
    states 0-2 (the last stands for no step) and, for flips, the pairs (0, 1), (1, 2), (2, 3)."""
    k, v = 4, 4
    c = {name: np.zeros((k, v)) for name in T.WORLD_FIELDS}
    c["id"][:] = [10, 11, 12, 13]
    c["role"][:] = [1, 0, 0, 0]
    c["s"][:] = [100.0, 70.0, 0.0, 50.0]
    c["lane"][:] = [2, 2, 1, 0]
    c["target_lane"][:] = c["lane"]
    c["speed"][:] = [30.0, 20.0, 10.0, 1.0]
    c["length"][:] = 5.0
    c["accel"][:, 1] = [-4.0, 2.0, -2.0, 0.0]
    c["accel"][:, 2] = [-5.0, -5.0, 0.0, 0.0]
    run = RunData(time_s=np.arange(k) * 0.1, columns=c, ids=c["id"][0].astype(np.int64), sut_index=0, events=[],
                  dt_s=0.1)
    f = bv_realism(run)
    # main line, >= 5 m/s: BVs 11 and 12 at states 0-2 = 6 states (BV 13 is on the merge lane)
    assert f["bv_states"] == 9 and f["main_line_states"] == 6
    # braking < -3: BV 11 at state 0, BV 12 at states 0 and 1
    assert f["hard_braking_share"] == pytest.approx(3 / 6)
    # BV 11 has the SUT 25 m ahead (100 - 70 - 5): not phantom; BV 12 has nobody ahead in lane 1: phantom twice
    assert f["phantom_braking_share"] == pytest.approx(2 / 6)
    # standstill (< 2 m/s): BV 13 on the merge lane, 3 of the 9 BV states
    assert f["standstill_share_merge_lane"] == pytest.approx(3 / 9) and f["standstill_share_main_line"] == 0.0
    # flips: BV 11 -4 -> 2 and 2 -> -2 (|a| > 1 both, signs differ); -2 -> 0 is not; 9 pairs in all
    assert f["flip_pairs"] == 9 and f["accel_flip_share"] == pytest.approx(2 / 9)
    # pooled: counts add, shares weighted by their denominators
    g = combine([f, f])
    assert g["main_line_states"] == 12 and g["phantom_braking_share"] == pytest.approx(2 / 6)
    assert g["accel_flip_share"] == pytest.approx(2 / 9)


def _window_run() -> RunData:
    """A run under the traffic window (traffic.mode: window), by hand: SUT 10, BVs 11, 12, 13; four states
    0.5 s apart, lengths 5 m.

    State 0 -> 1: every vehicle drives (SUT 30, BV 11 20, BV 12 25, BV 13 28 m/s: +15, +10, +12.5, +14 m) and
    the window shifts every vehicle back by 1,700 m (an ``evoscen/shift`` event).
    State 1 -> 2: BV 13 has left the window behind and enters it again at its front edge in lane 4 at
    26 m/s: its s jumps from 114 to 570 m and its lane column from 1 to 4 (an ``evoscen/reentry``
    event, no lane change).
    State 2 -> 3: BV 11 completes a lane change 2 -> 3 (an ``evoscen/lane_change`` completed event)."""
    k, v = 4, 4
    c = {name: np.zeros((k, v)) for name in T.WORLD_FIELDS}
    c["id"][:] = [10, 11, 12, 13]
    c["role"][:] = [1, 0, 0, 0]
    c["policy"][:] = [0, 2, 2, 2]
    c["length"][:] = 5.0
    c["s"][:] = [[1990.0, 1960.0, 2100.0, 1800.0],
                 [305.0, 270.0, 412.5, 114.0],
                 [320.0, 280.0, 425.0, 570.0],
                 [335.0, 290.0, 437.5, 583.0]]
    c["lane"][:] = [[2, 2, 3, 1], [2, 2, 3, 1], [2, 2, 3, 4], [2, 3, 3, 4]]
    c["target_lane"][:] = [[2, 2, 3, 1], [2, 3, 3, 1], [2, 3, 3, 4], [2, 3, 3, 4]]
    c["speed"][:] = [[30.0, 20.0, 25.0, 28.0], [30.0, 20.0, 25.0, 28.0],
                     [30.0, 20.0, 25.0, 26.0], [30.0, 20.0, 25.0, 26.0]]
    events = [
        {"name": "evoscen/shift", "step": 1, "shift_m": 1700.0},
        {"name": "evoscen/reentry", "step": 2, "ids": [13], "to_lane": 4},
        {"name": "evoscen/lane_change", "kind": "completed", "step": 3, "ids": [11], "from_lane": 2, "to_lane": 3},
    ]
    return RunData(time_s=np.arange(k) * 0.5, columns=c, ids=c["id"][0].astype(np.int64), sut_index=0,
                   events=events, dt_s=0.5)


def test_window_shift_and_entry_add_no_distance_and_no_lane_change():
    run = _window_run()
    f = bv_realism(run)
    # vehicle-km = sum over states 0..2 of speed * dt: BV 11 3 x 20, BV 12 3 x 25, BV 13 28 + 28 + 26 = 217 m/s
    # x 0.5 s = 108.5 m; neither the shift (1,700 m back for all) nor BV 13's entry (+456 m) counts
    assert f["bv_vehicle_km"] == pytest.approx(0.1085)
    assert f["bv_vehicle_hours"] == pytest.approx(3 * 3 * 0.5 / 3600.0)
    # what the positions would give instead: |ds| summed (the jumps counted), or the shift undone but the entry not
    s = run.columns["s"][:, 1:]
    assert np.abs(np.diff(s, axis=0)).sum() / 1000.0 > 5.0
    undone = s + np.array([[0.0], [1700.0], [1700.0], [1700.0]])  # the shift undone, the entry kept: +442 m
    assert np.diff(undone, axis=0).sum() / 1000.0 == pytest.approx(0.1085 - 0.014 + 0.456)
    # one lane change (BV 11's completed event); BV 13's entry into lane 4 moves its lane column but is none
    lane_moves = int((np.diff(run.columns["lane"][:, 1:], axis=0) != 0).sum())
    assert lane_moves == 2
    assert f["bv_lane_changes"] == 1
    assert f["bv_lane_changes_per_vehicle_km"] == pytest.approx(1.0 / 0.1085)
    assert f["by_policy"] == {"competitive": {"lane_changes": 1, "vehicle_km": pytest.approx(0.1085)}}
    # THW at each state in its own frame: BV 11 behind the SUT (lane 2) at 25, 30, 35 m / 20 m/s; at state 3 BV 11
    # is in lane 3, 142.5 m behind BV 12 (> 100 m: no sample); BVs 12 and 13 never have a leader in range
    assert f["thw_samples"] == 3
    assert f["thw_median_s"] == pytest.approx(1.5)
    assert f["thw_share_below_1s"] == 0.0
    assert f["bv_bv_collisions"] == 0 and f["sut_collisions"] == 0


def test_window_run_vehicle_km_matches_the_distance_driven():
    """A short in-process run under the window (level-0 BVs, 700 steps: the SUT passes the shift point once):
    vehicle-km (speed * dt) equals the distance the BVs drove along the road, i.e. the steps of the arc
    length with the shift undone and the steps where a BV began a new trip (entries) left out, within 1 %
    (the body's heading and the lateral motion make the two differ a little); and the lane changes are the
    completed events only, fewer than the lane column's changes (entries into other lanes move it too)."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_eval.naturalistic.highd_export import unshifted_s
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.physics.window import new_trips

    cfg = load_scenario_config(None, {"steps": 700, "seed": 7, "bvs.driver": "level0", "traffic.mode": "window",
                                      "bvs.makeup": "uniform"})
    run = run_inprocess(cfg, bag_dir=None, evaluate=True, plots=False, keep_run=True).run
    assert run.events_named("evoscen/shift") and run.events_named("evoscen/reentry")
    f = bv_realism(run)
    c = run.columns
    bv = c["role"][0] == 0
    s = c["s"]
    trips = np.array([new_trips(s[k], s[k + 1], run.dt_s) for k in range(s.shape[0] - 1)])
    driven = np.diff(unshifted_s(s), axis=0)
    km = float(driven[:, bv][~trips[:, bv]].sum()) / 1000.0
    assert f["bv_vehicle_km"] == pytest.approx(km, rel=0.01)
    completed = [e for e in run.events_named("evoscen/lane_change", "completed") if e["ids"][0] != run.ids[0]]
    assert f["bv_lane_changes"] == len(completed)
    moved = (np.diff(c["lane"], axis=0) != 0)[:, bv]
    assert (moved & trips[:, bv]).any()  # some entry put a BV into another lane ...
    assert f["bv_lane_changes"] <= int((moved & ~trips[:, bv]).sum())  # ... and is not counted


def test_realism_table_by_hand():
    """scripts/bv_realism.py's table: a column per profile, highD's figure beside the one row that has one,
    ``-`` beside the others, the social types' lane-change rates from the pooled ``by_policy``."""
    from evoscen_eval.naturalistic.bv_realism import HIGHD_REFERENCE, TABLE_ROWS, realism_table

    pooled = {key: 0.0 for key, _, _ in TABLE_ROWS}
    pooled.update(bv_lane_changes_per_vehicle_km=0.25, bv_bv_collisions=2, sut_collisions=0, thw_median_s=1.5,
                  by_policy={"mutual": {"lane_changes": 3, "vehicle_km": 12.0}})
    lines = realism_table({"driver": pooled, "safety_net": {**pooled, "bv_bv_collisions": 0}}).splitlines()
    width = max(len(label) for _, label, _ in TABLE_ROWS)  # "share braking < -3 m/s2 (main line)"
    assert width == 35 and lines[0] == " " * 35 + f"  {'driver':>12}  {'safety_net':>12}  {'highD':>12}"
    assert lines[1].split() == ["BV", "lane", "changes", "/", "veh-km", "0.250", "0.250",
                                f"{HIGHD_REFERENCE['bv_lane_changes_per_vehicle_km']:.3f}"]
    assert lines[3] == "BV-BV collisions".ljust(35) + f"  {'2':>12}  {'0':>12}  {'-':>12}"
    assert lines[5].split()[-3:] == ["1.50", "1.50", "-"]
    assert lines[len(TABLE_ROWS) + 2].split()[-2:] == ["0.250", "0.250"]  # mutual: 3 / 12 km
    assert lines[len(TABLE_ROWS) + 1].split()[-2:] == ["nan", "nan"]  # no competitive BV
    assert lines[-1].startswith("highD: Krajewski") and len(lines) == len(TABLE_ROWS) + 5
