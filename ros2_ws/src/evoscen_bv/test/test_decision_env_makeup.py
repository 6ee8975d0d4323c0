"""The decision environment under ``env.makeup: highd`` (docs/learned-bvs.md, "Trained among the highD make-up")."""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_bv.environments import EGO_EDGE_M, DecisionEnv
from evoscen_bv.learned import load_policies, shipped_policy_dir
from evoscen_bv.truck import MakeupDriver, TruckDriver
from evoscen_bv.training_config import load_training_config
from evoscen_sim.errors import InputError
from evoscen_sim.road.road_model import load_road


@pytest.fixture(scope="module")
def road():
    return load_road()


@pytest.fixture(scope="module")
def policies():
    return load_policies(shipped_policy_dir() / "lc_calibrated")


def _config(tmp_path, makeup: str):
    (tmp_path / "t.yaml").write_text(f"env: {{makeup: {makeup}}}\n")
    return load_training_config(tmp_path / "t.yaml")


def test_makeup_key_defaults_to_uniform_and_a_bad_value_is_one_line(tmp_path):
    assert load_training_config().env.makeup == "uniform"
    assert _config(tmp_path, "highd").env.makeup == "highd"
    with pytest.raises(InputError, match=r"'env\.makeup' = 'mixed': expected one of uniform, highd") as e:
        _config(tmp_path, "mixed")
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("frozen", [False, True])
def test_highd_episode_puts_the_ego_in_a_car_inside_the_window_among_the_makeup(tmp_path, road, policies, frozen):
    cfg = _config(tmp_path, "highd")
    controller, mutual = policies[0], policies[1][1]
    env = DecisionEnv(road, cfg, "mutual", controller, mutual if frozen else None)
    for seed in (11, 12, 13):
        env.reset(seed)
        w = env.world
        p = w.window.p
        assert w.length[env.ego] <= 7.0  # a car
        truck = w.length > 7.0
        assert truck.sum() in (4, 5)  # 20 slots at a 0.229 share: floor(4.58) or one more
        # the traffic hosts every vehicle but the ego, trucks by the truck driver, cars by the car driver
        assert isinstance(env.traffic, MakeupDriver)
        np.testing.assert_array_equal(env.traffic.vehicles, np.delete(np.arange(w.n), env.ego))
        np.testing.assert_array_equal(np.sort(env.traffic.truck_driver.vehicles), np.flatnonzero(truck))
        cars = env.traffic.car_driver
        assert cars.speed_cap is False and env.ego_driver.speed_cap is False
        assert isinstance(env.traffic.truck_driver, TruckDriver)
        assert env.ego_bound is not None
    # the ego is drawn at least EGO_EDGE_M inside the window's edges (the start as drawn, before any step)
    rel = []
    for seed in range(40, 46):
        env2 = DecisionEnv(road, cfg, "mutual", controller, None)
        env2._advance_to_decision = lambda first: False  # the start as drawn, before any step
        env2.reset(seed)
        rel.append(float(env2.world.s[env2.ego] - env2.world.s[0]))
    assert all(-p.behind_m + EGO_EDGE_M <= r <= p.ahead_m - EGO_EDGE_M for r in rel)


def test_highd_episode_ends_truncated_when_the_window_takes_the_ego_out(tmp_path, road, policies):
    cfg = _config(tmp_path, "highd")
    env = DecisionEnv(road, cfg, "mutual", policies[0], None)
    env.reset(5)
    w = env.world
    # put the ego beyond the window's front edge and its exit margin: the next step takes it out
    p = w.window.p
    w.s[env.ego] = w.s[0] + p.ahead_m + p.exit_margin_m + 30.0
    w.refresh()
    _, _, terminal, truncated, info = env.step(np.array([0.0]))
    assert env.left and truncated and not terminal
    assert env.decisions == 1


def test_uniform_environment_is_the_loop_without_a_window(tmp_path, road, policies):
    cfg = _config(tmp_path, "uniform")
    env = DecisionEnv(road, cfg, "mutual", policies[0], None)
    env.reset(3)
    assert env.world.window is None and env.ego_bound is None and not env.left
    assert (env.world.length <= 7.0).all()
