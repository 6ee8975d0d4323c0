"""The package functions behind run_scenario.py, graph_node.py, evaluate.py, reindex.py,
export_scenario.py and fault_campaign.py, on hand-made values (no run, no bag): the overrides the
scenario options give, the lines they print, the checks of their options."""

from __future__ import annotations

from pathlib import Path

import pytest
from evoscen_sim.errors import InputError


def test_scenario_options_override_only_the_keys_given():
    from evoscen_bringup.runs import SCENARIO_OPTIONS, option_dest, scenario_overrides

    assert [option for option, _key, _help in SCENARIO_OPTIONS] == ["--steps", "--seed", "--sut", "--bvs", "--mix",
                                                                   "--bv-nodes"]
    assert option_dest("--bv-nodes") == "bv_nodes"
    values = {"steps": "40", "seed": None, "sut": "mobil", "bvs": None, "mix": None, "bv_nodes": "single",
              "out": "runs/x"}
    assert scenario_overrides(values) == {"steps": "40", "sut.model": "mobil", "bvs.nodes": "single"}
    assert scenario_overrides({}) == {}


def test_a_runs_steps_are_its_world_states_less_the_first():
    from evoscen_bringup.runs import steps_of

    assert steps_of({"/evoscen/world": 301, "/clock": 301}) == 300
    assert steps_of({"/evoscen/world": 1}) == 0 and steps_of({"/clock": 5}) == 0 and steps_of({}) == 0


def test_the_comparative_line_names_each_term():
    from evoscen_eval.scoring.report import comparative_line

    d = {"score": 0.5, "progress": {"score": 0.75}, "safety": {"score": 1.0}, "lane_change_time": {"score": 0.25},
         "interaction": {"score": 0.125}}
    d["weights"] = {"safety": 0.6, "lane_change_time": 0.2, "interaction": 0.2}
    assert comparative_line({"comparative": d}) == (
        "D, the comparative score: 0.5000 = P·(0.6·S + 0.2·L + 0.2·X): progress P 0.7500, safety per SUT-km S "
        "1.0000, lane-change time L 0.2500, interaction X 0.1250")
    assert comparative_line({}) is None and comparative_line({"comparative": None}) is None


def test_the_run_summary_says_whose_each_count_is_and_times_each_span_once():
    """600 steps in 0.5 s of stepping (1200 steps/s, the bar's rate), the bag closed 0.1 s later, scored in 1.25 s."""
    from evoscen_bringup.inprocess import RunSummary
    from evoscen_bringup.runs import summary_lines

    s = RunSummary(steps=600, sim_time_s=60.0, wall_time_s=0.6, bag_dir=Path("bag"), steps_wall_s=0.5,
                   report_wall_s=1.25, collisions=1, lane_changes=24, reentries=97, off_road=0, sut_lane_changes=1)
    assert summary_lines(s) == [
        "steps: 600  simulated: 60.0 s  stepping: 0.50 s (1200 steps/s, the progress bar's rate)  then closing the "
        "bag: 0.10 s, scoring and the report: 1.25 s",
        "all vehicles: collisions: 1  lane changes: 24  re-entries: 97  off-road: 0; the SUT: lane changes: 1 "
        "(completed)"]
    s.bag_dir, s.wall_time_s = None, 0.5  # no bag: none closed
    assert summary_lines(s)[0] == ("steps: 600  simulated: 60.0 s  stepping: 0.50 s (1200 steps/s, the progress "
                                   "bar's rate)  then scoring and the report: 1.25 s")


def test_the_progress_bar_times_the_steps_as_the_summary_does():
    """The bar's clock starts as step 0 begins (progress(0)) and stops as the last step ends: 3 steps between
    t = 10 s and t = 10.5 s show 6.00 steps/s, what the summary prints for 3 steps in 0.5 s of stepping."""
    import io

    from evoscen_bringup.runs import step_bar
    from tqdm import tqdm

    now = [0.0]
    out = io.StringIO()
    bar = tqdm(total=3, unit="step", file=out, smoothing=0, mininterval=0)
    bar._time = lambda: now[0]  # tqdm's clock
    tick = step_bar(bar, 3)
    now[0] = 10.0
    tick(0)  # step 0 begins: time spent before it (building the run) is not the steps'
    for k in (1, 2, 3):
        now[0] = 10.0 + k * 0.5 / 3
        tick(k)
    assert out.getvalue().rstrip().endswith("6.00step/s]")


def test_an_in_process_run_says_when_step_0_begins():
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config

    seen: list[int] = []
    cfg = load_scenario_config(None, {"steps": 5, "bvs.count": 2, "spawn.ramp_vehicles": 0})
    summary = run_inprocess(cfg, bag_dir=None, progress=seen.append)
    assert seen == [0, 1, 2, 3, 4, 5]
    assert 0 < summary.steps_wall_s <= summary.wall_time_s and summary.stepping_steps_per_s == 5 / summary.steps_wall_s


def test_graph_args_from_the_environment_are_shell_words():
    from evoscen_bringup.one_node import arguments_with_environment

    env = {"EVOSCEN_GRAPH_ARGS": "--steps 30 --sut 'mobil'"}
    assert arguments_with_environment(["eval"], env) == ["eval", "--steps", "30", "--sut", "mobil"]
    assert arguments_with_environment(["sim"], {}) == ["sim"]
    with pytest.raises(InputError, match=r"^EVOSCEN_GRAPH_ARGS: No closing quotation \(expected shell words"):
        arguments_with_environment(["sim"], {"EVOSCEN_GRAPH_ARGS": "--seed '4"})


def test_animation_frames_are_a_whole_number():
    from evoscen_eval.scoring.animation import ANIMATION_FRAMES
    from evoscen_eval.scoring.bag_report import animation_frames

    assert animation_frames(None) == ANIMATION_FRAMES and animation_frames("0") == 0 and animation_frames("7") == 7
    for text in ("-1", "2.5", "many"):
        with pytest.raises(InputError, match=rf"^--animation-frames: '{text}': expected a whole number >= 0$"):
            animation_frames(text)


def test_what_a_reindex_recovered_in_lines():
    from evoscen_record.reindex import ReindexResult, recovered_lines

    r = ReindexResult(mcap_path=Path("/r/bag/bag_0.mcap"), messages=12, topic_counts={"/clock": 7, "/evoscen/world": 5},
                      steps=5, last_step_ns=400_000_000, chunks=2, stopped="a chunk cut short",
                      original=Path("/r/bag/bag_0.mcap.orig"))
    assert recovered_lines(r) == [
        "recovered 12 messages, 5 world states (last at 0.4 s) from 2 chunks (read stopped at: a chunk cut short)",
        "  /clock: 7", "  /evoscen/world: 5", "bag: /r/bag  (damaged file kept as bag_0.mcap.orig)"]
    empty = ReindexResult(mcap_path=Path("b/x.mcap"))
    assert recovered_lines(empty) == ["recovered 0 messages, 0 world states (last at -) from 0 chunks "
                                      "(the file was complete)", "bag: b"]


def test_export_numbers_and_a_clips_summary_line():
    from evoscen_eval.scenes.exports import number, summary_line

    assert number("--from", None) is None and number("--from", "2.5") == 2.5
    with pytest.raises(InputError, match=r"^--to: 'soon': expected a number \(s\)$"):
        number("--to", "soon")
    with pytest.raises(InputError, match=r"^--from: 'inf': expected a finite number$"):
        number("--from", "inf")
    res = {"vehicles": 4, "states": 31, "asam_errors": 0, "read_back": None, "collisions": (1, True), "seconds": 2.25,
           "ok": True}
    assert summary_line("runs/a/clips/0-collision-3", "collision", res) == (
        "runs/a/clips/0-collision-3: collision, 4 vehicles, 31 states; ASAM 0 error(s); 1 collision(s) agree; "
        "2.2 s; ok")
    unchecked = {**res, "asam_errors": None, "collisions": None}
    assert summary_line("c", "exposure", unchecked) == "c: exposure, 4 vehicles, 31 states; 2.2 s"


def test_a_problem_runs_log_tail(tmp_path):
    """A graph run with a problem keeps the last lines of its logs, each headed by its file's name."""
    from evoscen_experiments.faults import _log_tail

    log = tmp_path / "launcher.log"
    log.write_text("".join(f"line {k}\n" for k in range(30)), encoding="utf-8")
    assert _log_tail(log, 3) == "\nlauncher.log:\nline 27\nline 28\nline 29"
    assert _log_tail(tmp_path / "gone.log", 3) == ""


def test_the_fault_classes_and_their_statuses():
    from evoscen_experiments.faults import chosen_classes, class_name, expected_kill_statuses, fault_classes

    classes = fault_classes()
    # SIGKILL and SIGTERM to 6 nodes in 2 phases, a stall, an intruder, 6 host faults, vanish, driver-kill
    assert len(classes) == 2 * 6 * 2 + 2 + 6 + 2
    assert class_name(classes[0]) == "kill:SIGKILL:sim:lockstep" and class_name(classes[-1]) == "driver-kill"
    assert chosen_classes("stall, inject") == [("stall",), ("inject",)] and chosen_classes(None) == classes
    with pytest.raises(InputError, match=r"^--classes = 'stall,nap': expected comma-separated names among kill:"):
        chosen_classes("stall,nap")
    assert expected_kill_statuses(("kill", "SIGTERM", "sim", "lockstep")) == (130,)
    assert expected_kill_statuses(("kill", "SIGTERM", "sim", "startup")) == (4, 130)
    assert expected_kill_statuses(("kill", "SIGKILL", "eval", "lockstep")) == (4,)
