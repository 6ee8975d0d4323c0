"""The HighD loader (evoscen_eval.naturalistic.highd) on small HighD-format files written here.

The fixture recording ``07`` is a 2 + 2-lane HighD road (upper markings 8.51, 12.59,
16.43: upper lanes 2, 3; lower markings 21.00, 24.96, 28.80: lower lanes 5, 6) with four
tracks over four frames:

* track 1, drivingDirection 2 (towards +x), a car 4.5 × 1.8 m at 30 m/s, in lane 6 behind
  track 2 (20 m gap, 25 m/s: TTC 20/5 = 4 s) for frames 1-2, then in lane 5 without a
  preceding vehicle for frames 3-4: a lane change to the left, mandatory;
* track 2, direction 2, lane 6, 25 m/s, no preceding vehicle (dhw = thw = ttc = 0);
* track 3, drivingDirection 1 (towards −x), a 12 m truck in lane 3 at −20 m/s behind
  track 4 (40 m gap) which drives faster (−22 m/s): the gap opens, TTC = 40/(20−22) = −20 s;
* track 4, direction 1, lane 3, −22 m/s, no preceding vehicle.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from evoscen_eval.naturalistic.behaviour import BehaviourConfig, car_following, extract_behaviour, lane_changes
from evoscen_eval.naturalistic.highd import TRACK_COLUMNS, TRACKS_META_COLUMNS, find_recordings, load_recording
from evoscen_sim.errors import InputError

RECORDING_META = (
    "id,frameRate,locationId,speedLimit,month,weekDay,startTime,duration,totalDrivenDistance,totalDrivenTime,"
    "numVehicles,numCars,numTrucks,upperLaneMarkings,lowerLaneMarkings\n"
    "7,25,2,-1.00,09.2017,Tue,08:38,0.16,20.00,0.64,4,3,1,8.51;12.59;16.43,21.00;24.96;28.80\n"
)


def _meta_row(track: int, length: float, width: float, cls: str, direction: int) -> str:
    values = {"id": track, "width": length, "height": width, "initialFrame": 1, "finalFrame": 4, "numFrames": 4,
              "class": cls, "drivingDirection": direction, "traveledDistance": 4.0, "minXVelocity": 0,
              "maxXVelocity": 0, "meanXVelocity": 0, "minDHW": -1, "minTHW": -1, "minTTC": -1, "numLaneChanges": 0}
    return ",".join(str(values[c]) for c in TRACKS_META_COLUMNS)


def _track_rows() -> list[dict]:
    rows = []
    for f in range(1, 5):
        changed = f >= 3
        rows.append({"frame": f, "id": 1, "x": 100.0 + 1.2 * (f - 1), "y": 22.0 if changed else 25.0,
                     "width": 4.5, "height": 1.8, "xVelocity": 30.0,
                     "dhw": 0.0 if changed else 20.0, "thw": 0.0 if changed else 20.0 / 30.0,
                     "ttc": 0.0 if changed else 4.0, "precedingXVelocity": 0.0 if changed else 25.0,
                     "precedingId": 0 if changed else 2, "laneId": 5 if changed else 6})
    for f in range(1, 5):
        rows.append({"frame": f, "id": 2, "x": 124.5 + 1.0 * (f - 1), "y": 25.0, "width": 4.5, "height": 1.8,
                     "xVelocity": 25.0, "followingId": 1 if f <= 2 else 0, "laneId": 6})
    for f in range(1, 5):
        rows.append({"frame": f, "id": 3, "x": 300.0 - 0.8 * (f - 1), "y": 13.0, "width": 12.0, "height": 2.5,
                     "xVelocity": -20.0, "dhw": 40.0, "thw": 2.0, "ttc": -20.0, "precedingXVelocity": -22.0,
                     "precedingId": 4, "laneId": 3})
    for f in range(1, 5):
        rows.append({"frame": f, "id": 4, "x": 252.0 - 0.88 * (f - 1), "y": 13.3, "width": 4.0, "height": 1.9,
                     "xVelocity": -22.0, "followingId": 3, "laneId": 3})
    return rows


def write_fixture(directory: Path, *, recording_meta: str = RECORDING_META, tracks_header: list[str] | None = None,
                  tracks_rows: list[dict] | None = None, edit_line: tuple[int, str, str] | None = None) -> Path:
    """Write recording 07 into ``directory``; ``edit_line = (row_index, column, text)`` corrupts one value."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "07_recordingMeta.csv").write_text(recording_meta)
    meta = [_meta_row(1, 4.5, 1.8, "Car", 2), _meta_row(2, 4.5, 1.8, "Car", 2), _meta_row(3, 12.0, 2.5, "Truck", 1),
            _meta_row(4, 4.0, 1.9, "Car", 1)]
    (directory / "07_tracksMeta.csv").write_text(",".join(TRACKS_META_COLUMNS) + "\n" + "\n".join(meta) + "\n")
    header = list(TRACK_COLUMNS) if tracks_header is None else tracks_header
    lines = [",".join(header)]
    for i, row in enumerate(_track_rows() if tracks_rows is None else tracks_rows):
        cells = [str(row.get(c, 0)) for c in header]
        if edit_line is not None and edit_line[0] == i:
            cells[header.index(edit_line[1])] = edit_line[2]
        lines.append(",".join(cells))
    (directory / "07_tracks.csv").write_text("\n".join(lines) + "\n")
    return directory


@pytest.fixture
def recording(tmp_path: Path):
    return load_recording(write_fixture(tmp_path / "highd"), "07")


def test_meta_and_markings(recording, tmp_path: Path) -> None:
    assert recording.recording_id == 7 and recording.frame_rate_hz == 25.0
    np.testing.assert_allclose(recording.upper_lane_markings, [8.51, 12.59, 16.43])
    np.testing.assert_allclose(recording.lower_lane_markings, [21.00, 24.96, 28.80])
    assert recording.driving_lanes(1).tolist() == [2, 3]
    assert recording.driving_lanes(2).tolist() == [5, 6]
    assert recording.recording_meta["weekDay"] == "Tue"
    assert find_recordings(tmp_path / "highd") == ["07"]
    assert recording.tracks_meta["class"].tolist() == ["Car", "Car", "Truck", "Car"]


def test_both_directions_and_corner_to_centre(recording) -> None:
    t = recording.tracks
    assert t["frame"].dtype == np.int32 and t["laneId"].dtype == np.int32 and t["x"].dtype == np.float64
    assert recording.driving_direction().tolist() == [2] * 8 + [1] * 8
    xc, yc = recording.x_center(), recording.y_center()
    # track 1, frame 1: upper-left corner (100.0, 25.0), length ("width") 4.5, width ("height") 1.8
    assert (xc[0], yc[0]) == pytest.approx((102.25, 25.9))
    # track 3 (direction 1, the truck): corner (300.0, 13.0), 12.0 × 2.5
    assert (xc[8], yc[8]) == pytest.approx((306.0, 14.25))
    # HighD's lane-id rule agrees with the file's laneId for every row (1 + markings above the centre)
    assert recording.lane_id_at(yc).tolist() == t["laneId"].tolist()


def test_no_leader_and_negative_ttc_rows(recording) -> None:
    t = recording.tracks
    no_leader = t["precedingId"] == 0
    assert no_leader.sum() == 10  # track 1 frames 3-4, tracks 2 and 4
    assert np.all(t["dhw"][no_leader] == 0) and np.all(t["ttc"][no_leader] == 0)
    opening = t["id"] == 3
    assert np.all(t["ttc"][opening] == -20.0)
    dhw_speed, thw_speed = car_following(recording)
    # leader rows: track 1 frames 1-2 (20 m, 30 m/s), track 3 frames 1-4 (40 m, |-20| m/s)
    assert sorted(map(tuple, dhw_speed.tolist())) == [(20.0, 30.0)] * 2 + [(40.0, 20.0)] * 4
    assert sorted(map(tuple, np.round(thw_speed, 6).tolist())) == [(0.666667, 30.0)] * 2 + [(2.0, 20.0)] * 4


def test_lane_change_found_and_classified(recording) -> None:
    lc = lane_changes(recording)
    assert lc.track_id.tolist() == [1] and lc.frame.tolist() == [2]
    assert (lc.from_lane[0], lc.to_lane[0]) == (6, 5)
    assert lc.mandatory.tolist() == [True] and lc.ttc_s[0] == pytest.approx(4.0)
    s = extract_behaviour(recording)
    assert s.num_mandatory == 1 and s.num_voluntary == 0
    assert s.mandatory_ttc_s.tolist() == [4.0]


def test_only_requested_columns_are_loaded(tmp_path: Path) -> None:
    rec = load_recording(write_fixture(tmp_path), 7, columns=("xVelocity",))
    assert set(rec.tracks) == {"frame", "id", "xVelocity"}
    full = load_recording(tmp_path, 7, columns=TRACK_COLUMNS)
    assert set(full.tracks) == set(TRACK_COLUMNS)


def test_unsorted_rows_are_sorted(tmp_path: Path) -> None:
    rows = _track_rows()[::-1]
    rec = load_recording(write_fixture(tmp_path, tracks_rows=rows), "07")
    assert rec.tracks["id"].tolist() == [1] * 4 + [2] * 4 + [3] * 4 + [4] * 4
    assert rec.tracks["frame"][:4].tolist() == [1, 2, 3, 4]
    assert lane_changes(rec).frame.tolist() == [2]


# ------------------------------------------------------------------ malformed files


def test_missing_file(tmp_path: Path) -> None:
    write_fixture(tmp_path)
    (tmp_path / "07_tracksMeta.csv").unlink()
    with pytest.raises(InputError, match=r"07_tracksMeta\.csv: file not found"):
        load_recording(tmp_path, "07")
    with pytest.raises(InputError, match=r"99_recordingMeta\.csv: file not found"):
        load_recording(tmp_path, "99")


def test_missing_column(tmp_path: Path) -> None:
    header = [c for c in TRACK_COLUMNS if c != "dhw"]
    write_fixture(tmp_path, tracks_header=header)
    with pytest.raises(InputError, match=r"07_tracks\.csv: missing column 'dhw'"):
        load_recording(tmp_path, "07")
    # a column extraction does not need may be absent
    load_recording(tmp_path, "07", columns=("xVelocity", "laneId"))
    write_fixture(tmp_path, recording_meta=RECORDING_META.replace("lowerLaneMarkings", "lowerMarkings"))
    with pytest.raises(InputError, match=r"07_recordingMeta\.csv: missing column 'lowerLaneMarkings'"):
        load_recording(tmp_path, "07")


def test_non_numeric_value(tmp_path: Path) -> None:
    write_fixture(tmp_path, edit_line=(5, "xVelocity", "fast"))
    # row index 5 is line 7 of the file (after the header)
    with pytest.raises(InputError, match=r"07_tracks\.csv: line 7: column 'xVelocity': 'fast' is not a number"):
        load_recording(tmp_path, "07")


def test_non_integer_id_and_nan(tmp_path: Path) -> None:
    write_fixture(tmp_path, edit_line=(2, "laneId", "5.5"))
    with pytest.raises(InputError, match=r"07_tracks\.csv: line 4: column 'laneId': 5\.5 is not an integer"):
        load_recording(tmp_path, "07")
    write_fixture(tmp_path, edit_line=(0, "dhw", "nan"))
    with pytest.raises(InputError, match=r"07_tracks\.csv: line 2: column 'dhw': 'nan' is not a finite number"):
        load_recording(tmp_path, "07")


def test_bad_meta_values(tmp_path: Path) -> None:
    write_fixture(tmp_path, recording_meta=RECORDING_META.replace("8.51;12.59;16.43", "8.51;x;16.43"))
    with pytest.raises(InputError, match=r"07_recordingMeta\.csv: line 2: column 'upperLaneMarkings': 'x' is not a number"):
        load_recording(tmp_path, "07")
    write_fixture(tmp_path)
    meta = (tmp_path / "07_tracksMeta.csv").read_text().replace(",Truck,1,", ",Truck,3,")
    (tmp_path / "07_tracksMeta.csv").write_text(meta)
    with pytest.raises(InputError, match=r"07_tracksMeta\.csv: line 4: column 'drivingDirection': 3 \(expected 1"):
        load_recording(tmp_path, "07")


def test_track_missing_from_tracks_meta(tmp_path: Path) -> None:
    write_fixture(tmp_path, edit_line=(15, "id", "9"))
    with pytest.raises(InputError, match=r"07_tracks\.csv: line 17: column 'id': track 9 is not in 07_tracksMeta\.csv"):
        load_recording(tmp_path, "07")


def test_ragged_line(tmp_path: Path) -> None:
    write_fixture(tmp_path)
    path = tmp_path / "07_tracks.csv"
    lines = path.read_text().splitlines()
    lines[3] = lines[3] + ",1"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"07_tracks\.csv: line 4 has 26 fields, the header 25"):
        load_recording(tmp_path, "07")


def test_behaviour_config_filters(recording) -> None:
    dhw_speed, _ = car_following(recording, BehaviourConfig(leader_range_m=30.0))
    assert dhw_speed[:, 0].tolist() == [20.0, 20.0]
    dhw_speed, _ = car_following(recording, BehaviourConfig(min_speed_mps=25.0))
    assert dhw_speed[:, 1].tolist() == [30.0, 30.0]
    # a 15 m range makes track 1's leader "none ahead": the change becomes voluntary, sampled by speed
    s = extract_behaviour(recording, BehaviourConfig(leader_range_m=15.0))
    assert s.num_mandatory == 0 and s.voluntary_speed_mps.tolist() == [30.0]
