"""The car-following controller's observation, reward and throttle composition, by hand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from evoscen_bv.car_following import (
    CarFollowingParams,
    car_following_reward,
    compose_throttle,
    controller_observations,
    emergency_brake_throttle,
    gap_value,
    leader_state,
    leaders,
    speed_cap_throttle,
)
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.road.road_model import load_road

P = CarFollowingParams()


def test_observation_normalised_by_view_speed_and_accel():
    obs = leader_state(np.array([30.0, np.inf, 120.0]), np.array([20.0, np.nan, 20.0]), np.array([1.0, np.nan, 0.0]),
                       np.array([25.0, 25.0, 25.0]), np.array([-1.0, 0.0, 0.0]), P)
    # [Δs / o_smax, (v_l - v) / v_max, (a_l - a) / a_max, λ]
    assert obs[0] == pytest.approx([0.3, -5 / 33.33, 2 / 8.0, 1.0])
    assert obs[1].tolist() == [0.0, 0.0, 0.0, 0.0]  # no leader
    assert obs[2].tolist() == [0.0, 0.0, 0.0, 0.0]  # leader beyond the 100 m view


def test_observation_with_the_leaders_acceleration_alone():
    """own_accel_in_observation false: the third slot is a_leader / a_max, the rest as before."""
    assert P.own_accel_in_observation is True and P.own_accel_weight == 1.0  # the method's Δs̈ by default
    lead = dataclasses.replace(P, own_accel_in_observation=False)
    obs = leader_state(np.array([30.0, 50.0]), np.array([20.0, 25.0]), np.array([1.0, -2.0]),
                       np.array([25.0, 25.0]), np.array([-1.0, 3.0]), lead)
    # [Δs / o_smax, (v_l - v) / v_max, a_l / a_max, λ]: 1 / 8 and -2 / 8, the BV's own -1 and 3 m/s² ignored
    assert obs[0] == pytest.approx([0.3, -5 / 33.33, 0.125, 1.0])
    assert obs[1] == pytest.approx([0.5, 0.0, -0.25, 1.0])


def test_reward_by_hand():
    s = leader_state(np.array([30.0]), np.array([20.0]), np.array([0.0]), np.array([25.0]), np.array([0.0]), P)
    s2 = leader_state(np.array([27.0]), np.array([20.0]), np.array([0.0]), np.array([25.0]), np.array([0.0]), P)
    # V(s) = -(30 - 25)² / 100² = -0.0025, V(s') = -(27 - 25)² / 100² = -0.0004
    assert gap_value(s, P) == pytest.approx([-0.0025])
    assert gap_value(s2, P) == pytest.approx([-0.0004])
    # r = μ V(s') + k (V(s') - V(s)) = -0.0004 + 10 · 0.0021 = 0.0206
    assert car_following_reward(s, s2, np.array([False]), P) == pytest.approx([0.0206])
    # moving away from the target gap is penalised
    assert car_following_reward(s2, s, np.array([False]), P) == pytest.approx([-0.0025 - 0.021])
    # collision: -C
    assert car_following_reward(s, s2, np.array([True]), P) == pytest.approx([-10.0])


def test_value_without_a_leader_zero_or_the_view_edge():
    none = np.zeros((1, 4))
    far = leader_state(np.array([95.0]), np.array([25.0]), np.array([0.0]), np.array([25.0]), np.array([0.0]), P)
    # V(95 m) = -(95 - 25)² / 100² = -0.49
    assert gap_value(far, P) == pytest.approx([-0.49])
    # the default (V = 0 without a leader) pays for losing it: r = 0 + 10 · (0 - (-0.49)) = +4.9
    assert P.no_leader_at_view_edge is False
    assert gap_value(none, P) == pytest.approx([0.0])
    assert car_following_reward(far, none, np.array([False]), P) == pytest.approx([4.9])
    # at the view's edge: V(no leader) = -(100 - 25)² / 100² = -0.5625, and the leader leaving the view
    # costs r = -0.5625 + 10 · (-0.5625 + 0.49) = -1.2875
    edge = dataclasses.replace(P, no_leader_at_view_edge=True)
    assert gap_value(none, edge) == pytest.approx([-0.5625])
    assert car_following_reward(far, none, np.array([False]), edge) == pytest.approx([-1.2875])


def test_throttle_is_the_minimum_over_leaders_and_the_speed_cap():
    seen = np.array([[0.3, 0.0, 0.0, 1.0]] * 3)
    none = np.zeros((3, 4))
    u = compose_throttle(np.array([0.5, -0.2, 0.9]), np.array([0.1, 0.0, 0.0]), seen, np.vstack([seen[:2], none[:1]]),
                         np.array([1.0, 1.0, 0.2]))
    assert u.tolist() == pytest.approx([0.1, -0.2, 0.2])
    # free road: only the speed term k_v (v_des - v): 0.5 · (30 - 24) = 3 m/s² → full throttle (3 m/s²)
    free = compose_throttle(np.array([-1.0]), np.array([-1.0]), none[:1], none[:1],
                            speed_cap_throttle(np.array([24.0]), np.array([30.0]), P, 3.0, 8.0))
    assert free.tolist() == pytest.approx([1.0])
    # above the desired speed it brakes: 0.5 · (30 - 34) = -2 m/s² → -2/8
    assert speed_cap_throttle(np.array([34.0]), np.array([30.0]), P, 3.0, 8.0) == pytest.approx([-0.25])


def test_observations_in_the_world_include_the_merge_lane_end():
    road = load_road()
    # 0 follows 1 in lane 2; 2 drives alone on the merge lane at 850 m (its end 960 m - 60 m margin)
    w = hand_built_world(road, s=[300, 340, 850], lane=[2, 2, 0], speed=[25, 22, 20])
    own, target = controller_observations(w, np.array([0, 2]), P)
    assert own[0] == pytest.approx([35.2 / 100, -3 / 33.33, 0.0, 1.0])
    # standing obstacle at 900 m (where the taper begins): gap 900 - 852.4 = 47.6 m, speed difference -20
    assert own[1] == pytest.approx([47.6 / 100, -20 / 33.33, 0.0, 1.0])
    assert np.array_equal(own, target)  # nobody changes lanes


@pytest.mark.parametrize("own_accel", [True, False])
def test_fused_run_time_throttle_equals_the_pieces(own_accel):
    """The compiled run-time throttle = observations → controller → min with the speed term
    (with either form of the observation's acceleration slot)."""
    pytest.importorskip("torch")
    from evoscen_bv.car_following import learned_throttle
    from evoscen_bv.learned import PolicyBank
    from evoscen_bv.td3 import TD3, NumpyActor, TD3Params, export_actor

    agent = TD3(4, 1, 1.0, TD3Params(hidden=16), seed=5)
    import io

    buf = io.BytesIO()
    export_actor(agent.actor, buf)
    buf.seek(0)
    actor = NumpyActor(dict(np.load(buf)))
    road = load_road()
    # 0 behind 1; 2 changing lanes to the left towards 3's lane; 4 on the merge lane near its end; 5 alone
    w = hand_built_world(road, s=[300, 330, 500, 540, 900, 1500], lane=[2, 2, 1, 2, 0, 3],
                         speed=[25, 22, 28, 20, 20, 31])
    w.step(np.zeros(6), np.array([0, 0, 1, 0, 0, 0]))
    assert w.lane_change[2] == 1
    w.step(np.array([0.4, -0.3, 0.2, -0.5, 0.0, 0.3]), np.zeros(6, dtype=np.int64))
    assert np.all(w.accel[[0, 1, 2, 3]] != 0.0)  # the acceleration slot differs between the two forms
    params = dataclasses.replace(P, own_accel_in_observation=own_accel)
    idx = np.array([0, 2, 4, 5])
    desired = np.array([30.0, 29.0, 28.0, 27.0])
    own, target = controller_observations(w, idx, params)
    u = actor.forward(np.vstack([own, target]))[:, 0]
    cap = speed_cap_throttle(w.v[idx], np.minimum(desired, w.speed_limit_mps[idx]), P, 3.0, 8.0)
    gap, v_lead, a_lead = leaders(w, idx, params)
    cap = np.minimum(cap, emergency_brake_throttle(gap, v_lead, w.v[idx][:, None], P, 8.0, a_lead).min(axis=1))
    expected = compose_throttle(u[:4], u[4:], own, target, cap, changing=w.lane_change[idx] != 0)
    fused = learned_throttle(w, idx, desired, PolicyBank([actor]), params, 3.0, 8.0)
    assert fused == pytest.approx(expected, abs=1e-12)
    assert target[1, 3] == 1.0 and not np.array_equal(own[1], target[1])  # the target lane's leader is seen
    assert fused[2] == -1.0  # 4 is past the merge lane's standing end at 20 m/s: the emergency brake, full


def test_emergency_brake_by_hand():
    # 20 m/s towards a standing leader 47.6 m ahead: b = 20² / (2 (47.6 - 2)) = 4.386 m/s² >= 4 -> throttle -b / 8
    # 15 m/s: b = 225 / 91.2 = 2.47 m/s² < 4 -> not acting (1); leader faster, or none: not acting
    u = emergency_brake_throttle(np.array([47.6, 47.6, 47.6, np.inf, 1.0]), np.array([0.0, 0.0, 25.0, np.nan, 0.0]),
                                 np.array([20.0, 15.0, 20.0, 30.0, 20.0]), P, 8.0)
    assert u.tolist() == pytest.approx([-400.0 / 91.2 / 8.0, 1.0, 1.0, 1.0, -1.0])
    # a leader braking at 8 m/s², both at 20 m/s, 25 m apart: it stops in 400 / 16 = 25 m; stopping behind that
    # point needs 400 / (2 (23 + 25)) = 4.17 m/s² >= 4 -> acts; braking at 2 m/s² (stops in 100 m) -> not acting
    u = emergency_brake_throttle(np.array([25.0, 25.0]), np.array([20.0, 20.0]), np.array([20.0, 20.0]), P, 8.0,
                                 np.array([-8.0, -2.0]))
    assert u.tolist() == pytest.approx([-400.0 / 96.0 / 8.0, 1.0])


def test_leaders_see_vehicles_changing_into_or_reaching_into_the_lane():
    road = load_road()
    # 0 in lane 2; 1 ahead in lane 1 about to change left into lane 2; 2 further ahead in lane 2
    w = hand_built_world(road, s=[1200.0, 1230.0, 1300.0], lane=[2, 1, 2], speed=[25.0, 25.0, 25.0])
    gap, v_lead, _ = leaders(w, np.array([0]), P)
    assert gap[0, 0] == pytest.approx(100.0 - w.length[0])  # 2 (bumper gap: centre distance - one length)
    w.step(np.zeros(3), np.array([0, 1, 0]))
    assert w.lane[1] == 1 and w.lane_change[1] == 1
    gap, _, _ = leaders(w, np.array([0]), P)
    assert gap[0, 0] == pytest.approx(w.s[1] - w.s[0] - w.length[0])  # 1, changing into lane 2, is 0's leader now
    # 1's body reaching into lane 2 without a lane change in progress (heading towards it): still 0's leader
    w2 = hand_built_world(road, s=[1200.0, 1230.0], lane=[2, 1], speed=[25.0, 0.0])
    lk = w2.lane_lookup()
    w2.d[1] = lk.d_left[1, 1] - 0.5  # centre 0.5 m inside lane 1, body (1.8 m wide) 0.4 m into lane 2
    gap, v_lead, _ = leaders(w2, np.array([0]), P)
    assert gap[0, 0] == pytest.approx(30.0 - w2.length[0]) and v_lead[0, 0] == 0.0
    w2.d[1] = lk.d_left[1, 1] - 1.0  # fully in lane 1 (0.1 m clear): not a leader in lane 2
    gap, _, _ = leaders(w2, np.array([0]), P)
    assert gap[0, 0] == np.inf


def test_merge_lane_end_is_not_a_leader_while_changing_out_of_the_merge_lane():
    road = load_road()
    w = hand_built_world(road, s=[880.0], lane=[0], speed=[15.0])
    own, _ = controller_observations(w, np.array([0]), P)
    assert own[0, 3] == 1.0  # waiting for a gap: the line at 900 m is ahead
    w.step(np.zeros(1), np.array([1]))
    assert w.lane_change[0] == 1
    own, target = controller_observations(w, np.array([0]), P)
    assert own[0, 3] == 0.0 and target[0, 3] == 0.0  # merging: nothing ahead, it must not stop across the lanes


def test_a_bv_changing_lanes_creeps_past_a_standing_leader_in_the_old_lane():
    """Committed lane changes: the old lane's leader only bounds the throttle (emergency brake), so a BV that
    began a change 18 m behind a standing vehicle moves on (at rest it could not move sideways)."""
    from evoscen_bv.learned import LearnedDriver, load_policies, shipped_policy_dir

    controller, _, training = load_policies(shipped_policy_dir())
    road = load_road()
    w = hand_built_world(road, s=[1200.0, 1177.0], lane=[2, 2], speed=[0.0, 2.0])  # bumper gap 23 - length
    bv = LearnedDriver(np.array([1]), controller, {}, training, np.random.default_rng(0), w.vehicle)
    w.step(np.array([-1.0, 0.0]), np.array([0, 1]))
    assert w.lane_change[1] == 1
    for _ in range(200):
        w.step(np.concatenate([[-1.0], bv.throttle(w)]), np.zeros(2, dtype=np.int64))
    assert w.lane[1] == 3 and w.lane_change[1] == 0  # the change completed
    assert w.s[1] < w.s[0] or w.lane[1] != w.lane[0]  # without touching the standing vehicle
    assert not overlapping(w)


def overlapping(w) -> bool:
    from evoscen_sim.physics.collision import overlapping_pairs

    return len(overlapping_pairs(w.s, w.d, w.psi, w.length, w.width)) > 0


def _cut_in_world(policy: str):
    """A BV (index 0, ``policy``) at 1,200 m in lane 2 at 30 m/s; the SUT (index 1) 25 m ahead in lane 1 at
    25 m/s, requesting a change into lane 2 — ahead of the BV."""
    from evoscen_contract.contract import POLICY_CODES, ROLE_BV, ROLE_SUT

    w = hand_built_world(load_road(), s=[1200.0, 1225.0], lane=[2, 1], speed=[30.0, 25.0], roles=[ROLE_BV, ROLE_SUT])
    w.policy[0] = POLICY_CODES[policy]
    w.step(np.zeros(2), np.array([0, 1]))
    assert w.lane[1] == 1 and w.lane_change[1] == 1
    return w


def _body_in_lane_2(w) -> bool:
    lk = w.lane_lookup()
    e = 0.5 * (w.width[1] * np.cos(w.psi[1]) + w.length[1] * abs(np.sin(w.psi[1])))
    return bool(w.d[1] + e > lk.d_right[1, 2] + 0.1)


@pytest.mark.parametrize("profile", ["safety_net", "driver"])
def test_a_competitive_bv_does_not_yield_to_the_sut_cutting_in_until_its_body_is_in_the_lane(profile):
    """models.learned.competitive_cut_in (docs/learned-bvs.md): with ``compete`` a competitive BV ignores the
    SUT's request — its throttle is the one it has with no SUT at all (bit for bit) — until the SUT's body
    reaches into its lane; then (after its reaction time under ``driver``) it brakes for it like any BV.
    A mutual BV, and every BV with ``yield``, brakes for the SUT from its request on."""
    from evoscen_bv.learned import LearnedDriver, load_policies, shipped_policy_dir

    controller, _, training = load_policies(shipped_policy_dir())

    def throttle(w, compete: bool, bv: LearnedDriver | None = None) -> tuple[float, LearnedDriver]:
        bv = bv or LearnedDriver(np.array([0]), controller, {}, training, np.random.default_rng(0), w.vehicle,
                                 profile=profile, compete_with_sut=compete)
        return float(bv.throttle(w)[0]), bv

    alone = hand_built_world(load_road(), s=[1200.0], lane=[2], speed=[30.0])
    free, _ = throttle(alone, True)
    w = _cut_in_world("competitive")
    assert not _body_in_lane_2(w)
    competing, bv_c = throttle(w, True)
    yielding, bv_y = throttle(w, False)
    assert competing == free  # the SUT's request is not seen
    assert yielding < free - 0.1  # 25 m behind a vehicle 5 m/s slower: it brakes (-1 full brake, +1 full throttle)
    m = _cut_in_world("mutual")
    assert throttle(m, True)[0] == throttle(m, False)[0] < free - 0.1  # a mutual BV yields either way
    # the SUT moves over at constant speed; the BV holds its speed (throttle 0 keeps it at 30 m/s here)
    steps = 0
    while not _body_in_lane_2(w):
        assert throttle(w, True, bv_c)[0] == free
        throttle(w, False, bv_y)
        w.step(np.zeros(2), np.zeros(2, dtype=np.int64))
        w.v[0], w.s[0] = 30.0, w.s[1] - 25.0
        steps += 1
    assert 5 <= steps <= 30  # the body crosses the line 0.5-3 s into the change
    assert _body_in_lane_2(w) and w.lane_change[1] == 1
    later = [throttle(w, True, bv_c)[0] for _ in range(1)]
    for _ in range(20):  # the reaction time of the driver profile (under 2 s) passes
        w.step(np.zeros(2), np.zeros(2, dtype=np.int64))
        w.v[0], w.s[0] = 30.0, w.s[1] - 25.0
        later.append(throttle(w, True, bv_c)[0])
    assert min(later) < free - 0.1  # now it brakes for the SUT


def test_a_competitive_bv_changing_lanes_itself_sees_the_sut_changing_into_the_same_lane():
    """The competitive rule holds for a BV keeping its lane only: a competitive BV in lane 3 that starts a
    change into lane 2 at the step the SUT (lane 1, 25 m ahead) starts one into lane 2 brakes for the SUT
    from its request on, as with ``yield``."""
    from evoscen_bv.learned import LearnedDriver, load_policies, shipped_policy_dir
    from evoscen_contract.contract import POLICY_CODES, ROLE_BV, ROLE_SUT

    controller, _, training = load_policies(shipped_policy_dir())
    w = hand_built_world(load_road(), s=[1200.0, 1225.0], lane=[3, 1], speed=[30.0, 25.0], roles=[ROLE_BV, ROLE_SUT])
    w.policy[0] = POLICY_CODES["competitive"]
    w.step(np.zeros(2), np.array([-1, 1]))
    assert w.lane_change.tolist() == [-1, 1] and w.target_lane.tolist() == [2, 2]
    u = {compete: float(LearnedDriver(np.array([0]), controller, {}, training, np.random.default_rng(0), w.vehicle,
                                      profile="safety_net", compete_with_sut=compete).throttle(w)[0])
         for compete in (True, False)}
    alone = hand_built_world(load_road(), s=[1200.0], lane=[2], speed=[30.0])
    free = float(LearnedDriver(np.array([0]), controller, {}, training, np.random.default_rng(0), alone.vehicle,
                               profile="safety_net").throttle(alone)[0])
    assert u[True] == u[False] < free - 0.1
