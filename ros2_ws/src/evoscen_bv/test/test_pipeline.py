"""The level-k pipeline: a smoke run of every stage, exact resume, CLI errors, loadable policies."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")

from evoscen_bv.learned import LearnedDriver, load_policies
from evoscen_bv.pipeline import Pipeline
from evoscen_bv.td3 import NumpyActor

REPO = Path(__file__).resolve().parents[4] if (Path(__file__).resolve().parents[4] / "scripts").is_dir() else None
SMOKE = """
td3: {hidden: 16, batch_size: 32, start_steps: 100}
env: {control_episode_steps: 100, decision_episode_decisions: 20, bv_count: 8, eval_every_steps: 100,
      control_settling_check: true}
steps: {control: 300, level1: 150, level2: 150, competitive: 150, cooperative: 150}
"""


def _repo() -> Path:
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "scripts" / "train_bv.py").is_file():
            return parent
    pytest.skip("scripts/train_bv.py not found (installed test tree)")


def _train(args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(_repo() / "scripts" / "train_bv.py"), *args],
                          capture_output=True, text=True, timeout=600, env={**os.environ})


@pytest.mark.e2e  # runs a CLI as a subprocess
def test_smoke_pipeline_all_stages_produces_loadable_policies(tmp_path):
    cfg = tmp_path / "smoke.yaml"
    cfg.write_text(SMOKE)
    out = tmp_path / "policies"
    r = _train(["--stage", "all", "--out", str(out), "--config", str(cfg), "--seed", "7", "--quiet"])
    assert r.returncode == 0, r.stderr[-2000:]
    for policy in ("controller", "level1_mutual", "mutual", "competitive", "cooperative"):
        assert (out / f"{policy}.npz").is_file()
        card = (out / f"{policy}.md").read_text()
        assert "seed: 7" in card and "git_commit:" in card and "--stage all" in card
    for stage in ("control", "level1", "level2", "competitive", "cooperative"):
        rows = (out / stage / "curve.csv").read_text().splitlines()
        assert rows[0].startswith("episode,step,return") and len(rows) > 1
        assert (out / stage / "curve.png").stat().st_size > 0
        evals = (out / stage / "eval.csv").read_text().splitlines()
        header = "step,eval_mean_return" + (",settled_gap_m,flip_share,settling_collisions,settled"
                                            if stage == "control" else "")  # the settling check, controller only
        assert evals[0] == header and len(evals) >= 2
        assert not (out / stage / "checkpoint.pt").exists()
    assert (out / "control" / "gap_kde.png").stat().st_size > 0
    assert "settled_evaluations:" in (out / "controller.md").read_text()
    controller, decisions, training = load_policies(out)
    assert controller.state_dim == 4 and sorted(decisions) == [1, 2, 3]
    assert training.td3.hidden == 16
    # a finished stage is not redone
    again = _train(["--stage", "level1", "--out", str(out), "--seed", "7", "--quiet"])
    assert again.returncode == 0 and "level1: level1_mutual.npz, 150 steps" in again.stdout
    # resuming with another seed is refused
    other = _train(["--stage", "level1", "--out", str(out), "--seed", "8", "--quiet"])
    assert other.returncode == 2 and "was started with --seed 7, not 8" in other.stderr
    # the policies drive a scenario
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.scenario_builders import build_bv_driver, build_world

    scen = config_from_dict({"bvs": {"driver": "learned", "count": 10, "makeup": "uniform"}, "spawn": {"ramp_vehicles": 2},
                             "models": {"learned": {"policy_dir": str(out)}}})
    world = build_world(scen)
    driver = build_bv_driver(scen)
    assert isinstance(driver, LearnedDriver)
    for _ in range(30):
        t, lc = driver.act(world)
        full_t = np.zeros(world.n)
        full_lc = np.zeros(world.n, dtype=np.int64)
        full_t[driver.vehicles] = t
        full_lc[driver.vehicles] = lc
        world.step(full_t, full_lc)
        assert np.all(np.abs(t) <= 1.0) and set(np.unique(lc)) <= {-1, 0, 1}


def test_resume_continues_exactly(tmp_path, monkeypatch):
    cfg = tmp_path / "smoke.yaml"
    cfg.write_text(SMOKE)
    straight = Pipeline(tmp_path / "a", seed=3, config_path=cfg, progress=False, checkpoint_every=100)
    straight.run_stage("control")
    from evoscen_bv import td3

    real_train = td3.TD3.train
    calls = {"n": 0}

    def interrupted(self, replay, rng):
        calls["n"] += 1
        if calls["n"] == 150:  # training step 250 (learning starts after 100)
            raise KeyboardInterrupt
        return real_train(self, replay, rng)

    monkeypatch.setattr(td3.TD3, "train", interrupted)
    with pytest.raises(KeyboardInterrupt):
        Pipeline(tmp_path / "b", seed=3, config_path=cfg, progress=False, checkpoint_every=100).run_stage("control")
    assert (tmp_path / "b" / "control" / "checkpoint.pt").is_file()
    monkeypatch.setattr(td3.TD3, "train", real_train)
    Pipeline(tmp_path / "b", seed=3, config_path=None, progress=False, checkpoint_every=100).run_stage("control")
    a = NumpyActor.load(tmp_path / "a" / "controller.npz")
    b = NumpyActor.load(tmp_path / "b" / "controller.npz")
    assert np.array_equal(a.W1, b.W1) and np.array_equal(a.W3, b.W3)
    ca = (tmp_path / "a" / "control" / "curve.csv").read_text().splitlines()
    cb = (tmp_path / "b" / "control" / "curve.csv").read_text().splitlines()
    assert [r.split(",")[:4] for r in ca] == [r.split(",")[:4] for r in cb]


@pytest.mark.e2e  # runs a CLI as a subprocess
@pytest.mark.parametrize(("args", "message"), [
    (["--stage", "level9", "--out", "x"], "argument --stage: invalid choice: 'level9'"),
    (["--stage", "all"], "the following arguments are required: --out"),
    (["--stage", "control", "--out", "{tmp}/o", "--steps", "0"], "argument --steps: expected a positive integer"),
    (["--stage", "control", "--out", "{tmp}/o", "--seed", "-1"], "argument --seed: expected an integer in [0, 2^32)"),
    (["--stage", "level2", "--out", "{tmp}/o"], "stage level2 needs"),
    (["--stage", "control", "--out", "{tmp}/o", "--config", "{tmp}/bad.yaml"], "key 'td3.gamma': unknown key"),
    (["--stage", "control", "--out", "{tmp}/o", "--config", "{tmp}/missing.yaml"], "training config not found"),
])
def test_bad_cli_input_is_one_line_and_status_2(tmp_path, args, message):
    (tmp_path / "bad.yaml").write_text("td3: {gamma: 0.9}\n")
    r = _train([a.replace("{tmp}", str(tmp_path)) for a in args])
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], r.stderr


def test_bad_policy_dir_is_one_line(tmp_path):
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.errors import InputError
    from evoscen_sim.scenario_builders import build_bv_driver

    scen = config_from_dict({"bvs": {"driver": "learned"}, "models": {"learned": {"policy_dir": str(tmp_path)}}})
    with pytest.raises(InputError, match=r"models\.learned\.policy_dir = .*no training\.yaml"):
        build_bv_driver(scen)
    missing = tmp_path / "nowhere"
    scen = config_from_dict({"bvs": {"driver": "learned"}, "models": {"learned": {"policy_dir": str(missing)}}})
    with pytest.raises(InputError) as e:
        build_bv_driver(scen)
    assert str(e.value) == f"models.learned.policy_dir = {missing}: {missing} is not a directory"
    fallback = config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"},
                                 "models": {"learned": {"policy_dir": str(tmp_path), "on_missing": "level0"}}})
    from evoscen_bv.level0 import Level0Driver

    assert isinstance(build_bv_driver(fallback), Level0Driver)
    with pytest.raises(InputError, match=r"models\.learned\.on_missing.*expected one of error, level0"):
        config_from_dict({"models": {"learned": {"on_missing": "ignore"}}})


def test_settling_figures_by_hand():
    """Mean gap over all followers and steps, flips = consecutive |a| > 1 m/s² of opposite sign."""
    from evoscen_bv.pipeline import settling_figures

    gaps = np.array([[24.0, 26.0], [22.0, 28.0]])  # mean 25
    # follower 0: +2, -2, +2 (two flips); follower 1: +0.5, -3, -2 (0.5 is below 1 m/s²: none) -> 2 of 4 pairs
    accels = np.array([[2.0, 0.5], [-2.0, -3.0], [2.0, -2.0]])
    f = settling_figures(gaps, accels, 0, 25.0)
    assert f == {"settled_gap_m": 25.0, "flip_share": 0.5, "settling_collisions": 0, "settled": False}
    calm = np.array([[0.2, 0.1], [-0.3, 0.0], [0.1, 0.4]])
    assert settling_figures(gaps, calm, 0, 25.0)["settled"] is True
    assert settling_figures(gaps, calm, 0, 19.9)["settled"] is False  # 25 is 5.1 m off the target: outside g ± 5 m
    assert settling_figures(gaps, calm, 0, 20.0)["settled"] is True  # exactly 5 m off: inside
    assert settling_figures(gaps, calm, 1, 25.0)["settled"] is False  # a collision


def test_selection_prefers_a_settled_evaluation_over_a_better_return():
    from evoscen_bv.pipeline import selection_key

    evals = [{"step": 100, "eval_mean_return": -4.0, "settled": False},
             {"step": 200, "eval_mean_return": -5.0, "settled": True},
             {"step": 300, "eval_mean_return": -6.0, "settled": True}]
    assert max(evals, key=selection_key)["step"] == 200
    # none settled: the best return; evaluations without the check (decision stages) rank by return, then step
    assert max(evals[:1] + [{"step": 400, "eval_mean_return": -4.5, "settled": False}], key=selection_key)["step"] == 100
    assert max([{"step": 1, "eval_mean_return": -1.0}, {"step": 2, "eval_mean_return": -1.0}],
               key=selection_key)["step"] == 2


def test_training_options_are_plain_decimal_integers_in_range():
    """train_bv.py's --steps and --seed: decimal digits only (int() would take 1_000 and spaces), in range."""
    from evoscen_bv.training_config import training_seed, training_steps
    from evoscen_sim.errors import InputError
    from evoscen_sim.limits import MAX_TRAINING_STEPS

    assert training_steps("--steps", "2000") == 2000 and training_steps("--steps", "+7") == 7
    assert training_seed("--seed", "0") == 0 and training_seed("--seed", str(2**32 - 1)) == 2**32 - 1
    for text in ("0", "1_000", " 5", "0x10", "٣", str(MAX_TRAINING_STEPS + 1)):
        with pytest.raises(InputError) as err:
            training_steps("--steps", text)
        assert str(err.value) == (f"argument --steps: expected a positive integer (decimal digits, at most "
                                  f"{MAX_TRAINING_STEPS}), got {text!r}")
    with pytest.raises(InputError, match=r"^argument --seed: expected an integer in \[0, 2\^32\), got '4294967296'$"):
        training_seed("--seed", str(2**32))
