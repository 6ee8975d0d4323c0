"""Nilsson lane-utility lane changes (evoscen_sut.nilsson), hand-built situations, hand-derived decisions.

Utility of lane l (NilssonParams defaults; v_des = 120 km/h = 33.33 m/s, β = 300 s, v_min = 2 m/s):
    U_v/N_v  = −|1 − v_des/max(2, v̄)| / |1 − v_des/2|   (the d_max = v_des β cancels), weight 5 (v̄ ≤ v_des) or 12
    U_tg/N_tg = min(α t_des, t_g) / (α t_des), α t_des = 4 s, weight 0.5
    U_ld/N_ld = −max(0, 1 − d_end/d_max), d_max = 10 000 m, weight 5 (0 on the mainline)
v̄ = mean of the lane's front and rear speeds (front alone without rear; v_des without front);
t_g = min(g_front / v_ego, g_rear / v_rear) (bumper gaps at the ego's s), α t_des without neighbours.
A change to l needs U_l − θ|U_ego| + 0.05 (lane − l) > U_ego (θ = 0.9); the request is one step towards
the best lane if no vehicle in (or changing into) the adjacent lane is within 2.5 L = 12 m
(+ 3 s × closing speed) centre to centre.
Vehicles are 4.8 m long. Lane 0 (merge) exists for 600 ≤ s ≤ 960 (stop point 945).
"""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.road.road_model import load_road
from evoscen_sut import nilsson
from evoscen_sut.nilsson import NilssonParams, evaluate, lane_change_decision

L = 4.8
V0 = 120.0 / 3.6
P = NilssonParams()
EGO = np.array([0])


@pytest.fixture(scope="module")
def road():
    return load_road()


def u_v(v_bar: float) -> float:
    w = 5.0 if v_bar <= V0 else 12.0
    return -w * abs(1.0 - V0 / max(2.0, v_bar)) / abs(1.0 - V0 / 2.0)


def u_tg(t_g: float) -> float:
    return 0.5 * min(4.0, t_g) / 4.0


def u_ld(d_end: float) -> float:
    return -5.0 * max(0.0, 1.0 - d_end / (V0 * 300.0))


def decide(world, params: NilssonParams = P, vehicles=EGO) -> np.ndarray:
    return lane_change_decision(world, np.asarray(vehicles), params)


# ------------------------------------------------------------------ parameters
def test_defaults_and_declaration() -> None:
    assert (P.look_ahead_time_s, P.min_speed_mps, P.speed_weight_slow, P.speed_weight_fast) == (300.0, 2.0, 5.0, 12.0)
    assert (P.time_gap_weight, P.time_gap_factor, P.keep_right_bias, P.hysteresis, P.safety_length_factor) == (
        0.5, 2.0, 0.05, 0.9, 2.5)
    assert all("check" in f.metadata for f in fields(NilssonParams))
    assert nilsson.SPEC.name == "nilsson" and set(nilsson.SPEC.roles) == {"sut", "bv"}
    assert nilsson.SPEC.params_type is NilssonParams


# ------------------------------------------------------------------ decisions
def test_slow_leader_free_left_lane_changes_left(road) -> None:
    # ego lane 1 at 25 m/s behind a 20 m/s leader, bumper gap 25.2 m; lanes 2..4 empty; lane 0 absent at s = 300
    w = hand_built_world(road, s=[300.0, 330.0], lane=[1, 1], speed=[25.0, 20.0])
    ev = evaluate(w, EGO, P)
    u_own = u_v(20.0) + u_tg(25.2 / 25.0)  # −0.2128 + 0.126 = −0.0868
    assert u_own == pytest.approx(-0.0868, abs=1e-4)
    assert ev.speed[0, 1] == 20.0 and ev.time_gap[0, 1] == pytest.approx(1.008)
    np.testing.assert_allclose(ev.utility[0, 1:], [u_own, 0.5, 0.5, 0.5], rtol=1e-9)
    assert ev.utility[0, 0] == -np.inf
    # scores: lane 2: 0.5 − 0.9·0.0868 − 0.05 = 0.372 (best), lane 3: 0.322, lane 4: 0.272
    np.testing.assert_allclose(ev.score[0, 2:], [0.5 - 0.9 * abs(u_own) - 0.05 * k for k in (1, 2, 3)], rtol=1e-9)
    assert ev.target[0] == 2
    assert decide(w)[0] == 1


def test_fast_vehicle_closing_from_behind_blocks_the_change(road) -> None:
    # as above plus a 35 m/s vehicle in lane 2, 10 m behind (centres): within 2.5 L = 12 m -> keep
    w = hand_built_world(road, s=[300.0, 330.0, 290.0], lane=[1, 1, 2], speed=[25.0, 20.0, 35.0])
    assert decide(w)[0] == 0
    assert decide(w, replace(P, safety_closing_headway_s=0.0))[0] == 0  # docs/method.md §4.1's plain rule too
    # 15 m behind: outside 12 m, but closing at 10 m/s needs 12 + 3 s × 10 m/s = 42 m -> keep
    w = hand_built_world(road, s=[300.0, 330.0, 285.0], lane=[1, 1, 2], speed=[25.0, 20.0, 35.0])
    ev = evaluate(w, EGO, P)
    # lane 2's utility: free ahead (v̄ = v_des), rear time gap 10.2/35 = 0.291 s -> 0.0364: lane 3 is the target
    assert ev.utility[0, 2] == pytest.approx(u_tg(10.2 / 35.0), rel=1e-9)
    assert ev.target[0] == 3 and not ev.step_safe[0]
    assert decide(w)[0] == 0
    # the plain 2.5 L rule accepts the step (one step towards lane 3)
    assert decide(w, replace(P, safety_closing_headway_s=0.0))[0] == 1


def test_merge_lane_near_its_end_changes_onto_the_mainline(road) -> None:
    # ego on lane 0 at s = 900, 20 m/s, alone: U_0 = 0 + 0.5 + 5·(−(1 − 60/10000)) = −4.47
    w = hand_built_world(road, s=[900.0], lane=[0], speed=[20.0])
    ev = evaluate(w, EGO, P)
    u0 = 0.5 + u_ld(60.0)
    assert ev.utility[0, 0] == pytest.approx(u0, rel=1e-9) and u0 == pytest.approx(-4.47, abs=1e-3)
    # stop gap 945 − 902.4 = 42.6 m < 100 m: lane 0 is no candidate; lane 1: 0.5 − 0.9·4.47 − 0.05 = −3.52
    assert ev.score[0, 0] == -np.inf
    assert ev.target[0] == 1
    assert decide(w)[0] == 1
    # by the utilities alone (no mandatory rule): −3.52 > −4.47 -> +1
    assert decide(w, replace(P, merge_mandatory_distance_m=0.0))[0] == 1
    # early on the merge lane, s = 650: U_0 = 0.5 − 5·(1 − 310/10000) = −4.345; lane 1: 0.5 − 3.91 − 0.05 > −4.345
    w = hand_built_world(road, s=[650.0], lane=[0], speed=[20.0])
    ev = evaluate(w, EGO, P)
    assert ev.utility[0, 0] == pytest.approx(0.5 + u_ld(310.0), rel=1e-9)
    assert decide(w)[0] == 1


def test_merge_lane_vehicle_alongside_blocks(road) -> None:
    w = hand_built_world(road, s=[900.0, 900.0], lane=[0, 1], speed=[20.0, 20.0])
    assert evaluate(w, EGO, P).target[0] >= 1
    assert decide(w)[0] == 0


def test_mainline_vehicle_does_not_enter_the_merge_lane(road) -> None:
    # ego lane 1 at s = 700 behind a 15 m/s leader; lane 0 free but ending: U_0 = 0.5 + 5·(−(1 − 260/10000)) = −4.37
    w = hand_built_world(road, s=[700.0, 725.0], lane=[1, 1], speed=[25.0, 15.0])
    ev = evaluate(w, EGO, P)
    assert ev.utility[0, 0] == pytest.approx(0.5 + u_ld(260.0), rel=1e-9)
    assert ev.target[0] == 2
    assert decide(w)[0] == 1


def test_empty_road_keeps_lane(road) -> None:
    # all lanes free: U = 0.5 everywhere; a change needs 0.5 − 0.45 ± 0.05 > 0.5: never
    for lane in (1, 2, 3, 4):
        w = hand_built_world(road, s=[300.0], lane=[lane], speed=[30.0])
        assert decide(w)[0] == 0


def test_hysteresis_and_keep_right(road) -> None:
    # ego lane 2 at 30 m/s, leader 90 m ahead (bumper) at 30 m/s (t_g = 3 s): U_own = −0.0355 + 0.375 = 0.3395
    w = hand_built_world(road, s=[300.0, 394.8], lane=[2, 2], speed=[30.0, 30.0])
    ev = evaluate(w, EGO, P)
    u_own = u_v(30.0) + u_tg(3.0)
    assert ev.utility[0, 2] == pytest.approx(u_own, rel=1e-9)
    # right lane 1 free: 0.5 − 0.9·0.3395 + 0.05 = 0.244 < 0.3395 -> keep (hysteresis)
    assert ev.score[0, 1] == pytest.approx(0.5 - 0.9 * u_own + 0.05, rel=1e-9)
    assert decide(w)[0] == 0
    # θ = 0: right 0.55 and left 0.45 both beat 0.3395; the keep-right bias picks the right lane
    assert decide(w, replace(P, hysteresis=0.0))[0] == -1


def test_all_lanes_considered_one_step_at_a_time(road) -> None:
    # ego lane 1 behind a 20 m/s leader; lane 2 has a 20 m/s vehicle 30 m ahead (bumper, safe to enter);
    # lanes 3, 4 free. Lane 2: u_v(20) + u_tg(30/25) = −0.063; lane 3: 0.5 − 0.078 − 0.1 = 0.322: target 3.
    # The step into lane 2 is safe: 34.8 m centre distance ≥ 12 m + 3 s × 5 m/s = 27 m.
    w = hand_built_world(road, s=[300.0, 330.0, 334.8], lane=[1, 1, 2], speed=[25.0, 20.0, 20.0])
    ev = evaluate(w, EGO, P)
    assert ev.utility[0, 2] == pytest.approx(u_v(20.0) + u_tg(30.0 / 25.0), rel=1e-9)
    assert ev.target[0] == 3 and ev.step_safe[0]
    assert decide(w)[0] == 1  # one step, towards lane 3


def test_no_request_to_a_non_existent_lane(road) -> None:
    # leftmost lane 4 behind a very slow leader, lane 3 blocked alongside: only lanes 1..4 exist at s = 300
    w = hand_built_world(road, s=[300.0, 320.0, 300.0], lane=[4, 4, 3], speed=[30.0, 10.0, 30.0])
    ev = evaluate(w, EGO, P)
    assert ev.utility.shape == (1, 5) and ev.utility[0, 0] == -np.inf
    assert 1 <= ev.target[0] <= 4
    assert decide(w)[0] in (0, -1) and decide(w)[0] == 0  # the step to lane 3 is blocked
    # lane 1 at s = 300 with lane 0 absent: never −1
    w = hand_built_world(road, s=[300.0, 320.0, 300.0], lane=[1, 1, 2], speed=[30.0, 10.0, 30.0])
    assert decide(w)[0] == 0


def test_vehicle_changing_into_the_same_lane_blocks(road) -> None:
    # ego lane 1 behind a slow leader wants lane 2; vehicle 2 in lane 3, 8 m behind, starts changing into lane 2
    w = hand_built_world(road, s=[300.0, 330.0, 292.0], lane=[1, 1, 3], speed=[25.0, 20.0, 25.0])
    assert decide(w)[0] == 1
    w.step(np.zeros(3), np.array([0, 0, -1]))
    assert w.target_lane[2] == 2 and w.lane[2] == 3
    assert decide(w)[0] == 0


def test_no_request_while_changing(road) -> None:
    w = hand_built_world(road, s=[300.0, 330.0], lane=[1, 1], speed=[25.0, 20.0])
    w.step(np.zeros(2), np.array([1, 0]))
    assert w.lane_change[0] == 1
    assert decide(w)[0] == 0


def test_vectorized_over_vehicles(road) -> None:
    w = hand_built_world(road, s=[300.0, 330.0, 900.0, 2000.0], lane=[1, 1, 0, 2], speed=[25.0, 20.0, 20.0, 30.0])
    np.testing.assert_array_equal(decide(w, vehicles=[0, 2, 3]), [1, 1, 0])
    for i, expected in ((0, 1), (2, 1), (3, 0)):
        assert decide(w, vehicles=[i])[0] == expected


def test_unsettled_vehicle_and_same_step_conflicts(road) -> None:
    w = hand_built_world(road, s=[300.0, 330.0], lane=[1, 1], speed=[25.0, 20.0])
    assert decide(w)[0] == 1
    w.d[0] += 1.0  # 1 m off the centre line (still settling after a change): 0
    assert decide(w)[0] == 0
    # vehicles 0 (lane 1) and 1 (lane 3, 2 m behind), both behind slow leaders, both want lane 2
    w = hand_built_world(road, s=[300.0, 298.0, 330.0, 328.0], lane=[1, 3, 1, 3], speed=[25.0, 25.0, 20.0, 20.0])
    assert decide(w, vehicles=[0])[0] == 1 and decide(w, vehicles=[1])[0] == -1
    np.testing.assert_array_equal(decide(w, vehicles=[0, 1]), [1, 0])


def test_compiled_neighbour_search_matches_the_neighbourhood(road) -> None:
    # the kernel's nearest front / rear vehicle per lane (unlimited view) is the simulator's
    # neighbourhood (ties at equal s included): v̄ and the time gap follow from it
    rng = np.random.default_rng(5)
    p = replace(P, view_range_m=2500.0)
    for _ in range(20):
        n = 16
        s = np.round(rng.uniform(100.0, 400.0, n) / 4.0) * 4.0  # many vehicles level with each other
        lane = rng.integers(1, 5, n)
        w = hand_built_world(road, s=list(s), lane=list(lane), speed=list(rng.uniform(5.0, 33.0, n)))
        nb = w.neighborhood()
        ev = evaluate(w, np.arange(n), p)
        for i in range(n):
            for ln in range(1, 5):
                col = ln - lane[i] + 2
                if not 0 <= col <= 4:
                    continue
                fj, rj = nb.leader[i, col], nb.follower[i, col]
                v_bar = (0.5 * (w.v[fj] + w.v[rj]) if rj >= 0 else w.v[fj]) if fj >= 0 else V0
                assert ev.speed[i, ln] == v_bar
                t_front = nb.gap_front_m[i, col] / max(w.v[i], 2.0) if fj >= 0 else np.inf
                t_rear = nb.gap_rear_m[i, col] / max(w.v[rj], 2.0) if rj >= 0 else np.inf
                assert ev.time_gap[i, ln] == min(t_front, t_rear, 4.0)
