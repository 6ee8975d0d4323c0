"""Shared episode starts and batched rounds (evoscen_bringup.starts, campaign.batches/execute_batch).

A run from a shared start (the warm-up computed once, copied for every SUT variant) must score
exactly as the same run built from scratch, and a batch of runs in one task exactly as one run
per task: the reports are compared as JSON text, byte for byte.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import pytest
from evoscen_experiments import campaign
from evoscen_experiments.campaign import batches, execute, execute_batch
from evoscen_experiments.campaign_spec import CampaignRun
from evoscen_experiments.experiments import config_loader
from evoscen_bringup.inprocess import run_inprocess
from evoscen_bringup.scenario import build_scenario
from evoscen_bringup.starts import StartCache, start_key
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.errors import HostFault
from evoscen_sut.mutants import mutant_overrides

SEEDS = (90000, 90001)
VARIANTS = ({"sut.model": "mobil"}, mutant_overrides("mobil", "stale"))
STEPS = 50


def _cfg(seed: int, variant: dict, **extra: str):
    return load_scenario_config(None, {**variant, "seed": str(seed), "steps": str(STEPS),
                                       "recording.enabled": "false", **extra})


def _report_text(summary) -> str:
    return json.dumps(summary.report, sort_keys=True)


def test_start_key_leaves_out_only_what_picks_the_sut_driver():
    intact, stale = (_cfg(SEEDS[0], v) for v in VARIANTS)
    assert start_key(intact) == start_key(stale)  # sut.model and models.mutant differ: the same start
    assert start_key(intact) != start_key(_cfg(SEEDS[1], VARIANTS[0]))  # another seed
    assert start_key(intact) != start_key(_cfg(SEEDS[0], VARIANTS[0], **{"bvs.count": "12"}))
    assert start_key(intact) != start_key(intact, partitioned=False)
    # MOBIL BVs: models.mobil drives them, so it stays in the key (a mutant of mobil keeps it unchanged)
    bv_mobil = {"bvs.driver": "mobil"}
    assert start_key(_cfg(SEEDS[0], VARIANTS[0], **bv_mobil)) == start_key(_cfg(SEEDS[0], VARIANTS[1], **bv_mobil))
    assert (start_key(_cfg(SEEDS[0], VARIANTS[0], **bv_mobil))
            != start_key(_cfg(SEEDS[0], VARIANTS[0], **bv_mobil, **{"models.mobil.politeness": "0.9"})))


def test_shared_start_scores_as_a_run_built_from_scratch():
    cache = StartCache()
    for seed in SEEDS:
        for variant in VARIANTS:  # the second variant of a seed starts from the first's start, copied
            cfg = _cfg(seed, variant)
            fresh = run_inprocess(cfg, bag_dir=None, scenario=build_scenario(cfg), evaluate=True, plots=False)
            shared = run_inprocess(cfg, bag_dir=None, scenario=cache.scenario(cfg, partitioned=False),
                                   evaluate=True, plots=False)
            assert _report_text(shared) == _report_text(fresh), (seed, variant)
            assert shared.plot.ttc_hist.tolist() == fresh.plot.ttc_hist.tolist()
    assert (cache.built, cache.reused) == (2, 2)  # one warm-up per seed, reused by the other variant


def test_config_loader_equals_load_scenario_config():
    load = config_loader(None)
    for seed in SEEDS:
        for variant in VARIANTS:
            assert load({**variant, "seed": str(seed)}) == load_scenario_config(None, {**variant, "seed": str(seed)})


@dataclass(frozen=True)
class _Run:
    key: str
    group: str


def test_batches_keep_a_group_together_in_order_up_to_the_cap():
    runs = [_Run(f"r{i}", g) for i, g in enumerate("abab" "ac" "aa")]  # a: r0 r2 r4 r6 r7, b: r1 r3, c: r5
    got = [[r.key for r in b] for b in batches(runs, lambda r: r.group, size=3)]
    assert got == [["r0", "r2", "r4"], ["r6", "r7"], ["r1", "r3"], ["r5"]]
    assert [[r.key for r in b] for b in batches(runs, None)] == [[r.key] for r in runs]
    assert [[r.key for r in b] for b in batches(runs, lambda r: r.group, size=1)] == [[r.key] for r in runs]


def _runs() -> list[CampaignRun]:
    return [CampaignRun(f"k{seed}{i}", (("label", str(i)),), seed, _cfg(seed, v))
            for seed in SEEDS for i, v in enumerate(VARIANTS)]


def test_a_batch_gives_the_results_of_one_run_per_task(tmp_path, monkeypatch):
    runs = _runs()
    alone = []
    for run in runs:  # one run per task: a fresh worker cache each time, nothing shared
        monkeypatch.setattr(campaign, "_STARTS", None)
        alone.append(execute(run, str(tmp_path), "none"))
    monkeypatch.setattr(campaign, "_STARTS", None)
    together = [a for b in batches(runs, lambda r: start_key(r.cfg, partitioned=False))
                for a in execute_batch(b, str(tmp_path), "none")]
    assert campaign._STARTS.built == len(SEEDS)
    by_key = {a["row"]["key"]: a for a in together}
    for a in alone:
        b = by_key[a["row"]["key"]]
        assert json.dumps(b["report"], sort_keys=True) == json.dumps(a["report"], sort_keys=True)
        assert b["plot"] == a["plot"]
        skip = ("wall_time_s", "pid", "node")
        assert {k: v for k, v in b["row"].items() if k not in skip} == {k: v for k, v in a["row"].items()
                                                                          if k not in skip}


def test_a_failed_run_of_a_batch_is_reported_and_the_others_go_on(tmp_path, monkeypatch):
    runs = _runs()[:3]

    def fake(run, out_dir, record, clip_s=5.0):
        if run.key == runs[1].key:
            raise ValueError("bad plug-in answer\nsecond line")
        if run.key == runs[2].key:
            raise HostFault("cannot write /x: full", path="/x", cause="No space left on device (ENOSPC)")
        return {"row": {"key": run.key}}

    monkeypatch.setattr(campaign, "execute", fake)
    monkeypatch.setattr(campaign, "_RUNS_DONE", 0)  # this worker's first run, no start cache made
    monkeypatch.setattr(campaign, "_STARTS", None)
    assert execute_batch(runs, str(tmp_path), "none") == [
        {"row": {"key": runs[0].key}, "worker": {"first": True, "wait_s": 0.0, "built": False}},
        {"error": "ValueError: bad plug-in answer", "host_fault": None},
        {"error": "HostFault: cannot write /x: full", "host_fault": ("/x", "No space left on device (ENOSPC)")}]


@pytest.mark.parametrize("answer, failed, fault", [
    ({"error": "ValueError: boom", "host_fault": None}, ["k ({'cell': 'cell'}, seed 3): ValueError: boom"], None),
    ({"error": "HostFault: x", "host_fault": ("/x", "full")}, [], "run k (seed 3): cannot write /x on its worker: full"),
])
def test_a_failed_answer_is_noted_as_a_failed_task_was(tmp_path, answer, failed, fault):
    run = CampaignRun("k", (("cell", "cell"),), 3, _cfg(3, VARIANTS[0]))
    result = campaign.CampaignResult(runs=1, already_done=0)
    if fault is None:
        campaign._take(run, answer, tmp_path, result, 1, None)
    else:
        with pytest.raises(campaign._HostFaultStop):
            campaign._take(run, answer, tmp_path, result, 1, None)
    assert result.failed == failed
    assert result.host_fault == fault
    assert not (tmp_path / "runs").exists()


def test_a_recorded_run_from_a_shared_start_writes_the_same_bag(tmp_path):
    cache = StartCache()
    for k, variant in enumerate(VARIANTS):  # the second from the first's start, copied; BV nodes as recorded
        cfg = load_scenario_config(None, {**variant, "seed": str(SEEDS[0]), "steps": "40"})
        fresh, shared = tmp_path / f"fresh{k}" / "bag", tmp_path / f"shared{k}" / "bag"
        run_inprocess(cfg, bag_dir=fresh, scenario=build_scenario(cfg), bag_writer="inline")
        run_inprocess(cfg, bag_dir=shared, scenario=cache.scenario(cfg, partitioned=True), bag_writer="inline")
        names = sorted(p.name for p in fresh.iterdir())
        assert names == sorted(p.name for p in shared.iterdir())
        for name in names:
            assert (shared / name).read_bytes() == (fresh / name).read_bytes(), (variant, name)
    assert (cache.built, cache.reused) == (1, 1)


def test_a_run_scores_the_same_with_and_without_a_bag(tmp_path):
    # with a bag the evaluator stacks the world's columns (as the bag holds them); without one it takes the table
    # made in one compiled pass (World.table): the reports are the same, byte for byte as JSON
    from pathlib import Path

    for seed in SEEDS:
        bag = Path(tmp_path) / f"bag{seed}"
        summary = run_inprocess(_cfg(seed, VARIANTS[0], **{"recording.enabled": "true"}), bag_dir=bag, evaluate=True,
                                plots=False)
        recorded = summary.report
        plain = run_inprocess(_cfg(seed, VARIANTS[0]), bag_dir=None, evaluate=True, plots=False).report
        assert summary.bag_bytes > 0 and any(bag.glob("*.mcap"))
        assert json.dumps(recorded, sort_keys=True) == json.dumps(plain, sort_keys=True)


def test_the_animation_frames_are_kept_only_for_a_report_with_plots(tmp_path):
    # the frames feed the report's animation alone: a run scored for its figures skips them and scores the same
    cfg = _cfg(SEEDS[0], VARIANTS[0])
    plain = run_inprocess(cfg, bag_dir=None, evaluate=True, plots=False)
    written = run_inprocess(cfg, bag_dir=None, report_dir=tmp_path / "report", plots=True)
    no_plots = run_inprocess(cfg, bag_dir=None, report_dir=tmp_path / "report2", plots=False)
    assert plain.plot.frames.frames == [] and no_plots.plot.frames.frames == []
    # 51 states (50 steps and the first), every one kept below the series' cap
    assert [f.state for f in written.plot.frames.frames] == list(range(STEPS + 1))
    assert _report_text(plain) == _report_text(written) == _report_text(no_plots)
    assert (tmp_path / "report" / "run.gif").exists() and not (tmp_path / "report2" / "run.gif").exists()


def test_copies_of_a_driver_share_the_read_only_weights_and_answer_alike():
    import copy

    import numpy as np
    from evoscen_bv.learned import LearnedDriver, PolicyBank
    from evoscen_bv.td3 import NumpyActor

    cfg = load_scenario_config(None, {"seed": "1031002", "steps": "20", "recording.enabled": "false"})
    cache = StartCache()
    first, second = (cache.scenario(cfg, partitioned=False) for _ in range(2))
    cars = [getattr(sc.bv_driver, "car_driver", sc.bv_driver) for sc in (first, second)]
    assert all(isinstance(c, LearnedDriver) for c in cars)
    assert cars[0] is not cars[1] and cars[0].stack is cars[1].stack  # shared, not copied per run
    assert cars[0].controller_bank is cars[1].controller_bank
    with pytest.raises(ValueError):
        cars[0].stack.W1[0, 0, 0] = 1.0
    for _ in range(20):  # the copies drive alike from the same start
        a, b = first.step(), second.step()
        assert a.executed_lane_change.tolist() == b.executed_lane_change.tolist()
    assert first.world.s.tobytes() == second.world.s.tobytes()
    # an actor with writable weights (one made in memory) is copied, not shared
    w = {k: np.ones((2, 2)) if k in ("W1", "W2") else np.ones(2) if k in ("b1", "b2") else np.ones((2, 1))
         for k in ("W1", "b1", "W2", "b2", "W3")}
    actor = NumpyActor({**w, "b3": np.zeros(1), "max_action": np.array(1.0)})
    twin = copy.deepcopy(actor)
    assert twin is not actor and twin.W1 is not actor.W1 and np.array_equal(twin.W1, actor.W1)
    bank = PolicyBank([actor])
    assert copy.deepcopy(bank) is bank
    # by hand: relu(1*1 + 1*1 + 1) = 3 per unit, relu(3 + 3 + 1) = 7, 7 + 7 + 0 = 14, tanh(14) * 1
    assert bank.forward(np.ones((1, 2)))[0] == pytest.approx(np.tanh(14.0))
