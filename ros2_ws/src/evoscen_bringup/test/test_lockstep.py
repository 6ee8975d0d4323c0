"""Runs stepped in lockstep in one process (``run_plans``) score as each run alone; a run that fails ends alone."""

from __future__ import annotations

import json

import pytest
from evoscen_bringup import inprocess
from evoscen_bringup.inprocess import run_plan, run_plans
from evoscen_bringup.plan import plan_of
from evoscen_bringup.starts import StartCache, start_key
from evoscen_experiments import campaign
from evoscen_experiments.campaign import batches, execute_batch
from evoscen_experiments.campaign_spec import CampaignRun
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.errors import PluginFault
from evoscen_sut.mutants import mutant_overrides

STEPS = 40
VARIANTS = ({"sut.model": "mobil"}, mutant_overrides("mobil", "stale"), {"sut.model": "nilsson"})


def _cfg(seed: int, variant: dict):
    return load_scenario_config(None, {**variant, "seed": str(seed), "steps": str(STEPS), "recording.enabled": "false"})


def _text(summary) -> str:
    return json.dumps(summary.report, sort_keys=True)


def _plans(cfgs, cache: StartCache):
    return [plan_of(c, recorded=False, scenario=cache.scenario(c, partitioned=False)) for c in cfgs]


@pytest.mark.parametrize("size", [1, 7, 64])
def test_a_world_scores_the_same_alone_and_in_a_batch(size):
    cfgs = [_cfg(1032000 + k // len(VARIANTS), VARIANTS[k % len(VARIANTS)]) for k in range(size)]
    alone = [run_plan(p, bag_dir=None, evaluate=True) for p in _plans(cfgs, StartCache())]
    together = run_plans(_plans(cfgs, StartCache()))
    assert len(together) == size
    for a, b in zip(alone, together):
        assert _text(b) == _text(a)
        assert b.plot.ttc_hist.tolist() == a.plot.ttc_hist.tolist() and b.steps == a.steps == STEPS
        assert (b.collisions, b.lane_changes, b.sut_lane_changes, b.reentries) == (
            a.collisions, a.lane_changes, a.sut_lane_changes, a.reentries)


def test_a_world_whose_driver_raises_ends_alone_and_the_others_go_on():
    cfgs = [_cfg(1032100 + k, VARIANTS[0]) for k in range(3)]
    plans = _plans(cfgs, StartCache())
    sut = plans[1].scenario.sut
    real = sut.act

    def act(view):
        if view.step_index == 10:
            raise RuntimeError("plug-in broke")
        return real(view)

    sut.act = act
    got = run_plans(plans)
    assert isinstance(got[1], PluginFault) and got[1].steps == 11 and "plug-in broke" in str(got[1])
    alone = [run_plan(p, bag_dir=None, evaluate=True) for p in _plans([cfgs[0], cfgs[2]], StartCache())]
    assert [_text(got[0]), _text(got[2])] == [_text(a) for a in alone]


def test_a_run_that_fails_in_its_set_up_or_its_scoring_ends_alone(monkeypatch):
    """One run's error while its scorer is made, and a fault of the host while another is scored: each is
    that run's answer (as run_plan would raise it for that run alone); the third scores as alone."""
    from evoscen_sim.errors import HostFault

    cfgs = [_cfg(1032150 + k, VARIANTS[k]) for k in range(3)]
    plans = _plans(cfgs, StartCache())
    real_scoring, real_finish = inprocess._scoring, inprocess._finish

    def scoring(plan, *a):
        if plan is plans[0]:
            raise ValueError("scorer broke")
        return real_scoring(plan, *a)

    def finish(plan, *a):
        if plan is plans[2]:
            raise HostFault("no space left", path="/full/report.json", cause="No space left on device")
        return real_finish(plan, *a)

    monkeypatch.setattr(inprocess, "_scoring", scoring)
    monkeypatch.setattr(inprocess, "_finish", finish)
    got = run_plans(plans)
    assert isinstance(got[0], ValueError) and str(got[0]) == "scorer broke"
    assert isinstance(got[2], HostFault) and got[2].path == "/full/report.json"
    assert plans[0].scenario.world.step_index == 0 and plans[2].scenario.world.step_index == STEPS
    monkeypatch.undo()
    alone = run_plan(_plans([cfgs[1]], StartCache())[0], bag_dir=None, evaluate=True)
    assert _text(got[1]) == _text(alone)


def test_a_lockstep_task_counts_every_run_given_as_one_at_a_time_does(tmp_path, monkeypatch):
    """A failed run counts among the worker's runs in both paths: only the task's first run is the worker's
    first, and a host fault is that run's answer (its file and reason), not the task's failure."""
    from evoscen_sim.errors import HostFault

    runs = [CampaignRun(f"c{i}", (("label", str(i)),), 1032400, _cfg(1032400, v)) for i, v in enumerate(VARIANTS)]
    real, calls = inprocess._finish, []

    def finish(plan, *a):
        calls.append(plan)
        if len(calls) == 3:  # the third run's scoring (each path scores in the runs' order)
            raise HostFault("no space left", path="/full/x", cause="No space left on device")
        return real(plan, *a)

    monkeypatch.setattr(inprocess, "_finish", finish)
    for lockstep in (False, True):
        calls.clear()
        monkeypatch.setattr(campaign, "_STARTS", None)
        monkeypatch.setattr(campaign, "_RUNS_DONE", 0)
        got = execute_batch(runs, str(tmp_path), "none", lockstep=lockstep)
        assert campaign._RUNS_DONE == 3
        assert [a["worker"]["first"] for a in got[:2]] == [True, False]
        assert got[2]["host_fault"] == ("/full/x", "No space left on device") and "row" not in got[2]
        again = execute_batch(runs[:1], str(tmp_path), "none", lockstep=lockstep)
        assert again[0]["worker"]["first"] is False and campaign._RUNS_DONE == 4


def test_a_recorded_plan_is_refused():
    cfg = load_scenario_config(None, {"steps": "5"})
    with pytest.raises(ValueError, match="unrecorded runs only"):
        run_plans([plan_of(cfg, recorded=True)])


def test_ctrl_c_ends_every_world_and_raises(monkeypatch):
    plans = _plans([_cfg(1032200 + k, VARIANTS[0]) for k in range(2)], StartCache())
    real = inprocess._InProcessPort.begin_step

    def begin(self, step):
        if step == 5:
            self.ctrl_c.pending = True
        return real(self, step)

    monkeypatch.setattr(inprocess._InProcessPort, "begin_step", begin)
    with pytest.raises(KeyboardInterrupt):
        run_plans(plans)
    assert [p.scenario.world.step_index for p in plans] == [5, 5]  # each ended at its next step boundary


def test_a_lockstep_task_answers_as_one_run_at_a_time(tmp_path, monkeypatch):
    runs = [CampaignRun(f"k{seed}{i}", (("label", str(i)),), seed, _cfg(seed, v))
            for seed in (1032300, 1032301) for i, v in enumerate(VARIANTS)]
    group = lambda r: start_key(r.cfg, partitioned=False)  # noqa: E731
    answers = {}
    for lockstep in (False, True):
        monkeypatch.setattr(campaign, "_STARTS", None)
        answers[lockstep] = {a["row"]["key"]: a for b in batches(runs, group)
                             for a in execute_batch(b, str(tmp_path), "none", lockstep=lockstep)}
    skip = ("wall_time_s", "pid", "node")
    for key, a in answers[False].items():
        b = answers[True][key]
        assert json.dumps(b["report"], sort_keys=True) == json.dumps(a["report"], sort_keys=True)
        assert b["plot"] == a["plot"] and b["worker"]["built"] == a["worker"]["built"]
        assert {k: v for k, v in b["row"].items() if k not in skip} == {k: v for k, v in a["row"].items()
                                                                          if k not in skip}
        assert b["row"]["wall_time_s"] > 0.0


def test_the_batch_option_is_a_positive_count_or_absent():
    import argparse

    from evoscen_experiments.experiments import batch_option
    from evoscen_sim.errors import InputError

    assert batch_option(argparse.Namespace()) is None and batch_option(argparse.Namespace(batch=None)) is None
    assert batch_option(argparse.Namespace(batch=" 7 ")) == 7
    for bad in ("0", "-2", "x"):
        with pytest.raises(InputError, match="^--batch"):
            batch_option(argparse.Namespace(batch=bad))
