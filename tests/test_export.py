"""``scripts/export_scenario.py`` and ``run_scenario.py --start-from`` (docs/export.md).

A hand-built start (``START``: the SUT at 30 m/s 22 m behind a 12-m truck at 5 m/s in lane III,
a car in lane V) is run for 30 steps: the SUT cannot stop in the gap, so the run has one collision.
Its bag and the shared recorded run (``recorded_run``: 200 steps, re-entries, no collision) are
exported; the exports are checked by tools evoscen did not write: the ASAM Quality Checker
(``asam-qc-openscenarioxml``), commonroad-io's reader, and shapely's polygons for collisions.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
EXPORT = REPO / "scripts" / "export_scenario.py"

pytestmark = pytest.mark.e2e
for _module in ("scenariogeneration", "qc_openscenario", "commonroad", "shapely"):
    pytest.importorskip(_module, reason=f"the export tools are not installed ({_module}; make setup installs "
                                        "requirements-export.txt)")


def _vehicle(name: str, category: str, length: float, width: float, props: str) -> str:
    return (f'<ScenarioObject name="{name}"><Vehicle name="{name}" vehicleCategory="{category}"><BoundingBox>'
            f'<Center x="0" y="0" z="0.75"/><Dimensions width="{width}" length="{length}" height="1.5"/></BoundingBox>'
            '<Performance maxSpeed="70" maxAcceleration="10" maxDeceleration="10"/><Axles>'
            '<FrontAxle maxSteering="0.5" wheelDiameter="0.8" trackWidth="1.6" positionX="1.5" positionZ="0.4"/>'
            '<RearAxle maxSteering="0" wheelDiameter="0.8" trackWidth="1.6" positionX="-1.5" positionZ="0.4"/>'
            f'</Axles><Properties>{props}</Properties></Vehicle></ScenarioObject>')


def _init(name: str, x: float, y: float, v: float) -> str:
    return (f'<Private entityRef="{name}"><PrivateAction><TeleportAction><Position><WorldPosition x="{x}" y="{y}" '
            'z="0" h="0"/></Position></TeleportAction></PrivateAction><PrivateAction><LongitudinalAction><SpeedAction>'
            '<SpeedActionDynamics dynamicsShape="step" value="0" dynamicsDimension="time"/><SpeedActionTarget>'
            f'<AbsoluteTargetSpeed value="{v}"/></SpeedActionTarget></SpeedAction></LongitudinalAction></PrivateAction>'
            '</Private>')


# On the shipped map the reference line runs along +x from the origin for s < 1000 m and is the
# carriageway's left edge, lanes 3.5 m wide: a point (x, y) there is s = x, d = y; lane III (index 2)
# holds d in [-10.5, -7], its centre -8.75; lane V (index 4) [-3.5, 0], centre -1.75.
START = ('<?xml version="1.0" encoding="utf-8"?>\n<OpenSCENARIO><FileHeader revMajor="1" revMinor="2" '
         'date="2026-01-01T00:00:00" description="hand-built" author="test"/><ParameterDeclarations/><CatalogLocations/>'
         '<RoadNetwork><LogicFile filepath="onramp.xodr"/></RoadNetwork><Entities>'
         + _vehicle("sut", "car", 5.0, 2.0, "")
         + _vehicle("lorry", "truck", 12.0, 2.5, '<Property name="evoscen:id" value="1"/>')
         + _vehicle("car2", "car", 4.5, 1.8, '<Property name="evoscen:id" value="2"/>')
         + '</Entities><Storyboard><Init><Actions>'
         + _init("sut", 300.0, -8.75, 30.0) + _init("lorry", 322.0, -8.75, 5.0) + _init("car2", 340.0, -1.75, 31.5)
         + '</Actions></Init><StopTrigger/></Storyboard></OpenSCENARIO>\n')


@pytest.fixture(scope="module")
def crash(tmp_path_factory, cli):
    """The hand-built start run for 30 steps (seed 0): its output directory."""
    root = tmp_path_factory.mktemp("export")
    (root / "start.xosc").write_text(START, encoding="utf-8")
    res = cli("--start-from", root / "start.xosc", "--steps", 30, "--seed", 0, "--out", root / "run", "--quiet",
              "--no-plots")
    assert res.returncode == 0, res.stderr
    return root / "run"


def test_a_start_from_a_file_has_its_vehicles_classes_positions_and_speeds(crash):
    from evoscen_eval.scoring.rundata import read_run

    run = read_run(crash / "bag")
    c = {f: run.columns[f][0] for f in ("id", "role", "s", "d", "lane", "speed", "length", "width")}
    assert c["id"].tolist() == [0, 1, 2] and c["role"].tolist() == [1, 0, 0]
    np.testing.assert_allclose(c["s"], [300.0, 322.0, 340.0], atol=0.01)
    np.testing.assert_allclose(c["d"], [-8.75, -8.75, -1.75], atol=0.01)
    assert c["lane"].tolist() == [2, 2, 4]
    np.testing.assert_allclose(c["speed"], [30.0, 5.0, 31.5], atol=0.01)
    assert c["length"].tolist() == [5.0, 12.0, 4.5] and c["width"].tolist() == [2.0, 2.5, 1.8]


def test_the_independent_collision_check_agrees_with_evoscens_events(crash, tmp_path):
    from evoscen_eval.scenes import scenario_export as X

    ex = X.load_range(crash / "bag")
    assert [pair for _t, pair in ex.collisions] == [(0, 1)]  # the SUT runs into the truck, once
    assert [t.klass for t in ex.tracks] == ["car", "truck", "car"]
    path = X.write_xosc(ex, tmp_path / "all")
    found = X.box_collisions(X.read_xosc_tracks(path), ex.dt_s)
    assert [pair for _t, pair in found] == [("bv1", "sut")]
    assert abs(found[0][0] - ex.collisions[0][0]) <= 0.1
    assert X.compare_collisions(ex, path)[0]
    # a range that ends before the collision: neither finds one
    t_hit = ex.collisions[0][0]
    before = X.load_range(crash / "bag", 0.0, t_hit - 0.2)
    assert before.collisions == []
    assert X.box_collisions(X.read_xosc_tracks(X.write_xosc(before, tmp_path / "before")), before.dt_s) == []


def test_xosc_passes_the_asam_checker_and_holds_the_recorded_motion(recorded_run, tmp_path, capsys):
    from evoscen_contract import contract as C
    from evoscen_eval.scenes import scenario_export as X
    from evoscen_eval.scoring.rundata import read_run

    t_from, t_to = 2.0, 12.0
    status = _export_main()([str(recorded_run.bag_dir), "--from", str(t_from), "--to", str(t_to), "--format", "xosc",
                             "--out", str(tmp_path), "--check"])
    out = capsys.readouterr().out
    assert status == 0, out
    assert "ASAM quality checker: 0 error(s)" in out
    assert "0 collision(s), evoscen: 0; agree" in out
    run = read_run(recorded_run.bag_dir)
    k0, k1 = int(round(t_from / run.dt_s)), int(round(t_to / run.dt_s))
    tracks = X.read_xosc_tracks(tmp_path / "scenario.xosc")
    assert len(tracks) == len(run.ids) and "sut" in tracks
    # a re-entry in the range is a jump: one more piece (a teleport) for that vehicle
    reentries = [e for e in run.events_named(C.EVENT_REENTRY) if t_from < e["time_s"] <= t_to]
    text = (tmp_path / "scenario.xosc").read_text()
    assert text.count("<TeleportAction>") == len(run.ids) + len(reentries) and reentries
    for v, vid in enumerate(run.ids.tolist()):
        tr = tracks["sut" if v == run.sut_index else f"bv{vid}"]
        t = np.array([s[0] for s in tr.samples])
        assert t[0] == 0.0 and abs(t[-1] - (t_to - t_from)) < 1e-9 and len(t) == k1 - k0 + 1
        np.testing.assert_allclose([s[1] for s in tr.samples], run.columns["x"][k0:k1 + 1, v], atol=1e-6)
        np.testing.assert_allclose([s[2] for s in tr.samples], run.columns["y"][k0:k1 + 1, v], atol=1e-6)
        assert tr.init_speed == pytest.approx(run.columns["speed"][k0, v], abs=1e-9)
    # the checker can fail: an action for an entity the file does not declare is an error
    broken = tmp_path / "broken.xosc"
    broken.write_text(text.replace('entityRef="bv1"', 'entityRef="nobody"', 1))
    assert X.check_xosc(broken)


def test_commonroad_round_trip_keeps_obstacles_time_steps_and_planning_problem(recorded_run, crash, tmp_path):
    """Written and read back with commonroad-io in a process of its own (it needs protobuf's pure-Python
    implementation, chosen before protobuf is first imported: docs/export.md "Packages")."""
    from evoscen_eval.scenes import scenario_export as X

    code = """
import json, sys
from evoscen_eval.scenes import scenario_export as X
X.protobuf_runtime()
from commonroad.common.file_reader import CommonRoadFileReader
out = {}
for tag, bag, t0, t1, d in zip(("run", "crash"), sys.argv[1:3], (2.0, None), (12.0, None), sys.argv[3:5]):
    path = X.write_commonroad(X.load_range(bag, t0, t1), d)
    sc, pps = CommonRoadFileReader(str(path)).open()
    obs = sorted(sc.dynamic_obstacles, key=lambda o: o.obstacle_id)
    pp = next(iter(pps.planning_problem_dict.values()))
    out[tag] = {"ids": [o.obstacle_id for o in obs], "types": [o.obstacle_type.name for o in obs],
                "first": [o.initial_state.time_step for o in obs],
                "last": [o.prediction.final_time_step if o.prediction else o.initial_state.time_step for o in obs],
                "lanelets": len(sc.lanelet_network.lanelets), "dt": sc.dt,
                "start": [float(v) for v in pp.initial_state.position] + [pp.initial_state.velocity],
                "goal_step": [g.time_step.start for g in pp.goal.state_list]}
    ex = X.load_range(bag, t0, t1)
    out[tag]["check"] = X.check_commonroad(ex, path)
    ex.tracks.pop()  # the file now holds an obstacle (or more) that was not exported
    ex.states += 1
    out[tag]["doctored"] = X.check_commonroad(ex, path)[2]
print(json.dumps(out))
"""
    res = subprocess.run([sys.executable, "-c", code, str(recorded_run.bag_dir), str(crash / "bag"),
                          str(tmp_path / "run"), str(tmp_path / "crash")],
                         cwd=REPO, capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stderr
    got = json.loads(res.stdout.strip().splitlines()[-1])
    for tag, bag, t0, t1 in (("run", recorded_run.bag_dir, 2.0, 12.0), ("crash", crash / "bag", None, None)):
        ex = X.load_range(bag, t0, t1)
        bvs = [t for t in ex.tracks if t.role != 1]
        pieces = [(X.obstacle_id(t.vid, n), p) for t in bvs for n, p in enumerate(t.pieces)]
        g = got[tag]
        assert g["ids"] == sorted(i for i, _p in pieces)  # one obstacle per BV piece
        by_id = dict(pieces)
        assert g["first"] == [by_id[i].k0 for i in g["ids"]]
        assert g["last"] == [by_id[i].k0 + by_id[i].steps - 1 for i in g["ids"]]
        assert max(g["last"]) == ex.states - 1 and g["dt"] == pytest.approx(ex.dt_s)
        # lanes II-V in [0, 600], [600, 960], [960, end] and lane I in [600, 960]: 3 * 4 + 1 lanelets
        assert g["lanelets"] == 13
        p = ex.sut.pieces[0]
        np.testing.assert_allclose(g["start"], [p.x[0], p.y[0], p.speed[0]], atol=1e-5)
        assert g["goal_step"] == [p.k0 + p.steps - 1]
        assert g["check"] == [len(pieces), ex.states, []]
        assert [line.split(":")[0] for line in g["doctored"]] == ["obstacles", "time steps"]
    assert got["crash"]["types"] == ["TRUCK", "CAR"]


def test_an_exported_start_restarts_evoscen_in_the_same_state(recorded_run, cli, tmp_path):
    from evoscen_eval.scenes import scenario_export as X
    from evoscen_eval.scoring.rundata import read_run

    t_from = 5.0
    path = X.write_xosc(X.load_range(recorded_run.bag_dir, t_from, t_from + 1.0), tmp_path / "x")
    res = cli("--start-from", path, "--steps", 3, "--seed", recorded_run.seed, "--out", tmp_path / "run", "--quiet",
              "--no-plots")
    assert res.returncode == 0, res.stderr
    a, b = read_run(recorded_run.bag_dir), read_run(tmp_path / "run" / "bag")
    k = int(round(t_from / a.dt_s))
    ia, ib = np.argsort(a.ids), np.argsort(b.ids)
    assert a.ids[ia].tolist() == b.ids[ib].tolist()
    for field, tol in (("x", 0.01), ("y", 0.01), ("s", 0.01), ("speed", 0.01), ("length", 0.0), ("width", 0.0)):
        np.testing.assert_allclose(b.columns[field][0][ib], a.columns[field][k][ia], atol=tol, err_msg=field)
    for field in ("role", "lane"):
        assert b.columns[field][0][ib].tolist() == a.columns[field][k][ia].tolist(), field
    # compare_start (export_scenario.py --compare-start) says the same, and sees a vehicle 2 cm off
    ex = X.load_range(recorded_run.bag_dir, t_from, t_from + 1.0)
    assert X.compare_start(ex, tmp_path / "run" / "bag") == (len(a.ids), [])
    ex.tracks[1].pieces[0].x[0] += 0.02
    ex.tracks[2].pieces[0].speed[0] -= 0.02
    assert X.compare_start(ex, tmp_path / "run" / "bag")[1] == [
        f"vehicle {ex.tracks[1].vid}: position 0.0200 m from the export's",
        f"vehicle {ex.tracks[2].vid}: speed 0.0200 m/s from the export's"]


def _export_main():
    spec = importlib.util.spec_from_file_location("evoscen_export_cli", EXPORT)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(EXPORT.parent))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(EXPORT.parent))
    return module.main


@pytest.mark.parametrize("args, start", [
    (["{bag}", "--from", "5", "--to", "50"], "error: --to: 50 s: expected a time within the bag's states, 0 .. 20 s"),
    (["{bag}", "--from", "-1"], "error: --from: -1 s: expected a time within the bag's states"),
    (["{bag}", "--from", "7", "--to", "7"], "error: --from/--to: 7 .. 7 s holds 1 world state(s)"),
    (["{bag}", "--from", "soon"], "error: --from: 'soon': expected a number (s)"),
    (["{bag}", "--format", "osc"], "error: --format: 'osc': expected one of xosc, commonroad"),
    (["{junk}"], "error: bag "),
    (["{missing}"], "error: "),
    (["{bag}", "--compare-start", "{junk}"], "error: --compare-start: "),
])
def test_bad_input_is_one_error_line_and_status_2(recorded_run, tmp_path, capsys, args, start):
    junk = tmp_path / "junk.mcap"
    junk.write_text("not a bag")
    argv = [a.format(bag=recorded_run.bag_dir, junk=junk, missing=tmp_path / "none") for a in args]
    assert _export_main()([*argv, "--out", str(tmp_path / "out")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith(start), err


def test_a_start_file_that_is_not_a_scenario_is_one_line(tmp_path):
    from evoscen_eval.scenes.scenario_export import initial_state_from_xosc
    from evoscen_sim.errors import InputError
    from evoscen_sim.road.road_model import load_road

    bad = tmp_path / "bad.xosc"
    bad.write_text("<OpenSCENARIO><Entities>")
    with pytest.raises(InputError, match=r"^--start-from .*bad.xosc: not a readable OpenSCENARIO file") as err:
        initial_state_from_xosc(bad, load_road())
    assert "\n" not in str(err.value)
    nosut = tmp_path / "nosut.xosc"
    nosut.write_text(START.replace('name="sut"', 'name="ego"').replace('entityRef="sut"', 'entityRef="ego"'))
    with pytest.raises(InputError, match="expected exactly one SUT"):
        initial_state_from_xosc(nosut, load_road())


def test_a_vehicle_that_jumps_right_after_the_first_state_exports_valid_openscenario(tmp_path):
    """A first piece of a single state (a re-entry at the range's second state) has no trajectory:
    Init places the vehicle, no empty event is written (an Event needs an action), and the box check
    reads its state at t = 0 from Init."""
    from evoscen_contract import contract as C
    from evoscen_eval.scenes import scenario_export as X
    from evoscen_sim.config.scenario_config import share_path

    def piece(k0, x, y, v=10.0):
        n = len(x)
        return X.Piece(k0, np.array(x, float), np.full(n, y), np.zeros(n), np.full(n, v), np.zeros(n))

    # straight stretch of the shipped map: s = x, d = y; lane III centre y = -8.75, lane V -1.75
    sut = X.Track(0, C.ROLE_SUT, 0, 5.0, 2.0, "car", 2, 100.0, -8.75, [piece(0, [100.0, 101.0, 102.0, 103.0], -8.75)])
    bv = X.Track(1, C.ROLE_BV, 0, 4.5, 1.8, "car", 4, 50.0, -1.75,
                 [piece(0, [50.0], -1.75), piece(1, [300.0, 301.0, 302.0], -1.75)])
    ex = X.RangeExport(tmp_path / "bag", 0.0, 0.1, 4, [sut, bv], [], Path(share_path("maps/onramp.xodr")), None)
    path = X.write_xosc(ex, tmp_path)
    text = path.read_text()
    assert text.count('<Event name="bv1_piece') == 1 and 'name="bv1_piece1"' in text
    tracks = X.read_xosc_tracks(path)
    assert [s[:2] for s in tracks["bv1"].samples] == [(0.0, 50.0), (0.1, 300.0), (0.2, 301.0), (0.3, 302.0)]
    assert len(tracks["sut"].samples) == 4  # its vertex at t = 0 is not doubled by the Init pose
    assert X.check_xosc(path) == []


def test_a_campaigns_clips_export_with_a_summary_per_clip_and_a_total(crash, tmp_path):
    """``export_scenario.py CAMPAIGN --format commonroad --check``: each clip read back by commonroad-io
    (one obstacle per BV piece: the truck and the car), its collision found by the box check."""
    import shutil

    from evoscen_eval.scenes import scenario_export as X

    run = tmp_path / "camp" / "runs" / "k1"
    shutil.copytree(crash / "bag", run / "clips" / "001-collision-7" / "bag")
    (run / "clips.json").write_text(json.dumps([{"kind": "collision", "clip": "clips/001-collision-7/bag"}]))
    states = X.load_range(crash / "bag").states
    res = subprocess.run([sys.executable, str(EXPORT), str(tmp_path / "camp"), "--format", "commonroad", "--check"],
                         cwd=REPO, capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stdout + res.stderr
    out = res.stdout
    assert f"2 obstacles (exported 2), {states} time steps (exported {states}); same" in out
    assert (f"runs/k1/clips/001-collision-7: collision, 3 vehicles, {states} states; read back 2/2 obstacles, "
            f"{states}/{states} steps; 1 collision(s) agree;") in out
    assert "1 clip(s) exported (1 collision)" in out and "1 passed, 0 failed; collisions: 1 in 1 clip(s)" in out
