"""The challenge layer (docs/challenges.md): the tilt, the likelihood ratios' unbiasedness by simulation,
the layer in a scenario run, the config key and the recorded scenario."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from evoscen_sim.errors import InputError
from evoscen_sim.physics.vehicle import VehicleParams
from evoscen_sim.danger.challenge import LeaderBraking, OnsetProcess, Tilt


def test_tilt_by_hand():
    t = Tilt(300.0, 1.0, 2.0)
    assert t.multiplier(0.4) == 300.0 and t.multiplier(1.0) == 300.0
    assert t.multiplier(1.5) == pytest.approx(1.0 + 299.0 * 0.5)  # halfway: 150.5
    assert t.multiplier(1.75) == pytest.approx(1.0 + 299.0 * 0.25)
    assert t.multiplier(2.0) == 1.0 and t.multiplier(math.inf) == 1.0


def _world(gap_m: float, v_sut: float, v_leader: float, step: int):
    """Two vehicles on one lane: the SUT (index 0) and, ``gap_m`` ahead bumper to bumper, its leader."""
    return SimpleNamespace(step_index=step, dt_s=0.1, v=np.array([v_sut, v_leader]), role=np.array([1, 0]),
                           s=np.array([0.0, gap_m + 4.5]), d=np.zeros(2), length=np.array([4.5, 4.5]),
                           width=np.array([1.8, 1.8]), lane_change=np.zeros(2, dtype=np.int64),
                           vehicle=VehicleParams())


def _episode(process: OnsetProcess, tilt: Tilt | None, seed: int, steps: int) -> tuple[int, float]:
    """Onsets and log weight of one synthetic episode: the SUT at 25 m/s follows a 30 m/s leader whose gap
    cycles step by step through 10, 30, 45 and 60 m (headways 0.4, 1.2, 1.8, 2.4 s: four factors), the states fixed in
    advance so that only the process's draws differ; the leader is braking, so not eligible, after an onset."""
    layer = LeaderBraking(2, process, tilt, np.random.default_rng(seed))
    gaps = (10.0, 30.0, 45.0, 60.0)
    for k in range(steps):
        layer.apply(_world(gaps[k % 4], 25.0, 30.0, k), np.zeros(2))
    return len(layer.onsets), layer.log_weight


def _weighted_vs_plain(process: OnsetProcess, tilt: Tilt, n: int, steps: int):
    plain = np.array([_episode(process, None, 10_000 + i, steps)[0] for i in range(n)], dtype=float)
    tilted = [_episode(process, tilt, 50_000 + i, steps) for i in range(n)]
    counts = np.array([c for c, _ in tilted], dtype=float)
    w = np.exp(np.array([lw for _, lw in tilted]))
    return plain, counts, w


@pytest.mark.parametrize("per_1000km, max_m, steps", [(2_000.0, 8.0, 80), (100_000.0, 1.5, 40)])
def test_reweighted_onset_count_is_unbiased(per_1000km, max_m, steps):
    """E_q[w] = 1 and E_q[w N] = E_p[N] (N the episode's onsets): the weighted mean of tilted episodes
    against plain ones on other seeds, each within 4 standard errors. The second case (μ = 10 m: an onset in
    a quarter to a third of the eligible steps) fails with the rate ratio m as an onset's factor instead of
    the ratio of the step's probabilities (E_q[w] 1.05 ± 0.008 measured with the ratio 1/m of a continuous
    process, whose untriggered onsets a run's end leaves out)."""
    process = OnsetProcess(per_1000km=per_1000km, decel_mps2=(4.0, 7.0), duration_s=(0.5, 1.0), min_speed_mps=10.0)
    tilt = Tilt(max_m, 1.0, 2.0)
    plain, counts, w = _weighted_vs_plain(process, tilt, 3000, steps)
    assert counts.mean() > plain.mean() + 10 * plain.std() / math.sqrt(plain.size)  # the tilt: more onsets
    se_w = w.std(ddof=1) / math.sqrt(w.size)
    assert abs(w.mean() - 1.0) < 4 * se_w
    est, ref = w * counts, plain
    se = math.sqrt(est.var(ddof=1) / est.size + ref.var(ddof=1) / ref.size)
    assert abs(est.mean() - ref.mean()) < 4 * se, (est.mean(), ref.mean(), se)


def test_naturalistic_weight_is_one_and_factors_by_hand():
    process = OnsetProcess(per_1000km=1.0e5)  # μ = 10 m: an onset at the first eligible step or soon after
    layer = LeaderBraking(2, process, None, np.random.default_rng(1))
    for k in range(50):
        layer.apply(_world(10.0, 25.0, 30.0, k), np.zeros(2))
    assert layer.onsets and layer.log_weight == 0.0
    tilted = LeaderBraking(2, process, Tilt(300.0, 1.0, 2.0), np.random.default_rng(1))
    thr, onsets = tilted.apply(_world(10.0, 25.0, 30.0, 0), np.zeros(2))  # headway 0.4 s: m = 300
    ds = 30.0 * 0.1
    # the step's factor p/q: no onset e^(299 ds/μ) = e^89.7, an onset (1 - e^-0.3) / (1 - e^-90)
    if onsets:
        ratio = (1.0 - math.exp(-300.0 * ds / 10.0)) / (1.0 - math.exp(-ds / 10.0))  # q/p, 3.858
        assert onsets[0].multiplier == pytest.approx(ratio) and onsets[0].vehicle == 1
        assert tilted.log_weight == pytest.approx(-math.log(ratio))
        assert thr[1] == pytest.approx(-onsets[0].decel_mps2 / VehicleParams().max_brake_mps2)
    else:
        assert tilted.log_weight == pytest.approx(299.0 * ds / 10.0)
    assert tilted.distance_m == pytest.approx(ds)


def test_no_onset_beyond_view_or_below_min_speed():
    process = OnsetProcess(per_1000km=1.0e6)
    layer = LeaderBraking(2, process, Tilt(), np.random.default_rng(2))
    for k in range(20):
        layer.apply(_world(120.0, 25.0, 30.0, k), np.zeros(2))  # 120 m > VIEW_M
        layer.apply(_world(20.0, 25.0, 9.0, k), np.zeros(2))  # leader at 9 m/s < 10
    assert not layer.onsets and layer.distance_m == 0.0 and layer.log_weight == 0.0


def test_truck_cap():
    layer = LeaderBraking(2, OnsetProcess(per_1000km=1.0e6, decel_mps2=(7.0, 7.0)), None,
                          np.random.default_rng(3), max_decel_mps2=np.array([np.inf, 5.0]))
    _, onsets = layer.apply(_world(20.0, 25.0, 30.0, 0), np.zeros(2))
    assert onsets and onsets[0].decel_mps2 == 5.0


# ---------------------------------------------------------------------- in a scenario

def _config(**over):
    from evoscen_sim.config.scenario_config import load_scenario_config

    return load_scenario_config(None, {"sut.model": "mobil", "steps": "300", "recording.enabled": "false", **over})


def _run(cfg, scenario=None):
    from evoscen_bringup import inprocess
    from evoscen_bringup.scenario import build_scenario

    sc = scenario if scenario is not None else build_scenario(cfg)
    return sc, inprocess.run_inprocess(cfg, bag_dir=None, scenario=sc, evaluate=True, plots=False).report


def test_scenario_run_reports_its_weight_and_is_deterministic():
    from evoscen_bringup import starts

    cfg = _config(**{"seed": "990004", "challenge.mode": "nade"})
    sc, report = _run(cfg)
    ch = report["challenge"]
    layer = sc.world.challenge
    assert ch["complete"] and ch["count"] == len(layer.onsets) >= 1
    assert ch["log_weight"] == layer.log_weight and ch["weight"] == pytest.approx(math.exp(layer.log_weight))
    assert [o["multiplier"] for o in ch["onsets"]] == [o.multiplier for _, o in layer.onsets]
    # the learned BVs' own rule is off under the layer
    assert all(getattr(d, "hard_brake", None) is None for d in _drivers(sc.bv_driver))
    _, again = _run(cfg)
    assert again == report
    cache = starts.StartCache()
    _, shared = _run(cfg, cache.scenario(cfg, partitioned=False))
    assert shared["challenge"] == report["challenge"] and shared["comparative"] == report["comparative"]


def test_naturalistic_mode_weight_one_and_none_has_no_section():
    _, nat = _run(_config(**{"seed": "990004", "challenge.mode": "naturalistic"}))
    assert nat["challenge"]["log_weight"] == 0.0 and nat["challenge"]["weight"] == 1.0
    assert all(o["multiplier"] == 1.0 for o in nat["challenge"]["onsets"])
    _, plain = _run(_config(**{"seed": "990004"}))
    assert "challenge" not in plain


def _drivers(d):
    if d is None:
        return
    yield d
    yield from _drivers(getattr(d, "driver", None))
    yield from _drivers(getattr(d, "car_driver", None))
    for part in getattr(d, "parts", ()):
        yield from _drivers(part[1])


def test_config_errors_one_line():
    with pytest.raises(InputError, match=r"challenge\.headway_full_s.*below challenge\.headway_none_s = 1"):
        _config(**{"challenge.mode": "nade", "challenge.headway_full_s": "1.5", "challenge.headway_none_s": "1"})
    with pytest.raises(InputError, match=r"challenge\.mode"):
        _config(**{"challenge.mode": "always"})


def test_recorded_scenario_keeps_the_section_only_when_set():
    from evoscen_record.scenario_record import recorded_scenario

    assert "challenge" not in recorded_scenario(_config())
    assert recorded_scenario(_config(**{"challenge.mode": "nade"}))["challenge"]["mode"] == "nade"


def test_comparative_experiments_default_to_the_challenge_scenario(load_door):
    """Sensitivity and leaderboard runs take ``--challenge`` [nade] as every run's challenge.mode, over the
    config's; a bad value is one line."""
    from evoscen.experiment_runs import sensitivity_parser
    from evoscen_experiments.experiments import challenge_mode, config_loader

    assert sensitivity_parser().parse_args([]).challenge == "nade"
    assert load_door("leaderboard").parse_args([]).challenge == "nade"
    assert challenge_mode(None) == "nade" and challenge_mode("none") == "none"
    assert config_loader(None, "nade")({"seed": "3"}).challenge.mode == "nade"
    assert config_loader(None)({"seed": "3"}).challenge.mode == "none"
    with pytest.raises(InputError, match=r"^--challenge: expected one of none, naturalistic, nade, got 'x'$"):
        challenge_mode("x")


def test_a_challenge_bag_scores_again_and_exports_like_any_other(tmp_path):
    """A recorded `nade` run: its bag scored alone gives the report's challenge section and D; it exports as
    OpenSCENARIO across an onset."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    cfg_file = tmp_path / "nade.yaml"
    cfg_file.write_text("challenge:\n  mode: nade\n", encoding="utf-8")
    run = [sys.executable, str(repo / "scripts" / "run_scenario.py"), "--mode", "inprocess", "--config", str(cfg_file),
           "--sut", "mobil", "--steps", "300", "--seed", "990004", "--no-plots", "--out", str(tmp_path / "run")]
    assert subprocess.run(run, capture_output=True, text=True, timeout=300).returncode == 0
    report = json.loads((tmp_path / "run" / "report" / "report.json").read_text(encoding="utf-8"))
    assert report["challenge"]["count"] >= 1 and report["challenge"]["complete"]
    again = [sys.executable, str(repo / "scripts" / "evaluate.py"), str(tmp_path / "run" / "bag"), "--no-plots",
             "--out", str(tmp_path / "again")]
    assert subprocess.run(again, capture_output=True, text=True, timeout=300).returncode == 0
    rescored = json.loads((tmp_path / "again" / "report.json").read_text(encoding="utf-8"))
    assert rescored["challenge"] == report["challenge"] and rescored["comparative"] == report["comparative"]
    t = report["challenge"]["onsets"][0]["time_s"]
    export = [sys.executable, str(repo / "scripts" / "export_scenario.py"), str(tmp_path / "run" / "bag"),
              "--from", f"{max(0.0, t - 3):.1f}", "--to", f"{min(30.0, t + 3):.1f}", "--format", "xosc",
              "--out", str(tmp_path / "xosc")]
    p = subprocess.run(export, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "xosc" / "scenario.xosc").stat().st_size > 1000


def test_a_paired_campaign_spec_runs_the_challenge_scenario(tmp_path):
    from evoscen_experiments.campaign_spec import load_spec

    def spec(text: str):
        p = tmp_path / "spec.yaml"
        p.write_text(text, encoding="utf-8")
        return load_spec(p)

    grid = "grid:\n  mutant: [intact, stale]\n"
    assert spec(grid + "compare: {axis: mutant, reference: intact}\n").fixed["challenge.mode"] == "nade"
    assert "challenge.mode" not in spec(grid).fixed  # no pair: the config's scenario
    kept = spec("set:\n  challenge.mode: none\n" + grid + "compare: {axis: mutant, reference: intact}\n")
    assert kept.fixed["challenge.mode"] == "none"
    axis = spec("grid:\n  challenge.mode: [none, nade]\ncompare: {axis: challenge.mode, reference: none}\n")
    assert "challenge.mode" not in axis.fixed and axis.grid["challenge.mode"] == ("none", "nade")


def test_an_entering_vehicle_brings_no_braking_with_it():
    layer = LeaderBraking(2, OnsetProcess(per_1000km=1.0e6), None, np.random.default_rng(4))
    _, onsets = layer.apply(_world(20.0, 25.0, 30.0, 0), np.zeros(2))
    assert onsets and layer.until_step[1] > 1
    layer.entered([1])
    thr, _ = layer.apply(_world(120.0, 25.0, 30.0, 1), np.full(2, 0.3))  # beyond the view: no new onset
    assert layer.until_step[1] == -1 and thr[1] == 0.3
