"""Run → HighD conversion (evoscen_eval.naturalistic.highd_export), neighbour relations and lane-change
classification on hand-built traffic.

The hand-built run (dt 0.1 s, 11 states, t = 0 … 1 s; every vehicle 4.8 × 1.9 m, heading
along the road; lanes 3.5 m wide, lane i's centre at d = −(4 − i)·3.5 − 1.75, so HighD
laneId = 12 − i on the virtual road):

* A (id 10) at 30 m/s in lane 2 behind B (id 11, 25 m/s, 30 m ahead at t = 0): it moves to
  lane 3 between t = 0.15 and 0.55 s, crossing the marking d = −7 at t = 0.35 s; the last
  state in lane 2 is t = 0.3 s, where the gap is (137.5 − 2.4) − (109 + 2.4) = 23.7 m and
  the closing speed 5 m/s: a MANDATORY change with TTC 4.74 s.
* C (id 20) alone at 28 m/s (s = 1000 m) moves from lane 1 to lane 0 the same way:
  VOLUNTARY (no one ahead), speed 28.
* D (id 30) at 25 m/s in lane 4 (s = 0) behind E (id 31, 40 m ahead, 30 m/s, faster) moves
  right to lane 3, behind A: VOLUNTARY (the vehicle ahead is faster), speed 25.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from evoscen_eval.naturalistic.behaviour import BehaviourConfig, extract_behaviour, lane_changes
from evoscen_eval.naturalistic.highd import TRACK_COLUMNS, find_neighbours, load_recording, write_recording
from evoscen_eval.naturalistic.highd_export import ExportOptions, VirtualRoad, run_to_highd

DT = 0.1
T = np.arange(11) * DT
LENGTH, WIDTH = 4.8, 1.9


def lane_centre(i: int) -> float:
    return -(4 - i) * 3.5 - 1.75


def lateral_move(from_lane: int, to_lane: int) -> np.ndarray:
    """d(t): from one lane centre to the other, linearly over t = 0.15 … 0.55 s."""
    a, b = lane_centre(from_lane), lane_centre(to_lane)
    return a + (b - a) * np.clip((T - 0.15) / 0.4, 0.0, 1.0)


def make_run(vehicles: list[dict]) -> SimpleNamespace:
    """A RunData-shaped run from per-vehicle dicts (id, s(t), d(t), speed, role)."""
    k, v = len(T), len(vehicles)
    cols = {name: np.zeros((k, v)) for name in ("id", "role", "s", "d", "speed", "accel", "heading_rel",
                                                  "length", "width", "lane")}
    for j, veh in enumerate(vehicles):
        cols["id"][:, j] = veh["id"]
        cols["role"][:, j] = veh.get("role", 0)
        cols["s"][:, j] = veh["s"]
        cols["d"][:, j] = veh["d"]
        cols["speed"][:, j] = veh["speed"]
        cols["length"][:, j] = LENGTH
        cols["width"][:, j] = WIDTH
    return SimpleNamespace(time_s=T.copy(), columns=cols, ids=np.array([veh["id"] for veh in vehicles]),
                           sut_index=0, warnings=[])


def three_situations() -> SimpleNamespace:
    return make_run([
        {"id": 10, "s": 100 + 30 * T, "d": lateral_move(2, 3), "speed": 30.0, "role": 1},
        {"id": 11, "s": 130 + 25 * T, "d": np.full_like(T, lane_centre(2)), "speed": 25.0},
        {"id": 20, "s": 1000 + 28 * T, "d": lateral_move(1, 0), "speed": 28.0},
        {"id": 30, "s": 0 + 25 * T, "d": lateral_move(4, 3), "speed": 25.0},
        {"id": 31, "s": 40 + 30 * T, "d": np.full_like(T, lane_centre(4)), "speed": 30.0},
    ])


def rows_of(rec, vehicle_id: int) -> np.ndarray:
    tracks = rec.tracks_meta["id"][rec.tracks_meta["evoscenVehicleId"] == vehicle_id]
    return np.flatnonzero(np.isin(rec.tracks["id"], tracks))


def test_native_rate_values_by_hand() -> None:
    rec = run_to_highd(three_situations(), ExportOptions(frame_rate_hz=None))
    t = rec.tracks
    assert rec.frame_rate_hz == pytest.approx(10.0)
    a, b = rows_of(rec, 10), rows_of(rec, 11)
    assert t["frame"][a].tolist() == list(range(1, 12))
    # corner = centre − (length, width)/2; y = y_top − d with y_top = 2 + 5·3.5 + 2 = 21.5
    assert t["x"][a[0]] == pytest.approx(100 - 2.4)
    assert t["y"][a[0]] == pytest.approx(21.5 + 8.75 - 0.95)
    assert (t["width"][a[0]], t["height"][a[0]]) == (LENGTH, WIDTH)
    assert t["laneId"][a].tolist() == [10] * 4 + [9] * 7
    assert VirtualRoad().lane_id(np.array([4, 2, 0])).tolist() == [8, 10, 12]
    assert t["laneId"][b].tolist() == [10] * 11
    # t = 0: gap 130 − 2.4 − 102.4 = 25.2 m, THW 25.2/30 = 0.84 s, TTC 25.2/5 = 5.04 s
    assert t["precedingId"][a[0]] == t["id"][b[0]]
    assert (t["dhw"][a[0]], t["thw"][a[0]], t["ttc"][a[0]]) == pytest.approx((25.2, 0.84, 5.04))
    assert t["precedingXVelocity"][a[0]] == 25.0
    assert t["followingId"][b[0]] == t["id"][a[0]]
    # once A is in lane 3 it has no preceding vehicle: HighD's zeros; B has none at all
    assert t["precedingId"][a[5]] == 0 and t["dhw"][a[5]] == 0 and t["ttc"][a[5]] == 0
    assert np.all(t["dhw"][b] == 0)
    # E (faster, ahead of D): the gap opens, TTC negative: (40 − 2.4 − 2.4)/(25 − 30) = −7.04 s
    d = rows_of(rec, 30)
    assert t["ttc"][d[0]] == pytest.approx(-7.04)
    # the SUT is marked; every track is a car driving towards +x
    assert rec.tracks_meta["evoscenRole"].tolist() == [1, 0, 0, 0, 0]
    assert set(rec.tracks_meta["drivingDirection"]) == {2} and set(rec.tracks_meta["class"]) == {"Car"}
    assert rec.tracks_meta["numLaneChanges"].tolist() == [1, 0, 1, 1, 0]


def test_lane_change_classification() -> None:
    rec = run_to_highd(three_situations(), ExportOptions(frame_rate_hz=None))
    lc = lane_changes(rec, BehaviourConfig(include_sut=True))
    vehicles = rec.tracks_meta["evoscenVehicleId"][lc.track_id - 1]
    assert vehicles.tolist() == [10, 20, 30]
    assert lc.frame.tolist() == [4, 4, 4]  # t = 0.3 s, the last state in the original lane
    assert lc.mandatory.tolist() == [True, False, False]  # slower leader / no leader / faster leader
    assert lc.ttc_s[0] == pytest.approx(23.7 / 5.0)
    assert lc.speed_mps.tolist() == pytest.approx([30.0, 28.0, 25.0])
    assert (lc.from_lane.tolist(), lc.to_lane.tolist()) == ([10, 11, 8], [9, 12, 9])
    # the SUT (A) is left out by default: docs/method.md §5.3 compares background vehicles
    s = extract_behaviour(rec)
    assert s.num_mandatory == 0 and sorted(s.voluntary_speed_mps.tolist()) == pytest.approx([25.0, 28.0])
    s = extract_behaviour(rec, BehaviourConfig(include_sut=True))
    assert s.mandatory_ttc_s.tolist() == pytest.approx([4.74])


def test_resampled_to_25_hz() -> None:
    rec = run_to_highd(three_situations(), ExportOptions(frame_rate_hz=25.0))
    t = rec.tracks
    a = rows_of(rec, 10)
    assert t["frame"][a].tolist() == list(range(1, 27))  # 0 … 1 s at 25 Hz
    centre = t["x"][a] + 0.5 * t["width"][a]
    np.testing.assert_allclose(centre, 100 + 30 * np.arange(26) / 25.0, atol=1e-9)
    # linear interpolation of d: the marking d = −7 is crossed at t = 0.35 s (frame 9.75): last old frame 9 (0.32 s)
    lc = lane_changes(rec, BehaviourConfig(include_sut=True))
    assert lc.frame.tolist() == [9, 9, 9]
    assert lc.ttc_s[0] == pytest.approx(((130 + 25 * 0.32 - 2.4) - (100 + 30 * 0.32 + 2.4)) / 5.0)
    assert rec.recording_meta["frameRate"] == "25" and rec.recording_meta["numVehicles"] == "5"


def test_reentry_starts_a_new_track() -> None:
    s = 2380.0 + 30 * T
    s[6:] -= 2393.76  # passes the end after t = 0.5 s and re-enters upstream
    run = make_run([{"id": 7, "s": s, "d": np.full_like(T, lane_centre(3)), "speed": 30.0}])
    rec = run_to_highd(run, ExportOptions(frame_rate_hz=None))
    assert rec.tracks_meta["id"].tolist() == [1, 2]
    assert rec.tracks_meta["evoscenVehicleId"].tolist() == [7, 7]
    assert rec.tracks_meta["initialFrame"].tolist() == [1, 7]
    assert rec.tracks_meta["finalFrame"].tolist() == [6, 11]
    # resampling never interpolates across the jump: every 25 Hz x lies on one of the two lines
    rec25 = run_to_highd(run, ExportOptions(frame_rate_hz=25.0))
    xc = rec25.tracks["x"] + 0.5 * rec25.tracks["width"]
    tf = (rec25.tracks["frame"] - 1) / 25.0
    on_line = np.isclose(xc, 2380 + 30 * tf) | np.isclose(xc, 2380 + 30 * tf - 2393.76)
    assert on_line.all()
    assert rec25.tracks_meta["finalFrame"][0] == 13 and rec25.tracks_meta["initialFrame"][1] == 16  # 0.48 s, 0.6 s


def test_write_and_load_back_every_column(tmp_path: Path) -> None:
    rec = run_to_highd(three_situations())
    write_recording(tmp_path, rec)
    back = load_recording(tmp_path, 1, columns=TRACK_COLUMNS)
    for c in TRACK_COLUMNS:
        np.testing.assert_allclose(back.tracks[c], rec.tracks[c], atol=6e-4, err_msg=c)
    for c in ("id", "initialFrame", "finalFrame", "drivingDirection", "evoscenVehicleId", "evoscenRole"):
        assert back.tracks_meta[c].tolist() == rec.tracks_meta[c].tolist()
    np.testing.assert_allclose(back.lower_lane_markings, VirtualRoad().lower_markings())
    with pytest.raises(Exception, match="already exists"):
        write_recording(tmp_path, rec)


def test_neighbours_in_both_directions() -> None:
    # direction 2 (towards +x): ego row 0 in lane 9 at x = 100 (4 m long: 98 … 102);
    # lane 8 is its LEFT: 101 overlaps (alongside), 130 ahead, 70 behind;
    # lane 10 its right: 97 overlaps (alongside, 95 … 99), 50 behind; a row in another frame is ignored
    frame = np.array([1, 1, 1, 1, 1, 1, 2])
    lane = np.array([9, 8, 8, 8, 10, 10, 9])
    x = np.array([100.0, 101.0, 130.0, 70.0, 97.0, 50.0, 120.0])
    length = np.full(7, 4.0)
    nb = find_neighbours(frame, lane, x, length, np.full(7, 2))
    got = (nb.left_preceding[0], nb.left_alongside[0], nb.left_following[0],
           nb.right_preceding[0], nb.right_alongside[0], nb.right_following[0], nb.preceding[0], nb.following[0])
    assert got == (2, 1, 3, -1, 4, 5, -1, -1)
    # direction 1 (towards −x): the same layout mirrored in x; "ahead" is −x and left is laneId + 1
    nb = find_neighbours(frame, 18 - lane, -x, length, np.full(7, 1))
    got = (nb.left_preceding[0], nb.left_alongside[0], nb.left_following[0],
           nb.right_preceding[0], nb.right_alongside[0], nb.right_following[0])
    assert got == (2, 1, 3, -1, 4, 5)
    # same lane: preceding / following by centre
    nb = find_neighbours(np.ones(3, int), np.full(3, 5), np.array([10.0, 50.0, 30.0]), np.full(3, 4.0), np.full(3, 2))
    assert nb.preceding.tolist() == [2, -1, 1] and nb.following.tolist() == [-1, 2, 0]


def test_unshifted_s_undoes_the_exact_shift_of_the_events() -> None:
    from evoscen_eval.naturalistic.highd_export import unshifted_s

    s = np.array([[1990.0, 2000.0, 2100.0], [1993.0, 2002.5 - 1700.0, 2103.0 - 1700.0]])
    s[1, 0] -= 1700.0
    np.testing.assert_allclose(unshifted_s(s, {1: 1700.0}), [[1990.0, 2000.0, 2100.0], [1993.0, 2002.5, 2103.0]])
    # without the events: the median step (here 3 m of driving + the shift) is taken for the shift
    np.testing.assert_allclose(unshifted_s(s)[1], [1990.0, 1999.5, 2100.0])
