"""The learned BVs' hard braking of the SUT's leader (docs/learned-bvs.md, "Hard braking")."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from evoscen_bringup.model_testing import commands_digest
from evoscen_bv.bv_models import LearnedParams, hard_brake_params
from evoscen_bv.learned import (
    HARD_BRAKE_VIEW_M,
    HardBrakeParams,
    HardBrakeState,
    LearnedDriver,
    load_policies,
    shipped_policy_dir,
)
from evoscen_contract.contract import ROLE_BV, ROLE_SUT
from evoscen_sim.errors import InputError
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.vehicle import VehicleParams
from evoscen_sim.road.road_model import load_road

MAX_BRAKE = VehicleParams().max_brake_mps2


def _view(s_leader: float, v_leader: float, step: int, dt_s: float, lane_change: int = 0):
    """Two vehicles in one lane: the SUT (index 0) at s = 0 and a BV (index 1) ahead of it."""
    return SimpleNamespace(role=np.array([ROLE_SUT, ROLE_BV]), s=np.array([0.0, s_leader]), d=np.zeros(2),
                           v=np.array([v_leader, v_leader]), length=np.array([4.5, 4.5]), width=np.array([1.8, 1.8]),
                           lane_change=np.array([0, lane_change]), step_index=step, dt_s=dt_s)


def test_episode_rate_matches_the_configured_rate_over_a_long_draw():
    """λ = 1 episode per km; the BV drives 100 m per step (100 m/s, dt 1 s) as the SUT's leader, and
    the odometer runs on the steps it is not braking (an episode lasts 1 step here). Episodes are a
    Poisson process in that distance D: N ~ Poisson(λD), so |N − λD| ≤ 4 √(λD) (4 σ) for the seeded draw,
    and the mean deceleration of U(4, 7) draws is 5.5 within 4 √(0.75 / N) (variance (7 − 4)²/12)."""
    p = HardBrakeParams(per_1000km=1000.0, decel_mps2=(4.0, 7.0), duration_s=(1.0, 1.0), min_speed_mps=10.0)
    hb = HardBrakeState(1, p, np.random.default_rng(12345))
    vehicles = np.array([1])
    odometer_m = 0.0
    for step in range(20000):
        view = _view(50.0, 100.0, step, 1.0)
        if not hb.until_step[0] > step:
            odometer_m += 100.0
        hb.bound(view, vehicles, np.zeros(1), VehicleParams())
    n, lam_d = len(hb.episodes), odometer_m / 1000.0
    assert abs(n - lam_d) <= 4.0 * math.sqrt(lam_d), (n, lam_d)
    decels = np.array([e[2] for e in hb.episodes])
    assert decels.min() >= 4.0 and decels.max() <= 7.0
    assert abs(decels.mean() - 5.5) <= 4.0 * math.sqrt(0.75 / n)


def test_no_episode_for_a_bv_that_is_not_the_sut_leader_in_view():
    p = HardBrakeParams(per_1000km=1.0e6)  # one per metre: any distance driven as the leader starts one
    vehicles = np.array([1])
    far = HardBrakeState(1, p, np.random.default_rng(0))
    changing = HardBrakeState(1, p, np.random.default_rng(0))
    slow = HardBrakeState(1, p, np.random.default_rng(0))
    for step in range(100):
        far.bound(_view(HARD_BRAKE_VIEW_M + 10.0, 30.0, step, 0.1), vehicles, np.zeros(1), VehicleParams())
        changing.bound(_view(50.0, 30.0, step, 0.1, lane_change=1), vehicles, np.zeros(1), VehicleParams())
        slow.bound(_view(50.0, p.min_speed_mps, step, 0.1), vehicles, np.zeros(1), VehicleParams())
    assert far.episodes == changing.episodes == slow.episodes == []


@pytest.fixture(scope="module")
def policies():
    return load_policies(shipped_policy_dir())


def test_the_sut_leader_brakes_at_the_drawn_deceleration_for_the_drawn_duration(policies):
    """SUT at 300 m, its leader BV at 340 m in lane 2, both 25 m/s. At a rate of one episode per metre
    the first one starts within a few steps; the BV's command is then −decel / 8 m/s² (the world's
    full brake) for round(duration / 0.1 s) steps, its speed falls by decel · duration, then the
    controller's throttle returns (no further episode: its odometer is set far away)."""
    controller, _, training = policies
    world = hand_built_world(load_road(), s=[300.0, 340.0], lane=[2, 2], speed=[25.0, 25.0],
                             roles=[ROLE_SUT, ROLE_BV])
    p = HardBrakeParams(per_1000km=1.0e6, decel_mps2=(4.0, 7.0), duration_s=(1.0, 2.0), min_speed_mps=5.0)
    drv = LearnedDriver(np.array([1]), controller, {}, training, np.random.default_rng(7), world.vehicle,
                        hard_brake=p)
    throttle = np.zeros(2)
    commands, speeds = [], []
    for _ in range(40):
        thr, _ = drv.act(world)
        if drv.hard_brake.episodes:
            drv.hard_brake.to_go_m[:] = 1.0e12
        commands.append(float(thr[0]))
        speeds.append(float(world.v[1]))
        throttle[1] = thr[0]
        world.step(throttle, np.zeros(2, dtype=np.int64))
        world.refresh()
    assert len(drv.hard_brake.episodes) == 1
    _, start, decel, duration = drv.hard_brake.episodes[0]
    n = round(duration / 0.1)
    assert 4.0 <= decel <= 7.0 and 1.0 <= duration <= 2.0 and start < 5
    assert commands[start:start + n] == pytest.approx([-decel / MAX_BRAKE] * n)
    assert commands[start + n] != pytest.approx(-decel / MAX_BRAKE)
    assert speeds[start] - speeds[start + n] == pytest.approx(decel * n * 0.1, abs=1e-6)


def test_an_episode_ends_at_the_speed_floor(policies):
    """Leader at 12 m/s, floor 10 m/s, 7 m/s² for 3 s: the episode ends once the speed is ≤ 10 m/s,
    i.e. after ceil(2 / 0.7) = 3 steps of braking (12 → 11.3 → 10.6 → 9.9), not after 30."""
    controller, _, training = policies
    world = hand_built_world(load_road(), s=[300.0, 340.0], lane=[2, 2], speed=[12.0, 12.0],
                             roles=[ROLE_SUT, ROLE_BV])
    p = HardBrakeParams(per_1000km=1.0e6, decel_mps2=(7.0, 7.0), duration_s=(3.0, 3.0), min_speed_mps=10.0)
    drv = LearnedDriver(np.array([1]), controller, {}, training, np.random.default_rng(1), world.vehicle,
                        hard_brake=p)
    drv.hard_brake.to_go_m[:] = 0.0  # the episode starts at the first step, at 12 m/s
    throttle = np.zeros(2)
    braking = []
    for _ in range(20):
        thr, _ = drv.act(world)
        if drv.hard_brake.episodes:
            drv.hard_brake.to_go_m[:] = 1.0e12
        braking.append(float(thr[0]) == pytest.approx(-7.0 / MAX_BRAKE))
        throttle[1] = thr[0]
        world.step(throttle, np.zeros(2, dtype=np.int64))
        world.refresh()
    assert sum(braking) == 3
    assert world.v[1] > 9.0


def test_keys_and_the_off_form():
    assert hard_brake_params(LearnedParams(hard_brake=False)) is None
    on = hard_brake_params(LearnedParams())
    assert on == HardBrakeParams(11.8, (4.0, 7.0), (1.0, 3.0), 10.0)
    with pytest.raises(InputError):
        hard_brake_params(LearnedParams(hard_brake_decel_min_mps2=6.0, hard_brake_decel_max_mps2=5.0))


BEFORE_COMMANDS_SHA256 = "32c3b0ffe38757126b4fba35ad04a0bfe3337e84ca1f40da26067bd612179748"
"""Every BV and SUT command of 1,000 steps of the default scenario with learned BVs, seed 3, SUT mobil,
computed with the code before the hard-braking rule existed (branch merge at 0abdd97); with the later
competitive BVs' rule at its earlier form (``competitive_cut_in: yield``)."""


def test_off_drives_exactly_as_before():
    assert commands_digest({"bvs.driver": "learned", "bvs.makeup": "uniform", "models.learned.hard_brake": False,
                            "models.learned.competitive_cut_in": "yield", "traffic.entry_retry_s": 0}, 1000) \
        == BEFORE_COMMANDS_SHA256  # and the entry rule of then (every step)


def test_rule_based_bvs_ignore_the_keys():
    for driver in ("level0", "mobil"):
        on = commands_digest({"bvs.driver": driver, "models.learned.hard_brake": True,
                               "models.learned.hard_brake_per_1000km": 1.0e6}, 200)
        off = commands_digest({"bvs.driver": driver, "models.learned.hard_brake": False}, 200)
        assert on == off, driver
