"""MOBIL lane changes (evoscen_sut.mobil), hand-built situations with hand-derived decisions.

IDM used by the decisions (MobilParams defaults, docs/method.md §4.2 highway values):
    a = a_max [1 − (v/v0)^4 − (s*/s)²],  s* = s0 + max(0, v T + v Δv / (2 √(a_max b))),
    a_max = 1.0, b = 1.5, T = 1.0 s, s0 = 2 m, v0 = 120 km/h = 33.33 m/s (the road's limit).
Criteria (asymmetric, defaults p = 0.25, Δa_th = 0.1, Δa_bias = 0.2, b_safe = 4):
    left:  ã_c − a_c + p (ã_n − a_n) > Δa_th + Δa_bias = 0.3
    right: min(ã_c, a_c) − a_c + p (ã_o − a_o) > Δa_th − Δa_bias = −0.1
    safety: ã_n ≥ −4 and ã_c ≥ −4.
Vehicles are 4.8 m long, so a bumper gap g means centres g + 4.8 m apart.
Road: lane 0 (merge lane) exists for 600 ≤ s ≤ 960 (stop point 960 − 15 = 945), lanes 1..4 everywhere.
"""

from __future__ import annotations

import math
from dataclasses import fields, replace

import numpy as np
import pytest
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.vehicle import VehicleParams
from evoscen_sim.road.road_model import load_road
from evoscen_sut import mobil
from evoscen_sut.krauss import KraussCarFollowing, KraussParams, sumo_follow_speed
from evoscen_sut.krauss_lane_change import KraussLaneChangeDriver, settled
from evoscen_sut.mobil import MobilParams, evaluate, lane_change_decision

L = 4.8
V0 = 120.0 / 3.6
P = MobilParams()
EGO = np.array([0])


@pytest.fixture(scope="module")
def road():
    return load_road()


def idm(v: float, gap: float = math.inf, v_lead: float = math.nan) -> float:
    """IDM with the MOBIL defaults, written out (clip at −9 m/s²)."""
    free = 1.0 - (v / V0) ** 4
    if math.isinf(gap):
        return free
    s_star = 2.0 + max(0.0, v * 1.0 + v * (v - v_lead) / (2.0 * math.sqrt(1.0 * 1.5)))
    return max(free - (s_star / gap) ** 2, -9.0)


def decide(world, params: MobilParams = P, vehicles=EGO) -> np.ndarray:
    return lane_change_decision(world, np.asarray(vehicles), params)


# ------------------------------------------------------------------ parameters
def test_defaults_and_sources() -> None:
    assert (P.politeness, P.threshold_mps2, P.bias_mps2, P.safe_decel_mps2) == (0.25, 0.1, 0.2, 4.0)
    assert (P.accel_mps2, P.comfort_decel_mps2, P.time_headway_s, P.min_gap_m, P.delta) == (1.0, 1.5, 1.0, 2.0, 4.0)
    assert P.desired_speed_mps == pytest.approx(V0)
    assert mobil.SPEC.name == "mobil" and set(mobil.SPEC.roles) == {"sut", "bv"}
    assert mobil.SPEC.params_type is MobilParams


def test_parameters_are_declared_for_config_validation() -> None:
    # every field carries a checker (evoscen_sim.config.scenario_config.number/flag), so models.mobil is validated
    assert all("check" in f.metadata for f in fields(MobilParams))
    assert fields(MobilParams)[0].metadata["check"](0.5) == 0.5
    with pytest.raises(Exception, match=r"expected a number in \[0, 5\]"):
        fields(MobilParams)[0].metadata["check"](-1.0)


# ------------------------------------------------------------------ decisions
def test_slow_leader_free_left_lane_changes_left(road) -> None:
    # ego lane 1 at 25 m/s, leader 25.2 m ahead (bumper) at 20 m/s; lane 2 empty; lane 0 absent at s = 300
    w = hand_built_world(road, s=[300.0, 330.0], lane=[1, 1], speed=[25.0, 20.0])
    ev = evaluate(w, EGO, P)
    a_c = idm(25.0, 25.2, 20.0)  # s* = 27 + 125/2.449 = 78.03 -> 1 - 0.3164 - 9.588 = -8.904
    at_c = idm(25.0)  # free: 1 - 0.75^4 = 0.6836
    assert a_c == pytest.approx(-8.904, abs=1e-3) and at_c == pytest.approx(0.6836, abs=1e-4)
    assert ev.acc_ego[0, 1] == pytest.approx(a_c, rel=1e-9)
    assert ev.acc_ego[0, 2] == pytest.approx(at_c, rel=1e-9)
    assert ev.incentive[0, 2] == pytest.approx(at_c - a_c - 0.3, rel=1e-9)
    assert not ev.exists[0, 0]  # lane 0 does not exist at s = 300
    assert decide(w)[0] == 1


def test_fast_vehicle_closing_from_behind_blocks_the_change(road) -> None:
    # as above, plus a vehicle in lane 2 with a 10.2 m bumper gap behind the ego at 35 m/s:
    # ã_n = IDM(35, gap 10.2, leader 25): s* = 37 + 350/2.449 = 179.9 -> clipped to -9 < -4: unsafe
    w = hand_built_world(road, s=[300.0, 330.0, 285.0], lane=[1, 1, 2], speed=[25.0, 20.0, 35.0])
    ev = evaluate(w, EGO, P)
    assert ev.acc_new_follower[0, 2] == pytest.approx(idm(35.0, 10.2, 25.0)) == pytest.approx(-9.0)
    assert not ev.safe[0, 2]
    assert ev.incentive[0, 2] > 0  # advantageous, yet unsafe
    assert decide(w)[0] == 0
    # the same follower 120 m behind (bumper): ã_n = 1 − 1.2155 − (179.9/120)² = −2.46 ≥ −4: safe -> +1
    w = hand_built_world(road, s=[300.0, 330.0, 175.2], lane=[1, 1, 2], speed=[25.0, 20.0, 35.0])
    an = idm(35.0, 120.0, 25.0)
    assert an == pytest.approx(-2.46, abs=1e-2)
    ev = evaluate(w, EGO, P)
    assert ev.acc_new_follower[0, 2] == pytest.approx(an, rel=1e-9)
    assert ev.safe[0, 2]
    assert decide(w)[0] == 1


def test_merge_lane_near_its_end_changes_onto_the_mainline(road) -> None:
    # ego on lane 0 at s = 900, 20 m/s, lane 1 empty. Stop point 945: gap 945 - 902.4 = 42.6 m
    w = hand_built_world(road, s=[900.0], lane=[0], speed=[20.0])
    ev = evaluate(w, EGO, P)
    a_c = idm(20.0, 42.6, 0.0)  # s* = 22 + 400/2.449 = 185.3 -> -18 -> clipped -9
    assert a_c == -9.0 and ev.acc_ego[0, 1] == pytest.approx(a_c)
    assert ev.mandatory[0]  # 42.6 m < 100 m: only the safety criteria count
    assert decide(w)[0] == 1
    # by the incentive alone (no mandatory rule): ã_c − a_c = 0.8704 + 9 > Δa_th − Δa_bias = −0.1
    assert decide(w, replace(P, merge_mandatory_distance_m=0.0))[0] == 1
    # early on the merge lane (s = 650, stop gap 292.6 m): a_c = 0.8704 − (185.3/292.6)² = 0.469 ...
    w = hand_built_world(road, s=[650.0], lane=[0], speed=[20.0])
    ev = evaluate(w, EGO, P)
    s_star = 22.0 + 400.0 / (2.0 * math.sqrt(1.5))
    assert ev.acc_ego[0, 1] == pytest.approx(1 - 0.6**4 - (s_star / 292.6) ** 2, rel=1e-9)
    # ... and ã_c = 0.8704: ã_c − a_c = 0.401, the bias points to the mainline: 0.401 − (0.1 − 0.2) > 0 -> +1
    assert ev.incentive[0, 2] == pytest.approx((1 - 0.6**4) - ev.acc_ego[0, 1] + 0.1, rel=1e-9)
    assert decide(w)[0] == 1


def test_merge_lane_vehicle_alongside_blocks(road) -> None:
    # lane 1 vehicle level with the ego (bodies overlap longitudinally): ã_n = −9 -> keep
    w = hand_built_world(road, s=[900.0, 900.0], lane=[0, 1], speed=[20.0, 20.0])
    assert decide(w)[0] == 0


def test_mainline_vehicle_never_enters_the_merge_lane(road) -> None:
    # ego lane 1 at s = 700 behind a slow leader; lane 2 blocked alongside; lane 0 free but ending
    w = hand_built_world(road, s=[700.0, 725.0, 700.0], lane=[1, 1, 2], speed=[25.0, 15.0, 25.0])
    ev = evaluate(w, EGO, P)
    assert bool(road.lane_exists(0, 700.0)) and not ev.exists[0, 0]
    assert decide(w)[0] == 0
    assert decide(w, replace(P, enter_ending_lane=True, asymmetric=False))[0] == -1


def test_empty_road_keeps_lane(road) -> None:
    # rightmost mainline lane, nothing around: left incentive 0 − 0.3 < 0, right lane does not exist
    w = hand_built_world(road, s=[300.0], lane=[1], speed=[30.0])
    assert decide(w)[0] == 0


def test_keep_right_returns_to_a_free_right_lane(road) -> None:
    # ego lane 3, lane 2 free: min(ã_c, a_c) − a_c + 0 = 0 > −0.1 -> −1
    w = hand_built_world(road, s=[300.0], lane=[3], speed=[30.0])
    ev = evaluate(w, EGO, P)
    assert ev.incentive[0, 0] == pytest.approx(0.1)
    assert decide(w)[0] == -1
    # symmetric MOBIL has no keep-right motive: 0 − 0.1 < 0 -> keep
    assert decide(w, replace(P, asymmetric=False))[0] == 0
    # a disadvantage on the right: a slower vehicle 20.2 m ahead in lane 2 at 25 m/s:
    # ã_c = IDM(30, 20.2, 25) = 1 − 0.656 − (s*=32+150/2.449=93.2 / 20.2)² < −9 -> incentive −9 + ... < −0.1
    w = hand_built_world(road, s=[300.0, 325.0], lane=[3, 2], speed=[30.0, 25.0])
    assert decide(w)[0] == 0


def test_no_overtaking_on_the_right(road) -> None:
    # ego lane 3 at 30 m/s behind a 25 m/s leader (bumper gap 40 m); lane 2 free; lane 4 blocked
    w = hand_built_world(road, s=[300.0, 344.8, 300.0], lane=[3, 3, 4], speed=[30.0, 25.0, 30.0])
    ev = evaluate(w, EGO, P)
    a_c = idm(30.0, 40.0, 25.0)
    assert ev.acc_ego[0, 1] == pytest.approx(a_c, rel=1e-9)
    # asymmetric: the right lane cannot give more than a_c (v = 30 > 16.7 m/s): incentive 0 + 0.1
    assert ev.incentive[0, 0] == pytest.approx(0.1)
    # symmetric: the free right lane is a gain of ã_c − a_c = 0.3439 − a_c
    ev_sym = evaluate(w, EGO, replace(P, asymmetric=False))
    assert ev_sym.incentive[0, 0] == pytest.approx(idm(30.0) - a_c - 0.1, rel=1e-9)


def test_politeness_changes_the_outcome(road) -> None:
    # ego lane 1 at 25 m/s behind a 24 m/s leader (bumper gap 40): a_c = 1 − 0.3164 − (37.21/40)² = −0.182;
    # left lane 2: free ahead (ã_c = 0.6836), new follower 40 m behind at 28 m/s:
    # a_n = 1 − (28/33.33)^4 = 0.502 (free), ã_n = 0.502 − ((30 + 84/2.449)/40)² = −2.08 (≥ −4: safe).
    w = hand_built_world(road, s=[300.0, 344.8, 255.2], lane=[1, 1, 2], speed=[25.0, 24.0, 28.0])
    a_c, at_c = idm(25.0, 40.0, 24.0), idm(25.0)
    a_n, at_n = idm(28.0), idm(28.0, 40.0, 25.0)
    assert a_c == pytest.approx(-0.182, abs=1e-3)
    assert at_n == pytest.approx(-2.08, abs=1e-2) and at_n >= -4.0
    gain_ego = at_c - a_c  # 0.866: small for the ego ...
    gain_n = at_n - a_n  # −2.58: ... costly for the new follower
    ev = evaluate(w, EGO, P)
    assert ev.gain_new_follower[0, 2] == pytest.approx(gain_n, rel=1e-9)
    assert ev.safe[0, 2]
    # p = 0: 0.866 − 0.3 > 0 -> change; p = 1: 0.866 − 2.58 − 0.3 < 0 -> keep; default p = 0.25: 0.866 − 0.645 − 0.3 < 0
    assert gain_ego - 0.3 > 0 and gain_ego + gain_n - 0.3 < 0 and gain_ego + 0.25 * gain_n - 0.3 < 0
    assert decide(w, replace(P, politeness=0.0))[0] == 1
    assert decide(w, replace(P, politeness=1.0))[0] == 0
    assert decide(w)[0] == 0


def test_no_request_to_a_non_existent_lane(road) -> None:
    # leftmost lane 4 behind a very slow leader, lane 3 blocked alongside: no +1 (lane 5 does not exist)
    w = hand_built_world(road, s=[300.0, 320.0, 300.0], lane=[4, 4, 3], speed=[30.0, 10.0, 30.0])
    ev = evaluate(w, EGO, P)
    assert not ev.exists[0, 2]
    assert decide(w)[0] == 0
    # lane 1 at s = 300 (lane 0 absent), lane 2 blocked alongside: no −1 even in symmetric MOBIL
    w = hand_built_world(road, s=[300.0, 320.0, 300.0], lane=[1, 1, 2], speed=[30.0, 10.0, 30.0])
    assert decide(w, replace(P, asymmetric=False, enter_ending_lane=True))[0] == 0


def test_vehicle_changing_into_the_same_lane_blocks(road) -> None:
    # ego lane 3 would move right into free lane 2 (keep right), but vehicle 1 in lane 1, 2 m behind,
    # is changing into lane 2: it counts as lane 2's follower there, ã = −9 -> keep
    w = hand_built_world(road, s=[300.0, 298.0], lane=[3, 1], speed=[30.0, 30.0])
    assert decide(w)[0] == -1  # alone: keep right
    w.step(np.zeros(2), np.array([0, 1]))  # vehicle 1 starts its change into lane 2
    assert w.target_lane[1] == 2 and w.lane[1] == 1
    assert decide(w)[0] == 0


def test_no_request_while_changing(road) -> None:
    w = hand_built_world(road, s=[300.0], lane=[3], speed=[30.0])
    w.step(np.zeros(1), np.array([-1]))
    assert w.lane_change[0] == -1
    assert decide(w)[0] == 0


def test_vectorized_over_vehicles(road) -> None:
    # three independent egos (far apart): slow leader (+1), free-right keep-right (−1), empty right lane (0)
    w = hand_built_world(road, s=[300.0, 330.0, 1200.0, 2000.0], lane=[1, 1, 3, 1], speed=[25.0, 20.0, 30.0, 30.0])
    np.testing.assert_array_equal(decide(w, vehicles=[0, 2, 3]), [1, -1, 0])
    for i, expected in ((0, 1), (2, -1), (3, 0)):
        assert decide(w, vehicles=[i])[0] == expected


def test_unsettled_vehicle_and_same_step_conflicts(road) -> None:
    # keep right (−1) normally; 1 m off its lane's centre line (still settling after a change): 0
    w = hand_built_world(road, s=[300.0], lane=[3], speed=[30.0])
    assert decide(w)[0] == -1
    w.d[0] += 1.0
    assert decide(w)[0] == 0
    # vehicle 0 (lane 3) keeps right into lane 2 while vehicle 1 (lane 1, 2 m behind, slow leader) moves left
    # into lane 2: each alone changes; decided together (one driver), the one ahead goes, the other yields
    w = hand_built_world(road, s=[300.0, 298.0, 320.0], lane=[3, 1, 1], speed=[30.0, 30.0, 10.0])
    assert decide(w, vehicles=[0])[0] == -1 and decide(w, vehicles=[1])[0] == 1
    np.testing.assert_array_equal(decide(w, vehicles=[0, 1]), [-1, 0])


# ------------------------------------------------------------------ driver (Krauss)
def _driver(vehicles, sigma: float = 0.0, params: MobilParams = P) -> KraussLaneChangeDriver:
    krauss = KraussCarFollowing(KraussParams(sigma=sigma), np.random.default_rng(0), 0.1)
    return KraussLaneChangeDriver(np.asarray(vehicles), lane_change_decision, params, krauss, VehicleParams(),
                                  params.merge_stop_margin_m)


def test_driver_follows_the_target_lane_leader_while_changing(road) -> None:
    # ego lane 3 changing right into lane 2 where a 22 m/s vehicle is ahead; own lane free
    w = hand_built_world(road, s=[300.0, 345.0], lane=[3, 2], speed=[30.0, 22.0])
    w.step(np.zeros(2), np.array([-1, 0]))
    assert w.lane_change[0] == -1 and w.lane[0] == 3
    drv = _driver([0])
    kp = KraussParams(sigma=0.0)
    v = w.v[0]
    own = (min(v + 2.6 * 0.1, V0) - v) / 0.1  # σ = 0, free road: accelerate by a = 2.6
    gap = w.s[1] - w.s[0] - L
    v_follow = float(sumo_follow_speed(gap, v, w.v[1], kp, 0.1))
    target = (max(min(v + 2.6 * 0.1, V0, v_follow), v - 9.0 * 0.1) - v) / 0.1  # Krauss, no dawdling
    assert target < 0.0 < own
    assert drv.acceleration(w)[0] == pytest.approx(min(own, target), abs=1e-9)
    # without the change in progress only the own lane counts
    w2 = hand_built_world(road, s=[300.0, 345.0], lane=[3, 2], speed=[30.0, 22.0])
    assert _driver([0]).acceleration(w2)[0] == pytest.approx((min(30.0 + 0.26, V0) - 30.0) / 0.1)


# ------------------------------------------------------------------ compiled kernels vs the numpy helpers
def test_compiled_settled_matches_the_road_model(road) -> None:
    # the kernels' settling test re-evaluates RoadModel.lane_center_d: same result everywhere,
    # including the merge lane's taper and s outside the road
    rng = np.random.default_rng(3)
    s = np.concatenate([rng.uniform(-20.0, road.length_m + 20.0, 400), [0.0, 600.0, 960.0, road.length_m]])
    lane = rng.integers(0, road.num_lanes, s.size)
    centre = road.lane_center_d(lane, np.maximum(s, 0.0))
    d = np.where(np.isfinite(centre), centre, 0.0) + rng.uniform(-1.0, 1.0, s.size)
    tables = road.kernel_tables()
    for tol in (0.0, 0.3, 0.5):
        expected = np.abs(d - centre) <= tol
        got = [settled(tables, s[k], d[k], lane[k], tol) for k in range(s.size)]
        np.testing.assert_array_equal(got, expected)


def test_compiled_krauss_command_matches_the_generic_path(road) -> None:
    # the driver's compiled Krauss + lane-end stop + throttle mapping == the numpy composition
    # (KraussCarFollowing.acceleration twice, sumo_follow_speed, accel_to_throttle), random draws included
    from evoscen_sim.physics.vehicle import accel_to_throttle

    w = hand_built_world(road, s=[800.0, 812.0, 790.0, 300.0, 345.0, 900.0], lane=[0, 1, 1, 3, 2, 0],
                         speed=[20.0, 25.0, 30.0, 30.0, 22.0, 5.0])
    w.step(np.zeros(6), np.array([0, 0, 1, -1, 0, 0]))
    assert np.count_nonzero(w.target_lane != w.lane) >= 2
    vehicles = np.arange(6)
    fast = _driver(vehicles, sigma=0.5)
    slow = _driver(vehicles, sigma=0.5)
    for _ in range(3):
        acc_fast, thr_fast = fast._acceleration_throttle(w)
        acc_slow = slow._acceleration_generic(w)
        np.testing.assert_array_equal(acc_fast, acc_slow)
        np.testing.assert_array_equal(thr_fast, accel_to_throttle(acc_slow, VehicleParams()))
