"""scripts/traffic_makeup.py: its pooled figures by hand (evoscen_eval.naturalistic.makeup; the pieces and lane
changes are evoscen_eval.naturalistic.fidelity_highd's, tested by hand in its own tests), bad input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


def _measures(truck, speed, trip_truck, trip_km, trip_lcs):
    from evoscen_eval.naturalistic.fidelity_highd import Measures

    n, m = len(truck), len(trip_truck)
    nan = np.full(n, np.nan)
    return Measures(truck=np.array(truck, dtype=bool), mean_speed_mps=np.array(speed, dtype=float), min_thw_s=nan,
                    min_dhw_m=nan, min_ttc_s=nan, run=np.zeros(n, dtype=np.int64),
                    trip_truck=np.array(trip_truck, dtype=bool), trip_km=np.array(trip_km, dtype=float),
                    trip_lane_changes=np.array(trip_lcs, dtype=np.int64), trip_run=np.zeros(m, dtype=np.int64),
                    runs=[{"density_veh_per_km_per_lane": 12.0}])


def test_pooled_figures_by_hand():
    """Pieces, speeds and lane changes come from the fidelity measures; the script adds truck shares,
    merges, collisions per vehicle-hour and the BVs near the SUT."""
    from evoscen_eval.naturalistic import makeup as tm

    a = {"measures": _measures([False, False, True], [30.0, 28.0, 22.0], [False, True], [2.0, 1.0], [3, 0]),
         "merges": {"car": 1, "truck": 0}, "bv_bv_collisions": 1, "vehicle_hours": 2.0, "slots": 4,
         "truck_slots": 1, "truck_steps_leftmost_lane": 0, "min_30s_mean_bvs_within_100m": 7.0,
         "mean_bvs_within_100m": 9.0}
    b = {"measures": _measures([False], [32.0], [False], [1.0], [1]),
         "merges": {"car": 0, "truck": 0}, "bv_bv_collisions": 0, "vehicle_hours": 2.0, "slots": 4,
         "truck_slots": 0, "truck_steps_leftmost_lane": 0, "min_30s_mean_bvs_within_100m": 6.5,
         "mean_bvs_within_100m": 8.0}
    f = tm.pooled([a, b])
    assert f["truck_share_of_pieces"] == pytest.approx(1 / 4)
    assert f["truck_share_of_trips"] == pytest.approx(1 / 3)
    assert f["truck_share_of_slots"] == pytest.approx(1 / 8)
    assert f["piece_mean_speed"]["mean"] == pytest.approx(28.0)  # (30 + 28 + 22 + 32) / 4
    assert f["piece_mean_speed"]["sd"] == pytest.approx(np.sqrt((4 + 0 + 36 + 16) / 3))
    assert f["car_piece_mean_speed"]["mean"] == pytest.approx(30.0)
    assert f["truck_piece_mean_speed"] == {"n": 1, "mean": 22.0, "sd": 0.0, "p5": 22.0, "p50": 22.0, "p95": 22.0}
    assert f["lane_changes_per_vehicle_km"] == pytest.approx(4 / 4.0)
    assert f["car_lane_changes_per_vehicle_km"] == pytest.approx(4 / 3.0)
    assert f["truck_lane_changes_per_vehicle_km"] == 0.0
    assert f["mainline_lane_changes_per_vehicle_km"]["car"] == pytest.approx(3 / 3.0)
    assert f["bv_bv_collisions_per_vehicle_hour"] == pytest.approx(1 / 4.0)
    assert f["min_30s_mean_bvs_within_100m"] == 6.5 and f["mean_bvs_within_100m"] == pytest.approx(8.5)


def test_run_figures_by_hand():
    """A run's own figures: merges by class, BV-BV collisions only, slot-hours, a truck's steps in the
    leftmost lane; the BVs near the SUT are the given report's."""
    from types import SimpleNamespace

    from evoscen_eval.naturalistic import makeup as tm

    k, t = 11, np.arange(11.0)
    # columns: SUT (id 0, lane 4), car (id 1: merge lane 0 for t <= 4, then lane 1), truck (id 2, 12 m:
    # lane 2, then the leftmost lane 4 for t >= 7: 4 states)
    lane = np.stack([np.full(k, 4.0), np.where(t <= 4, 0.0, 1.0), np.where(t >= 7, 4.0, 2.0)], axis=1)
    cols = {"id": np.tile([0.0, 1.0, 2.0], (k, 1)), "role": np.tile([1.0, 0.0, 0.0], (k, 1)),
            "length": np.tile([4.5, 4.5, 12.0], (k, 1)), "width": np.tile([1.9, 1.9, 2.5], (k, 1)),
            "s": np.stack([300 + 30 * t, 250 + 25 * t, 200 + 22 * t], axis=1),
            "speed": np.tile([30.0, 25.0, 22.0], (k, 1)), "lane": lane, "d": -(4 - lane) * 3.5 - 1.75}
    for name in ("accel", "heading_rel"):
        cols[name] = np.zeros((k, 3))
    events = [
        {"name": "evoscen/lane_change", "kind": "completed", "ids": [1], "from_lane": 0, "time_s": 5.0},
        {"name": "evoscen/lane_change", "kind": "completed", "ids": [2], "from_lane": 2, "time_s": 7.0},
        {"name": "evoscen/lane_change", "kind": "started", "ids": [1], "from_lane": 0, "time_s": 4.0},
        {"name": "evoscen/collision", "ids": [1, 2], "time_s": 8.0},
        {"name": "evoscen/collision", "ids": [0, 1], "time_s": 9.0},  # the SUT's: not BV-BV
    ]
    run = SimpleNamespace(time_s=t, columns=cols, ids=np.array([0, 1, 2]), sut_index=0, events=events,
                          scenario=None, warnings=[], states=k, dt_s=1.0,
                          events_named=lambda name, kind=None: [e for e in events if e["name"] == name and (
                              kind is None or e.get("kind") == kind)])
    f = tm.figures(run, {"traffic": {"min_window_mean_bvs": 7.0, "mean_bvs": 9.0}})
    assert f["merges"] == {"car": 1, "truck": 0}
    assert f["bv_bv_collisions"] == 1
    assert f["vehicle_hours"] == pytest.approx(2 * 10 * 1.0 / 3600.0)  # two BV slots, ten steps of 1 s
    assert (f["slots"], f["truck_slots"], f["leftmost_lane"], f["truck_steps_leftmost_lane"]) == (2, 1, 4, 4)
    assert (f["min_30s_mean_bvs_within_100m"], f["mean_bvs_within_100m"]) == (7.0, 9.0)
    assert f["measures"].trip_truck.tolist() == [False, True]  # one trip each, classed by length


def test_highd_figures_are_the_shipped_aggregates():
    from evoscen_eval.naturalistic import makeup as tm

    h = tm.highd_figures()
    assert (h["truck_share"], h["car_lane_changes_per_vehicle_km"], h["truck_lane_changes_per_vehicle_km"]) == (
        0.1886, 0.328, 0.151)
    assert (h["mean_speed_mps"], h["car_mean_speed_mps"], h["truck_mean_speed_mps"]) == (29.14, 30.38, 23.84)


@pytest.mark.parametrize("args, fragment", [
    (["--makeup", "cars", "--seeds", "1", "--steps", "5"], "bvs.makeup"),
    (["--steps", "0"], "--steps"),
    (["--bags", "no/such/bag"], "--bags"),
    (["--seeds", "1", "--steps", "5", "--set", "models.learned.policy_dir=no/such/dir"], "policy_dir"),
    # a second --set adds to the first (it replaced it: the bad directory went unnoticed)
    (["--seeds", "1", "--steps", "5", "--set", "models.learned.policy_dir=no/such/dir", "--set",
      "models.highd.truck_share=0.2"], "policy_dir"),
])
def test_bad_input_is_one_line(args, fragment):
    res = subprocess.run([sys.executable, "scripts/traffic_makeup.py", *args], cwd=REPO, capture_output=True,
                         text=True, timeout=300, check=False)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and fragment in lines[0]
