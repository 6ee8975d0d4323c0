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
    assert comparative_line({"comparative": d}) == ("comparative: 0.5000 (progress 0.7500, safety 1.0000, "
                                                    "lane-change time 0.2500, interaction 0.1250)")
    assert comparative_line({}) is None and comparative_line({"comparative": None}) is None


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
