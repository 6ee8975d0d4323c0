"""Round trip: a recorded run, exported to HighD format and loaded back, gives the samples of
the bag read directly (within the 25 Hz resampling), so JS(bag ‖ its own export) ≈ 0; and the
two scripts (export_highd.py, experiment_fidelity.py) end to end.

One in-process run (400 steps, seed 5, MOBIL driving the BVs so that lane changes happen)
is recorded once for the module.
"""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from evoscen_eval.naturalistic.behaviour import BehaviourConfig, extract_behaviour, lane_changes
from evoscen_eval.naturalistic.fidelity import run_recording
from evoscen_eval.naturalistic.highd import load_recording, write_recording
from evoscen_eval.naturalistic.highd_export import ExportOptions, VirtualRoad
from evoscen_eval.scoring.rundata import read_run
from evoscen_eval.naturalistic.similarity import compare

REPO = Path(__file__).resolve().parents[4]
STEPS = 400


@pytest.fixture(scope="module")
def bag(tmp_path_factory) -> Path:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config

    bag_dir = tmp_path_factory.mktemp("fidelity") / "bag"
    cfg = load_scenario_config(None, {"steps": STEPS, "seed": 5, "bvs.driver": "mobil"})
    run_inprocess(cfg, bag_dir=bag_dir)
    return bag_dir


@pytest.fixture(scope="module")
def direct(bag):
    """The bag read directly: one HighD frame per recorded world state (10 Hz)."""
    return run_recording(bag)


@pytest.fixture(scope="module")
def exported(bag, tmp_path_factory):
    """The bag exported at 25 Hz, written as HighD files and loaded back."""
    out = tmp_path_factory.mktemp("export")
    write_recording(out, run_recording(bag, ExportOptions(frame_rate_hz=25.0, recording_id=4)))
    return load_recording(out, "04")


def script(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *map(str, args)], cwd=REPO, capture_output=True, text=True, timeout=180,
                          check=False)


def test_direct_rows_are_the_recorded_states(bag, direct) -> None:
    run = read_run(bag)
    assert direct.warnings == [] and direct.frame_rate_hz == pytest.approx(10.0)
    # every vehicle-state of the run is one row (split into tracks at re-entries)
    assert direct.num_rows == run.states * len(run.ids)
    t = direct.tracks
    vid = direct.row_meta("evoscenVehicleId")
    col = np.searchsorted(run.ids, vid)
    k = t["frame"] - 1
    np.testing.assert_allclose(t["x"] + 0.5 * t["width"], run.columns["s"][k, col])
    np.testing.assert_allclose(t["xVelocity"], run.columns["speed"][k, col] * np.cos(run.columns["heading_rel"][k, col]))
    # HighD's positional laneId is the simulator's lane column (virtual road: laneId = 12 - lane)
    assert np.array_equal(t["laneId"], VirtualRoad().lane_id(run.columns["lane"][k, col]))
    # the SUT's tracks are marked
    assert set(vid[direct.row_meta("evoscenRole") == 1]) == {int(run.ids[run.sut_index])}


def test_export_gives_the_same_lane_changes(direct, exported) -> None:
    cfg = BehaviourConfig(include_sut=True)
    a, b = lane_changes(direct, cfg), lane_changes(exported, cfg)
    assert len(a.frame) >= 5  # the run has lane changes to compare
    va = direct.tracks_meta["evoscenVehicleId"][a.track_id - 1]
    vb = exported.tracks_meta["evoscenVehicleId"][b.track_id - 1]
    assert sorted(va.tolist()) == sorted(vb.tolist())
    ta, tb = (a.frame - 1) / 10.0, (b.frame - 1) / 25.0
    oa, ob = np.lexsort((ta, va)), np.lexsort((tb, vb))
    # the moment (last frame in the old lane) agrees within one 10 Hz state
    assert np.all(np.abs(ta[oa] - tb[ob]) <= 0.1 + 1e-9)
    np.testing.assert_allclose(a.speed_mps[oa], b.speed_mps[ob], atol=0.5)
    assert np.array_equal(a.from_lane[oa], b.from_lane[ob]) and np.array_equal(a.to_lane[oa], b.to_lane[ob])


def test_js_of_bag_and_its_export_is_zero(direct, exported) -> None:
    a, b = extract_behaviour(direct), extract_behaviour(exported)
    # 25 Hz vs 10 Hz: 2.5 times the car-following samples, within the resampling (tracks' ends)
    assert len(b.dhw_speed) / len(a.dhw_speed) == pytest.approx(2.5, rel=0.03)
    for x, y in ((a.dhw_speed, b.dhw_speed), (a.thw_speed, b.thw_speed)):
        assert compare(x, y).js < 1e-3
    assert a.num_mandatory + a.num_voluntary == b.num_mandatory + b.num_voluntary
    assert compare(a.voluntary_speed_mps, b.voluntary_speed_mps).js < 5e-3
    # a genuinely different sample set is far from 0 (the test can fail): THW against DHW-scaled speed
    assert compare(a.dhw_speed, b.dhw_speed * [1.3, 1.0]).js > 0.05


@pytest.mark.e2e  # runs a CLI as a subprocess
def test_export_script_and_experiment_end_to_end(bag, tmp_path) -> None:
    out = tmp_path / "highd"
    r = script("scripts/export_highd.py", bag, out, "--recording-id", "7")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["07_recordingMeta.csv", "07_tracks.csv", "07_tracksMeta.csv"]
    assert "tracks" in r.stdout and "25 Hz" in r.stdout
    r = script("scripts/export_highd.py", bag, out, "--recording-id", "7")
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [f"error: {out / '07_recordingMeta.csv'}: already "
                                                                   "exists (choose another directory or recording id, "
                                                                   "or overwrite)"]
    res = tmp_path / "fidelity"
    r = script("scripts/experiment_fidelity.py", "--highd", out, "--recordings", "07", "--bags", bag.parent, "--out", res)
    assert r.returncode == 0, r.stderr
    rows = {row["distribution"]: row for row in csv.DictReader(open(res / "fidelity.csv", encoding="utf-8"))}  # noqa: SIM115
    assert list(rows) == ["dhw_speed", "thw_speed", "mandatory_ttc", "voluntary_speed"]
    for key in ("dhw_speed", "thw_speed", "voluntary_speed"):
        assert float(rows[key]["js"]) < 5e-3 and float(rows[key]["similarity_pct"]) > 99.5
    assert sorted(p.name for p in res.glob("*.png")) == ["dhw_speed.png", "mandatory_ttc.png", "thw_speed.png",
                                                         "voluntary_speed.png"]
    assert "| Car following: DHW and speed |" in r.stdout


@pytest.mark.e2e  # runs a CLI as a subprocess
def test_script_errors() -> None:
    r = script("scripts/experiment_fidelity.py", "--bags", "somewhere")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --highd DIR is required") and "highd-dataset.com" in lines[0]
    r = script("scripts/export_highd.py", "no/such/bag", "out")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "no/such/bag" in r.stderr
    r = script("scripts/export_highd.py", "no/such/bag", "out", "--frame-rate", "fast")
    assert r.returncode == 2 and r.stderr.startswith("error: --frame-rate 'fast'")


@pytest.mark.e2e  # runs a CLI as a subprocess
def test_bench_script_small() -> None:
    """scripts/bench_fidelity.py at a small size: generates, writes, loads and extracts in a child process."""
    r = script("scripts/bench_fidelity.py", "--vehicles", "40", "--frames", "3000", "--rows", "20000", "--seed", "1")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("synthetic HighD recording: 20000 rows, 40 tracks")
    assert "car-following rows" in r.stdout and r.stdout.strip().endswith("PASS")
