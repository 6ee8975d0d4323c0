"""SUMO's Krauss car following (evoscen_sut.krauss), expected values derived by hand.

Defaults (SUMO's passenger vType): a = 2.6, b = 4.5, e = 9.0 m/s², σ = 0.5, τ = 1 s, minGap 2.5 m;
Δt = 0.1 s, so b Δt = 0.45 m/s per step. SUMO gap g = bumper gap − 2.5 m.

* Continuous safe speed v_safe = −τb + √((τb)² + v_l² + 2 b g).
* Per-step (Euler) safe speed: leader braking distance D = Δt (k v_l − b Δt k (k+1)/2), k = ⌊v_l/(b Δt)⌋;
  G = g + D − 0.001; n = ⌊1/2 − (τ − √((2τ − Δt)² + 8 G / b) / 2) / Δt⌋, h = n (n−1) b Δt²/2 + n b Δt τ,
  x = n b Δt + (G − h)/(n Δt + τ).
* Free-road mean speed with dawdling: v_max − σ a Δt / 2 (= 33.33 − 0.065 = 33.265 m/s), see the module.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.vehicle import VehicleParams, accel_to_throttle
from evoscen_sim.road.road_model import load_road
from evoscen_sut.krauss import (
    KraussCarFollowing,
    KraussParams,
    krauss_next_speed,
    krauss_safe_speed,
    sumo_follow_speed,
)

DT = 0.1
P = KraussParams()
P0 = KraussParams(sigma=0.0)
VP = VehicleParams()
V_MAX = 33.33  # desired speed (the road's limit is 120 km/h = 33.333 m/s)


@pytest.fixture(scope="module")
def road():
    return load_road()


def one(x) -> float:
    return float(np.asarray(x).ravel()[0])


# ------------------------------------------------------------------ safe speed
def test_continuous_safe_speed_by_hand() -> None:
    # τb = 4.5; (τb)² + v_l² + 2bg = 20.25 + 100 + 36 = 156.25 = 12.5² -> 12.5 - 4.5 = 8
    assert one(krauss_safe_speed(4.0, 10.0, 1.0, 4.5)) == pytest.approx(8.0, abs=1e-12)
    # no gap, leader stopped: 0; no leader: inf; a gap so negative that the radicand is < 0: 0
    got = krauss_safe_speed(np.array([0.0, np.inf, 20.0, -100.0]), np.array([0.0, np.nan, np.nan, 0.0]), 1.0, 4.5)
    assert got[0] == pytest.approx(0.0, abs=1e-12)
    assert got[1] == math.inf and got[2] == math.inf and got[3] == 0.0
    # vectorized, broadcasting: τ = 2, b = 2: -4 + √(16 + 0 + 4 g) for g = 0, 5, 32 -> 0, 2, 8
    assert krauss_safe_speed(np.array([0.0, 5.0, 32.0]), 0.0, 2.0, 2.0) == pytest.approx([0.0, 2.0, 8.0])


def test_euler_safe_speed_behind_a_stopped_leader_by_hand() -> None:
    # G = 7.0 (bumper gap 9.501): √(1.9² + 8·7/4.5) = √16.0544 = 4.0068, n = ⌊0.5 + 10.034⌋ = 10,
    # h = 0.0225·90 + 4.5 = 6.525, x = 4.5 + (7 - 6.525)/(1 + 1) = 4.7375
    assert one(sumo_follow_speed(9.501, 4.7, 0.0, P, DT)) == pytest.approx(4.7375, abs=1e-9)
    # at or below minGap + 1 mm the follower must stand
    assert one(sumo_follow_speed(2.5005, 0.0, 0.0, P, DT)) == 0.0
    # no leader: no constraint
    assert one(sumo_follow_speed(np.inf, 20.0, np.nan, P, DT)) == math.inf


def test_euler_safe_speed_behind_a_moving_leader_by_hand() -> None:
    # leader at 2 m/s: k = ⌊2/0.45⌋ = 4, D = 0.1 (4·2 - 0.45·4·5/2) = 0.35; g = 6.651 -> G = 7.0 as above
    assert one(sumo_follow_speed(6.651 + 2.5, 4.7, 2.0, P, DT)) == pytest.approx(4.7375, abs=1e-9)


def test_emergency_braking_by_hand() -> None:
    # v = 20, v_l = 5, g = 10 (bumper 12.5): the stop speed needs ≫ b, so SUMO's emergency deceleration:
    # b1 = v²/(2 (g + v_l²/(2b))) = 400/(2·12.778) = 15.65 > b -> b2 = (400 - 25)/(2·10) = 18.75,
    # ×1.2 = 22.5 m/s² -> follow speed 20 - 2.25 = 17.75
    assert one(sumo_follow_speed(12.5, 20.0, 5.0, P, DT)) == pytest.approx(17.75, abs=1e-9)
    # the next speed is limited by emergencyDecel: max(17.75, 20 - 0.9) = 19.1 -> a = -9
    v1 = one(krauss_next_speed(20.0, V_MAX, 12.5, 5.0, 0.0, P0, DT))
    assert (v1 - 20.0) / DT == pytest.approx(-9.0, abs=1e-9)
    # with emergencyDecel = decel the vehicle brakes at decel only: 20 - 0.45
    p = KraussParams(sigma=0.0, emergency_decel_mps2=4.5)
    assert one(krauss_next_speed(20.0, V_MAX, 12.5, 5.0, 0.0, p, DT)) == pytest.approx(19.55, abs=1e-9)


def test_next_speed_dawdling_branches_by_hand() -> None:
    # free road, v = 30: v_high = 30.26, dawdle σ a Δt U = 0.5·2.6·0.1·0.5 = 0.065
    assert one(krauss_next_speed(30.0, V_MAX, np.inf, np.nan, 0.5, P, DT)) == pytest.approx(30.195, abs=1e-12)
    # slow (v_high = 1.26 < a): dawdle σ v_high Δt U = 0.5·1.26·0.1·0.5 = 0.0315
    assert one(krauss_next_speed(1.0, V_MAX, np.inf, np.nan, 0.5, P, DT)) == pytest.approx(1.2285, abs=1e-12)
    # dawdling never brakes below v - b Δt (v_min): v = 0.1, U -> 1 keeps 0.1 + 0.26 - ... >= 0
    assert one(krauss_next_speed(0.0, V_MAX, np.inf, np.nan, 0.999, P, DT)) == pytest.approx(0.26 - 0.5 * 0.26 * 0.0999)
    # above the cap (e.g. a lower limit): comfortable deceleration b, not more (SUMO: "speed limits are
    # not emergencies"); dawdling cannot brake below v - b Δt either
    assert one(krauss_next_speed(30.0, 20.0, np.inf, np.nan, 0.9, P, DT)) == pytest.approx(29.55, abs=1e-12)
    assert one(krauss_next_speed(30.0, 20.0, np.inf, np.nan, 0.0, P, DT)) == pytest.approx(29.55, abs=1e-12)


# ------------------------------------------------------------------ the driver API on a world
def test_sigma_zero_free_road_gives_exactly_v_max(road) -> None:
    world = hand_built_world(road, s=[100.0, 400.0], lane=[2, 3], speed=[V_MAX, 30.0])
    kcf = KraussCarFollowing(P0, np.random.default_rng(0), DT)
    acc = kcf.acceleration(world, np.array([0, 1]))
    assert acc[0] == 0.0  # at v_max: no change at all
    assert acc[1] == pytest.approx(P0.accel_mps2, abs=1e-9)  # below: full acceleration
    # desired speed above the lane limit (120 km/h): capped by the limit
    fast = KraussCarFollowing(KraussParams(sigma=0.0, desired_speed_mps=40.0), np.random.default_rng(0), DT)
    w2 = hand_built_world(road, s=[100.0], lane=[2], speed=[33.3])
    assert one(fast.acceleration(w2, np.array([0]))) == pytest.approx((100.0 / 3.0 - 33.3) / DT, abs=1e-9)
    # held over time through the bicycle world: exactly v_max every step
    for _ in range(50):
        a = kcf.acceleration(world, np.array([0]))
        world.step(np.concatenate([accel_to_throttle(a, VP), [0.0]]), np.zeros(2, dtype=np.int64))
        assert world.v[0] == pytest.approx(V_MAX, abs=1e-12)


def test_free_road_mean_speed_is_dawdling_reduced(road) -> None:
    """Mean free speed v_max − σ a Δt / 2 = 33.265 m/s; speeds in (v_max − σ a Δt, v_max].

    Std of one speed σ a Δt / √12 = 0.0375 m/s, of the mean of 4000 independent steps 0.0006 m/s:
    tolerance 0.003 m/s (5 standard deviations).
    """
    world = hand_built_world(road, s=[100.0], lane=[2], speed=[25.0])
    kcf = KraussCarFollowing(P, np.random.default_rng(7), DT)
    speeds = []
    for k in range(4200):
        a = kcf.acceleration(world, np.array([0]))
        world.step(accel_to_throttle(a, VP), np.zeros(1, dtype=np.int64))
        if k >= 200:  # 25 -> 33.3 m/s takes ~3.3 s
            speeds.append(world.v[0])
    v = np.array(speeds)
    width = P.sigma * P.accel_mps2 * DT
    assert v.min() >= V_MAX - width - 1e-9 and v.max() <= V_MAX + 1e-9
    assert v.mean() == pytest.approx(V_MAX - width / 2.0, abs=0.003)


@pytest.mark.parametrize("start_s", [600.0, 1080.0])
def test_approach_to_stopped_leader_stops_without_collision(road, start_s) -> None:
    """From 33 m/s towards a stopped leader at s = 1200 m (lane 2), far (595 m gap) and close (115 m gap).

    Close: stopping within 115 m from 33 m/s needs ≈ 33²/(2·(115 − 2.5)) = 4.8 m/s² > b, with the τ = 1 s
    headway SUMO's emergency branch brakes harder still (world brake limit 8 m/s²). The follower must stop
    without a collision and creep up to the standstill gap minGap (+1 mm).
    """
    world = hand_built_world(road, s=[start_s, 1200.0], lane=[2, 2], speed=[33.0, 0.0])
    kcf = KraussCarFollowing(P, np.random.default_rng(3), DT)
    collisions = []
    min_gap = np.inf
    for _ in range(800):
        a = kcf.acceleration(world, np.array([0]))
        res = world.step(np.concatenate([accel_to_throttle(a, VP), [0.0]]), np.zeros(2, dtype=np.int64))
        collisions += res.collisions
        min_gap = min(min_gap, world.neighborhood().own_gap_m[0])
    gap = world.neighborhood().own_gap_m[0]
    assert collisions == []
    assert world.v[1] == 0.0 and world.lane[0] == 2
    assert world.v[0] == pytest.approx(0.0, abs=1e-3)
    assert min_gap >= P.min_gap_m  # never inside minGap (observed: 2.501 m throughout the creep)
    assert gap == pytest.approx(P.min_gap_m + 0.001, abs=0.01)  # minGap + NUMERICAL_EPS


def test_lane_offset_selects_the_leader_lane(road) -> None:
    # vehicle 0 in lane 2 at 30 m/s; a stopped vehicle 20 m ahead in lane 3 (left), nobody ahead in lane 2
    world = hand_built_world(road, s=[500.0, 524.8, 800.0], lane=[2, 3, 1], speed=[30.0, 0.0, 30.0])
    kcf = KraussCarFollowing(P0, np.random.default_rng(0), DT)
    acc = kcf.acceleration(world, np.array([0, 0, 2]), lane_offset=np.array([0, 1, 0]))
    assert acc[0] == pytest.approx(P0.accel_mps2, abs=1e-9)  # own lane: free road
    assert acc[1] == pytest.approx(-P0.emergency_decel_mps2, abs=1e-9)  # left lane: hard braking
    assert acc[2] == pytest.approx(P0.accel_mps2, abs=1e-9)
    with pytest.raises(ValueError):
        kcf.acceleration(world, np.array([0]), lane_offset=np.array([3]))


def test_vectorized_equals_elementwise(road) -> None:
    world = hand_built_world(road, s=[100.0, 130.0, 170.0, 175.0, 400.0], lane=[2, 2, 2, 3, 4],
                             speed=[30.0, 20.0, 10.0, 5.0, 33.0])
    vehicles = np.array([4, 0, 1, 2])
    acc = KraussCarFollowing(P, np.random.default_rng(11), DT).acceleration(world, vehicles)
    u = np.random.default_rng(11).random(4)  # one draw per vehicle, in the order of `vehicles`
    nb = world.neighborhood()
    for k, i in enumerate(vehicles):
        v1 = one(krauss_next_speed(world.v[i], V_MAX, nb.own_gap_m[i], nb.leader_speed_mps[i, 2], u[k], P, DT))
        assert acc[k] == pytest.approx((v1 - world.v[i]) / DT, abs=1e-12)


def test_deterministic_given_the_seed(road) -> None:
    world = hand_built_world(road, s=[100.0, 140.0, 300.0], lane=[2, 2, 3], speed=[33.0, 25.0, 33.3])
    idx = np.array([0, 1, 2])
    a = KraussCarFollowing(P, np.random.default_rng(5), DT)
    b = KraussCarFollowing(P, np.random.default_rng(5), DT)
    for _ in range(20):
        np.testing.assert_array_equal(a.acceleration(world, idx), b.acceleration(world, idx))
    other = KraussCarFollowing(P, np.random.default_rng(6), DT).acceleration(world, idx)
    assert not np.array_equal(other, KraussCarFollowing(P, np.random.default_rng(5), DT).acceleration(world, idx))
    # exactly one draw per vehicle per call
    rng = np.random.default_rng(9)
    KraussCarFollowing(P, rng, DT).acceleration(world, idx)
    expected = np.random.default_rng(9)
    expected.random(3)
    assert rng.random() == expected.random()


def test_acceleration_bounded_by_accel_and_emergency_decel() -> None:
    rng = np.random.default_rng(1)
    n = 200_000
    v = rng.uniform(0.0, 40.0, n)
    v_max = rng.uniform(5.0, 40.0, n)
    gap = rng.uniform(-5.0, 200.0, n)
    gap[rng.random(n) < 0.1] = np.inf
    vl = np.where(np.isfinite(gap), rng.uniform(0.0, 40.0, n), np.nan)
    v1 = krauss_next_speed(v, v_max, gap, vl, rng.random(n), P, DT)
    acc = (v1 - v) / DT
    assert np.all(v1 >= 0.0)
    assert acc.max() <= P.accel_mps2 + 1e-9
    assert acc.min() >= -P.emergency_decel_mps2 - 1e-9
    # the emergency range is reached, and so is full acceleration
    assert acc.min() < -P.decel_mps2 - 1.0 and acc.max() > P.accel_mps2 - 0.01
