"""``export_scenario.py --event N --around S``, the traffic window's shift in an exported range, a
damaged bag's warning and what the exported files declare (docs/export.md).

The range arithmetic is checked on hand-made events and shifts; the end-to-end tests export a recorded
run of 800 steps (SUT mobil, seed 3) whose window shifts once (at about 58 s) and whose scoring thresholds
are loosened (TTC 4 s, braking 1 m/s²) so that exposures fall a few seconds after that shift.
"""

from __future__ import annotations

import importlib.util
import json
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EXPORT = REPO / "scripts" / "export_scenario.py"
SCENARIO = "steps: 800\nsut: {model: mobil}\nevaluation: {ttc_threshold_s: 4.0, hard_brake_mps2: 1.0}\n"
RANGE = re.compile(r"\(t = ([0-9.]+) \.\. ([0-9.]+) s, dt")


def _event(first, last, anchor, kind="exposure", n=1):
    from evoscen_eval.scenes.event_ranges import CriticalEvent

    return CriticalEvent(n, kind, n, first, last, anchor)


# ------------------------------------------------------------------------------------------ the range


def test_a_range_without_a_shift_is_the_event_with_its_seconds_either_side():
    from evoscen_eval.scenes.event_ranges import event_range

    assert event_range(_event(20.0, 20.4, 20.2), 5.0, (0.0, 100.0), [(60.0, 1700.0)], 0.1) == (15.0, 25.4, None)
    # clipped to the bag's states
    assert event_range(_event(2.0, 2.0, 2.0, "collision"), 5.0, (0.0, 6.0), [], 0.1) == (0.0, 6.0, None)


def test_a_range_that_would_hold_a_shift_moves_to_the_events_side():
    from evoscen_eval.scenes.event_ranges import event_range

    # the shift led to the state at 22.0 s (its last state before: 21.9 s); the event lies before it:
    # 15.0 .. 25.4 s (10.4 s) ends at 21.9 s instead and begins 10.4 s earlier, 11.5 s
    lo, hi, note = event_range(_event(20.0, 20.4, 20.2), 5.0, (0.0, 100.0), [(22.0, 1700.0)], 0.1)
    assert (lo, hi) == (11.5, 21.9)
    assert note == ("exposure 1 (t = 20.0 .. 20.4 s): 15.0 .. 25.4 s would hold the shift at t = 22.0 s (every "
                    "vehicle moved back 1700 m); exporting 11.5 .. 21.9 s, before it")
    # the event lies after a shift at 18.0 s: the range begins there, 10.4 s long
    lo, hi, note = event_range(_event(20.0, 20.4, 20.2), 5.0, (0.0, 100.0), [(18.0, 1700.0)], 0.1)
    assert (lo, hi) == (18.0, 28.4) and note.endswith("exporting 18.0 .. 28.4 s, after it")
    # shifts on both sides 6 s apart: the range is what lies between them
    lo, hi, _ = event_range(_event(20.0, 20.4, 20.2), 5.0, (0.0, 100.0), [(18.0, 1700.0), (24.0, 1700.0)], 0.1)
    assert (lo, hi) == (18.0, 23.9)
    # a range that begins at the state the shift led to holds no shift
    assert event_range(_event(23.0, 23.0, 23.0), 5.0, (18.0, 40.0), [(18.0, 1700.0)], 0.1) == (18.0, 28.0, None)


def test_an_event_across_a_shift_keeps_the_side_of_its_worst_state():
    from evoscen_eval.scenes.event_ranges import event_range

    lo, hi, note = event_range(_event(21.5, 22.5, 22.3), 5.0, (0.0, 100.0), [(22.0, 1700.0)], 0.1)
    assert (lo, hi) == (22.0, 33.0)
    assert note.endswith("after it; the exposure itself crosses the shift: the range holds its part after it")


def test_a_range_holding_a_shift_is_warned_about_with_its_time():
    from evoscen_eval.scenes.event_ranges import shift_warning

    assert shift_warning(50.0, 60.0, [(40.0, 1700.0), (60.1, 1700.0)]) is None
    assert shift_warning(53.0, 60.0, [(53.0, 1700.0)]) is None  # from the state after it
    text = shift_warning(50.0, 60.0, [(53.0, 1700.0)])
    assert text.startswith("the range 50.0 .. 60.0 s holds the traffic window's shift at t = 53.0 s (every vehicle "
                           "moved back 1700 m)")


def test_event_numbers_count_collisions_then_exposures():
    from evoscen_eval.scenes.event_ranges import CriticalEvent, pick_event
    from evoscen_sim.errors import InputError

    events = [CriticalEvent(1, "collision", 1, 5.0, 5.0, 5.0), CriticalEvent(2, "exposure", 1, 2.0, 2.5, 2.2)]
    assert pick_event(events, "2") is events[1] and pick_event(events, "exposure:1") is events[1]
    assert pick_event(events, "collision:1") is events[0]
    with pytest.raises(InputError, match=r"^--event 3: the run has 1 collision\(s\) and 1 exposure\(s\) of the SUT: "
                                         r"expected events 1 \.\. 2$"):
        pick_event(events, "3")
    with pytest.raises(InputError, match=r"^--event: '0': expected a number N >= 1"):
        pick_event(events, "0")
    with pytest.raises(InputError, match=r"^--event collision:1: the run has 0 collision\(s\) and 0 exposure"):
        pick_event([], "collision:1")


# ------------------------------------------------------------------------------------------ end to end


def _export_main():
    spec = importlib.util.spec_from_file_location("evoscen_export_cli_events", EXPORT)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(EXPORT.parent))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(EXPORT.parent))
    return module.main


@pytest.fixture(scope="module")
def shifted(tmp_path_factory, cli):
    """The run described in the module docstring: its output directory."""
    pytest.importorskip("scenariogeneration")
    root = tmp_path_factory.mktemp("shifted")
    (root / "scenario.yaml").write_text(SCENARIO, encoding="utf-8")
    res = cli("--config", root / "scenario.yaml", "--seed", 3, "--out", root / "run", "--quiet", "--no-plots",
              timeout=300)
    assert res.returncode == 0, res.stderr
    return root / "run"


def _facts(run: Path):
    """The run's shifts (time of the state after each) and exposures (first, last state time) from its
    bag's events and its report.json, dt."""
    from evoscen_eval.scoring.rundata import read_run

    data = read_run(run / "bag")
    report = json.loads((run / "report" / "report.json").read_text())
    dt = float(report["run"]["dt_s"])
    shifts = [float(e["time_s"]) for e in data.events if e["name"] == "evoscen/shift"]
    exposures = [(x["start_state"] * dt, (x["end_state"] - 1) * dt) for x in report["safety"]["exposure_list"]]
    return shifts, exposures, report, dt


@pytest.mark.e2e
def test_a_range_by_hand_that_holds_the_shift_warns_naming_its_time(shifted, tmp_path, capsys):
    shifts, _exposures, _report, _dt = _facts(shifted)
    assert len(shifts) == 1, shifts
    t = shifts[0]
    assert _export_main()([str(shifted / "bag"), "--from", f"{t - 3:.1f}", "--to", f"{t + 3:.1f}",
                           "--out", str(tmp_path / "x")]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and f"holds the traffic window's shift at t = {t:.1f} s" in warnings[0], warnings


@pytest.mark.e2e
def test_an_event_range_holds_its_exposure_and_no_shift(shifted, tmp_path, capsys):
    shifts, exposures, _report, dt = _facts(shifted)
    assert exposures, "the run was chosen for its exposures"
    moved = 0
    for n, (first, last) in enumerate(exposures, 1):
        assert _export_main()([str(shifted / "bag"), "--event", str(n), "--out", str(tmp_path / f"e{n}")]) == 0
        out, err = capsys.readouterr()
        lo, hi = (float(v) for v in RANGE.search(out).groups())
        assert lo <= first + 1e-6 and last <= hi + 1e-6, (n, lo, hi, first, last)
        assert not [s for s in shifts if lo + 1e-6 < s <= hi + 1e-6], (n, lo, hi, shifts)
        assert "warning" not in err
        naive = (first - 5.0, last + 5.0)
        if any(naive[0] < s <= naive[1] for s in shifts):  # 5 s either side would have held the shift
            moved += 1
            assert f"would hold the shift at t = {shifts[0]:.1f} s" in out
            assert hi - lo == pytest.approx(naive[1] - naive[0], abs=dt / 2)  # moved, not cut
    assert moved, "the run was chosen for an exposure within 5 s of its shift"


@pytest.mark.e2e
def test_the_xosc_declares_the_runs_limits_classes_and_policy_names(shifted, tmp_path, capsys):
    from evoscen_bv.truck import TruckParams
    from evoscen_contract.contract import POLICY_NAMES
    from evoscen_eval.scenes.scenario_export import initial_state_from_xosc
    from evoscen_eval.scoring.rundata import read_run
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.road.road_model import load_road

    assert _export_main()([str(shifted / "bag"), "--event", "1", "--out", str(tmp_path / "x")]) == 0
    capsys.readouterr()
    vehicle, truck = load_scenario_config().vehicle, TruckParams()  # the run changed neither
    car = (vehicle.max_speed_mps, vehicle.max_accel_mps2, vehicle.max_brake_mps2)
    lorry = (vehicle.max_speed_mps, min(vehicle.max_accel_mps2, truck.accel_mps2),
             min(vehicle.max_brake_mps2, truck.max_decel_mps2))
    assert car == (40.0, 3.0, 8.0) and lorry == (40.0, 1.0, 5.0)
    data = read_run(shifted / "bag")
    policy = {int(i): int(p) for i, p in zip(data.ids, data.columns["policy"][0])}
    root = ET.parse(tmp_path / "x" / "scenario.xosc").getroot()
    classes = []
    for obj in root.iter("ScenarioObject"):
        veh = obj.find("Vehicle")
        perf = veh.find("Performance")
        got = tuple(float(perf.get(k)) for k in ("maxSpeed", "maxAcceleration", "maxDeceleration"))
        props = {p.get("name"): p.get("value") for p in veh.iter("Property")}
        klass = veh.get("vehicleCategory")
        classes.append(klass)
        assert veh.get("name") == klass == props["evoscen:class"]
        assert got == (lorry if klass == "truck" else car), obj.get("name")
        front, rear = veh.find("Axles/FrontAxle"), veh.find("Axles/RearAxle")
        assert float(front.get("positionX")) - float(rear.get("positionX")) == pytest.approx(vehicle.wheelbase_m)
        assert float(front.get("maxSteering")) == vehicle.max_steer_rad
        assert props["evoscen:policy"] == POLICY_NAMES[policy[int(props["evoscen:id"])]]
    assert "truck" in classes and "car" in classes
    # a start from the file reads the names back as the policy codes
    start = initial_state_from_xosc(tmp_path / "x" / "scenario.xosc", load_road())
    assert start.policies.tolist() == [policy[int(i)] for i in start.ids]


@pytest.mark.e2e
def test_a_checked_export_leaves_only_its_files_and_commonroad_reads_it_back(shifted, tmp_path, capsys):
    _shifts, exposures, _report, dt = _facts(shifted)
    printed = ""
    for fmt, files in (("commonroad", ["scenario.xml"]), ("xosc", ["onramp.xodr", "scenario.xosc"])):
        # as a person runs it, in a process of its own: the suite's process has protobuf loaded already
        res = subprocess.run([sys.executable, str(REPO / "scripts" / "export_scenario.py"), str(shifted / "bag"),
                              "--event", "1", "--format", fmt, "--check", "--out", str(tmp_path / fmt)],
                             cwd=REPO, capture_output=True, text=True, timeout=300, check=False)
        assert res.returncode == 0, res.stderr
        printed += res.stdout
        assert sorted(p.name for p in (tmp_path / fmt).iterdir()) == files  # hidden ones too
    lo, hi = (float(v) for v in RANGE.search(printed).groups())
    code = ("import sys\nfrom evoscen_eval.scenes.scenario_export import read_commonroad\n"
            "sc, pps = read_commonroad(sys.argv[1])\npp = next(iter(pps.planning_problem_dict.values()))\n"
            "print(len(sc.dynamic_obstacles), pp.initial_state.time_step, pp.goal.state_list[0].time_step.start)")
    res = subprocess.run([sys.executable, "-c", code, str(tmp_path / "commonroad" / "scenario.xml")], cwd=REPO,
                         capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stderr
    obstacles, start, goal = (int(v) for v in res.stdout.split())
    # no shift in the range: the SUT's planning problem runs to its end, past the exposure
    assert obstacles > 0 and start == 0 and goal == round((hi - lo) / dt)
    assert lo + goal * dt >= exposures[0][1] - 1e-6


@pytest.mark.e2e
def test_a_truncated_bag_is_exported_with_evaluates_warning(recorded_run, tmp_path, capsys):
    from evoscen_eval.scoring.rundata import read_run

    bag = tmp_path / "bag"
    shutil.copytree(recorded_run.bag_dir, bag)
    mcap = next(bag.glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    states = read_run(bag).states
    assert 2 < states < recorded_run.steps
    assert _export_main()([str(bag), "--to", "0.2", "--out", str(tmp_path / "x")]) == 0
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"warning: bag {str(mcap)!r} is truncated or corrupt (")
    assert (f"evaluated the readable prefix, {states} world states ({states - 1} steps); to rebuild its summary "
            f"and metadata.yaml: python scripts/reindex.py {bag}") in lines[0]
    assert "3 states (t = 0.0 .. 0.2 s" in out


@pytest.mark.e2e
@pytest.mark.parametrize("args, line", [
    (["--event", "999"], "error: --event 999: the run has 0 collision(s) and {n} exposure(s) of the SUT: "
                         "expected events 1 .. {n}"),
    (["--event", "1", "--from", "3"], "error: --event: not with --from/--to"),
    (["--around", "3"], "error: --around: needs --event N"),
    (["--event", "1", "--around", "0"], "error: --around: 0: expected seconds > 0"),
    (["--event", "first"], "error: --event: 'first': expected a number N >= 1"),
])
def test_bad_event_input_is_one_error_line_and_status_2(shifted, tmp_path, capsys, args, line):
    n = len(_facts(shifted)[1])
    assert _export_main()([str(shifted / "bag"), *args, "--out", str(tmp_path / "x")]) == 2
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert len(err) == 1 and err[0].startswith(line.format(n=n)), err
    assert not (tmp_path / "x").exists()
