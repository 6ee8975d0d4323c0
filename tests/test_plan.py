"""The in-process runner's plan (:mod:`evoscen_bringup.plan`): the configuration resolved once, each
room given its part.

* a plan's evaluation part carries the configuration's evaluation settings (checked field by field
  against values set by hand) and they equal those the runner used before the plan (read back from the
  YAML of the bag's scenario record): the same settings an evaluation of the bag uses;
* its recording part carries the BV nodes, the ``recording`` section and the bag's scenario record;
* the recorders get the recording part and the scorer the evaluation settings, not the configuration,
  and no YAML is read during the run;
* a run of the plan gives the report of a run scored as before, and the report of its own bag.

The bytes of the bags are tests/test_bag_hashes.py's.
"""

from __future__ import annotations

import copy
import dataclasses

import pytest

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

SET_BY_HAND = {"evaluation.ttc_threshold_s": 3.5, "evaluation.score_form": "method",
               "evaluation.count_normalisation": "literal", "evaluation.weight_safety": 0.5,
               "evaluation.collision_exposures": 4.0, "evaluation.window_steps": 50, "dt_s": 0.05}


def _cfg(overrides: dict | None = None):
    from evoscen_sim.config.scenario_config import load_scenario_config

    return load_scenario_config(None, {"steps": 40, "seed": 3, **(overrides or {})})


def _read_back(cfg) -> dict:
    """The scenario as the runner read it back before the plan: the YAML text of the bag's record, loaded."""
    import yaml
    from evoscen_record.scenario_record import SCENARIO_KEY, scenario_metadata

    return yaml.safe_load(scenario_metadata(cfg)[SCENARIO_KEY])


def test_the_evaluation_part_carries_the_settings_set_by_hand():
    from evoscen_bringup.plan import evaluation_plan_of

    cfg = _cfg(SET_BY_HAND)
    ev = evaluation_plan_of(cfg)
    s = ev.settings
    assert (s.ttc_threshold_s, s.score_form, s.count_normalisation, s.weight_safety, s.collision_exposures,
            s.window_steps) == (3.5, "method", "literal", 0.5, 4.0, 50)
    assert (s.hard_brake_mps2, s.weight_efficiency) == (6.0, 0.2)  # left at their defaults
    assert ev.dt_s == 0.05 and ev.scenario["dt_s"] == 0.05
    assert s is cfg.evaluation  # the configuration's section itself


@pytest.mark.parametrize("overrides", [{}, SET_BY_HAND, {"bvs.makeup": "uniform", "bvs.driver": "nilsson"},
                                       {"evaluation.score_form": "comparative", "bvs.nodes": 4}])
def test_the_evaluation_part_is_what_the_bag_is_scored_with(overrides):
    """The settings, step and scenario of the evaluation part equal those read back from the bag's
    record (what the runner scored with before, and what an evaluation of the bag uses), each field
    of the same type."""
    from evoscen_bringup.plan import evaluation_plan_of
    from evoscen_eval.scoring.rundata import evaluation_settings_of

    cfg = _cfg(overrides)
    ev = evaluation_plan_of(cfg)
    recorded = _read_back(cfg)
    assert ev.scenario == recorded
    before = evaluation_settings_of(copy.deepcopy(recorded))
    assert ev.settings == before
    for f in dataclasses.fields(before):
        assert type(getattr(ev.settings, f.name)) is type(getattr(before, f.name)), f.name
    assert ev.dt_s == float(recorded["dt_s"])


def test_the_recording_part_carries_the_bv_nodes_the_section_and_the_record():
    from evoscen_bringup.plan import recording_plan_of
    from evoscen_record.recording_plan import RecordingPlan
    from evoscen_record.scenario_record import scenario_metadata

    cfg = _cfg({"bvs.nodes": 4, "recording.compression": "none", "recording.chunk_size_bytes": 4096,
                "recording.markers_every": 3})
    rec = recording_plan_of(cfg)
    assert type(rec) is RecordingPlan
    assert (rec.compression, rec.chunk_size_bytes, rec.markers_every, rec.dt_s) == ("none", 4096, 3, cfg.dt_s)
    assert rec.bv_count == cfg.bvs.count
    assert rec.bv_nodes == ["evoscen_bv_0", "evoscen_bv_1", "evoscen_bv_2", "evoscen_bv_3"]
    assert [b.topic for b in rec.bv_topics] == [f"/evoscen/commands/bv_{k}" for k in range(4)]
    positions = [p for b in rec.bv_topics for p in b.positions]
    assert positions == list(range(cfg.bvs.count))  # consecutive ids, every BV once
    assert dict(rec.scenario_record) == scenario_metadata(cfg)


def _no_config_in(args) -> bool:
    from evoscen_sim.config.scenario_config import ScenarioConfig

    def parts(value):
        yield value
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            for f in dataclasses.fields(value):
                yield getattr(value, f.name)

    return not any(isinstance(p, ScenarioConfig) for a in args for p in parts(a))


@pytest.mark.parametrize("writer", ["inline", "process"])
def test_the_recorder_and_the_scorer_get_only_their_parts(writer, tmp_path, monkeypatch):
    import yaml
    from evoscen_bringup import inprocess
    from evoscen_bringup.plan import plan_of
    from evoscen_eval.scoring.rundata import RunAccumulator
    from evoscen_record import bag_writer
    from evoscen_record.recording_plan import RecordingPlan
    from evoscen_record.step_recorder import StepRecorder
    from evoscen_sim.config.scenario_config import EvaluationConfig

    seen = {}

    def spy(cls, name):
        init = cls.__init__

        def wrapped(self, *args, **kwargs):
            seen[name] = (args, kwargs)
            init(self, *args, **kwargs)
        monkeypatch.setattr(cls, "__init__", wrapped)

    spy(StepRecorder, "recorder")
    spy(bag_writer.ProcessRecorder, "recorder")
    start_scoring = RunAccumulator.start_scoring

    def scoring(self, ev, dt_s=None, **kwargs):
        seen["scorer"] = ((ev, dt_s), {})
        return start_scoring(self, ev, dt_s, **kwargs)
    monkeypatch.setattr(RunAccumulator, "start_scoring", scoring)

    cfg = _cfg()
    plan = plan_of(cfg)

    def no_yaml(*args, **kwargs):
        raise AssertionError("YAML read during the run")
    monkeypatch.setattr(yaml, "safe_load", no_yaml)
    summary = inprocess.run_plan(plan, bag_dir=tmp_path / "bag", evaluate=True, bag_writer=writer)
    assert summary.report is not None
    args, kwargs = seen["recorder"]
    assert type(args[1]) is RecordingPlan and args[1] is plan.recording
    assert _no_config_in([*args, *kwargs.values()])
    (ev, dt_s), _ = seen["scorer"]
    assert type(ev) is EvaluationConfig and ev is cfg.evaluation and dt_s == cfg.dt_s


def test_a_plan_without_a_recording_part_records_nothing(tmp_path):
    from evoscen_bringup.inprocess import run_plan
    from evoscen_bringup.plan import plan_of

    plan = plan_of(_cfg(), recorded=False)
    assert plan.recording is None
    with pytest.raises(ValueError, match="without a recording part"):
        run_plan(plan, bag_dir=tmp_path / "bag")
    assert not (tmp_path / "bag").exists()


def test_a_run_of_the_plan_gives_the_report_of_before_and_of_its_bag(tmp_path):
    """The report of a run of the plan equals that of the same run scored as the runner scored before
    the plan (settings, step and scenario read back from the bag's record), and that of its bag scored
    offline; with ``keep_run`` the run's scenario is the bag's."""
    from evoscen_bringup.inprocess import run_plan
    from evoscen_bringup.plan import EvaluationPlan, plan_of
    from evoscen_eval.scoring.metrics import report_of_stream
    from evoscen_eval.scoring.rundata import evaluation_settings_of, read_run, score_bag

    overrides = {"steps": 120, "sut.model": "mobil", "evaluation.score_form": "method"}
    cfg = _cfg(overrides)
    now = run_plan(plan_of(cfg), bag_dir=tmp_path / "bag", evaluate=True, keep_run=True, bag_writer="inline")
    recorded = _read_back(cfg)
    plan = plan_of(cfg, recorded=False)
    before_plan = dataclasses.replace(plan, evaluation=EvaluationPlan(
        settings=evaluation_settings_of(copy.deepcopy(recorded)), dt_s=float(recorded["dt_s"]), scenario=recorded))
    before = run_plan(before_plan, bag_dir=None, evaluate=True)
    assert now.report == before.report
    scored = score_bag(tmp_path / "bag")
    assert report_of_stream(scored.stream, scored.info, scored.warnings) == now.report
    assert now.run.scenario == read_run(tmp_path / "bag").scenario
