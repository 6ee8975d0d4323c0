"""The shipped policies (``share/evoscen_bv/policies``) behave as designed, on fixed seeds.

* Free car following: a column of learned BVs behind a leader at constant speed holds a
  mean gap in the designed band g ± 5 m = [20, 30] m (g = 25 m) with no rear-end collision.
* The 20-BV default scenario with learned BVs (mix 4:3:3, seeds 1-4, 300 s each = 6.7
  vehicle-hours; the run-time rule profile the policies were trained with, docs/bv-profiles.md): lane changes per vehicle-hour order as competitive > mutual > cooperative
  (docs/method.md §3.3) and collisions among learned BVs are rare (at most 2; docs/learned-bvs.md
  gives the measured rate).

``EVOSCEN_POLICY_DIR`` points the tests at another policy directory (a training output).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from evoscen_bv.learned import LearnedDriver, load_policies, shipped_policy_dir
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.road.road_model import load_road

POLICY_DIR = Path(os.environ.get("EVOSCEN_POLICY_DIR") or shipped_policy_dir())
TARGET_BAND_M = (20.0, 30.0)


@pytest.fixture(scope="module")
def policies():
    return load_policies(POLICY_DIR)


def test_controller_holds_the_target_gap_without_rear_end_collisions(policies):
    controller, _, training = policies
    road = load_road()
    # leader (0) at 24 m/s in lane 2; four learned followers start 60, 50, 15 and 35 m apart, at mixed speeds
    s = [200.0, 135.2, 80.4, 60.6, 20.8]  # 70 s at 24 m/s ends before the road does
    w = hand_built_world(road, s=s, lane=[2] * 5, speed=[24.0, 28.0, 20.0, 26.0, 24.0])
    followers = LearnedDriver(np.arange(1, 5), controller, {}, training, np.random.default_rng(0), w.vehicle)
    gaps, collisions = [], 0
    for k in range(700):
        throttle = np.zeros(5)
        throttle[1:] = followers.throttle(w)
        collisions += len(w.step(throttle, np.zeros(5, dtype=np.int64)).collisions)
        if k >= 300:  # after the approach
            gaps.append(w.neighborhood().gap_front_m[1:, 2].copy())
    gaps = np.array(gaps)
    assert collisions == 0
    lo, hi = TARGET_BAND_M
    assert lo <= gaps.mean() <= hi, gaps.mean(axis=0)  # measured 29.8 m (the shipped set; the set before it 25.4 m)
    assert np.all(gaps > 5.0)


def _lane_changes_and_collisions(seed: int, steps: int) -> tuple[dict[int, float], dict[int, float], int, float]:
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config

    # the run-time rule profile the policies were trained with (their training.yaml's env.profile;
    # the shipped ones: safety_net): the policies are checked under the rules they were designed for
    trained_with = load_policies(POLICY_DIR)[2].env.profile
    cfg = load_scenario_config(None, {"bvs.driver": "learned", "bvs.makeup": "uniform", "seed": seed,
                                      "models": {"learned": {"policy_dir": str(POLICY_DIR), "profile": trained_with}}})
    sc = build_scenario(cfg)
    w = sc.world
    bvs = np.arange(1, w.n)
    collisions_bv = 0
    for _ in range(steps):
        result = sc.step()
        collisions_bv += sum(1 for i, j in result.collisions if i in bvs and j in bvs)
    hours = steps * w.dt_s / 3600.0
    per_hour, count = {}, {}
    for code in (1, 2, 3):
        members = bvs[w.policy[bvs] == code]
        per_hour[code] = float(w.lane_change_count[members].sum()) / (members.size * hours)
        count[code] = members.size
    return per_hour, count, collisions_bv, hours * bvs.size


def test_competitive_changes_lanes_most_and_collisions_are_rare():
    rates = {1: 0.0, 2: 0.0, 3: 0.0}
    collisions, vehicle_hours = 0, 0.0
    seeds = (1, 2, 3, 4)
    for seed in seeds:
        per_hour, _, coll, vh = _lane_changes_and_collisions(seed, 3000)
        for code in rates:
            rates[code] += per_hour[code] / len(seeds)
        collisions += coll
        vehicle_hours += vh
    mutual, competitive, cooperative = rates[1], rates[2], rates[3]
    # the method's order (docs/method.md §3.3): competitive changes lanes most, cooperative rarely, mutual in between
    assert competitive > mutual > cooperative, rates
    # rare: at most two collisions among learned BVs in the 6.7 vehicle-hours (measured: none; lane changes per
    # vehicle-hour competitive 118.5 > mutual 79.0 > cooperative 28.5)
    assert collisions <= 2, (collisions, vehicle_hours)


def test_first_set_is_selectable_and_records_its_training_profile():
    """``policy_dir: v0.1.0`` loads the first shipped set (kept selectable); it was trained under safety_net."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config

    first = shipped_policy_dir() / "v0.1.0"
    assert load_policies(first)[2].env.profile == "safety_net"
    assert load_policies(shipped_policy_dir())[2].env.profile == "driver"
    cfg = load_scenario_config(None, {"steps": 20, "bvs.driver": "learned", "models.learned.policy_dir": "v0.1.0",
                                      "models.learned.profile": "safety_net"})
    sc = build_scenario(cfg)
    for _ in range(20):
        sc.step()
    assert sc.world.step_index == 20


def test_source_tree_fallback_finds_the_policies():
    """Without an installed workspace (no AMENT_PREFIX_PATH) the shipped policies are found in
    the source tree, ros2_ws/src/evoscen_bv/policies (the fallback pointed into the Python
    package, where no policies are, in 0.1.0's first form)."""
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "AMENT_PREFIX_PATH"}
    out = subprocess.run([sys.executable, "-c", "from evoscen_bv.learned import shipped_policy_dir; "
                          "print(shipped_policy_dir())"], env=env, capture_output=True, text=True, check=True)
    path = Path(out.stdout.strip())
    src = Path(__file__).resolve().parents[1]  # ros2_ws/src/evoscen_bv
    assert path == src / "policies" and path.is_dir()
    assert any(path.iterdir())


def test_shipped_keyword_follows_the_makeup_and_every_set_is_selectable():
    """``policy_dir: shipped`` is the make-up's set (docs/learned-bvs.md, "Trained among the highD
    make-up"): ``uniform`` the 0.6.0 set, ``highd`` the set trained among it; each set by name too."""
    from evoscen_bv.bv_models import shipped_set

    assert shipped_set("shipped", "uniform") == "" and shipped_set("v0.6.0", "highd") == ""
    assert shipped_set("shipped", "highd") == "highd_trained" == shipped_set("highd_trained", "uniform")
    assert shipped_set("lc_calibrated", "highd") == "lc_calibrated"
    assert shipped_set("v0.1.0", "highd") == "v0.1.0"
    calibrated = load_policies(shipped_policy_dir() / "lc_calibrated")[2].reward
    before = load_policies(shipped_policy_dir())[2].reward
    # one factor on the three lane-change costs, the other rewards as before
    k = calibrated.lane_change_penalty / before.lane_change_penalty
    assert k > 1.0
    assert calibrated.comp_lane_change_penalty == pytest.approx(k * before.comp_lane_change_penalty)
    assert calibrated.coop_lane_change_penalty == pytest.approx(k * before.coop_lane_change_penalty)
    assert calibrated.request_penalty == before.request_penalty and calibrated.theta_left == before.theta_left
    # the controller is the 0.6.0 set's, byte for byte
    assert (shipped_policy_dir() / "lc_calibrated" / "controller.npz").read_bytes() == \
        (shipped_policy_dir() / "controller.npz").read_bytes()


def test_highd_trained_set_is_the_calibrated_costs_trained_among_the_makeup():
    """``highd_trained``: the training config of ``lc_calibrated`` (the same costs, k = 10) but for
    ``env.makeup: highd``; the 0.6.0 controller, byte for byte."""
    trained = load_policies(shipped_policy_dir() / "highd_trained")[2]
    calibrated = load_policies(shipped_policy_dir() / "lc_calibrated")[2]
    assert trained.env.makeup == "highd" and calibrated.env.makeup == "uniform"
    assert trained.reward == calibrated.reward and trained.td3 == calibrated.td3
    assert trained.steps == calibrated.steps and trained.car_following == calibrated.car_following
    assert (shipped_policy_dir() / "highd_trained" / "controller.npz").read_bytes() == \
        (shipped_policy_dir() / "controller.npz").read_bytes()
