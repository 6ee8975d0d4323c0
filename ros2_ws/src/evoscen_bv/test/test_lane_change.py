"""The lane-change decision model on hand-placed traffic: grid cells, action, rule constraints, rewards.

The road is the shipped on-ramp: lane 0 (merge lane) exists from s = 600 m to 960 m,
lanes 1-4 everywhere; vehicles are 4.8 m long.
"""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_bv.lane_change_decision import (
    RewardParams,
    action_to_lane_change,
    apply_rule_constraints,
    back_vehicles,
    cell_centres_m,
    drivable_area,
    forced_merge_requests,
    forced_merge_targets,
    individual_reward,
    lane_change_gain,
    merge_seek_accel,
    observation_grid,
    social_reward,
    social_terms,
)
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.road.road_model import load_road

V_MAX = 33.33
HAND = RewardParams(front_view_m=100.0, theta_left=1.1, gain_norm_m2=2500.0, lane_change_penalty=-0.3,
                    request_penalty=-0.5, comp_space_weight=0.3, comp_brake_weight=0.5, comp_brake_bound=0.1,
                    coop_space_weight=0.3, coop_speed_weight=0.3, coop_speed_bound=1.0, accel_norm_mps2=8.0,
                    speed_norm_mps=33.33)
"""Coefficients of the hand computations (independent of the shipped defaults)."""


@pytest.fixture(scope="module")
def road():
    return load_road()


def test_grid_cells_of_a_hand_placed_neighbourhood(road):
    # ego (0) in lane 2 at s = 500; A 30 m ahead in its lane, B 10 m behind on the left,
    # C 100 m ahead two lanes left, D 106 m ahead (beyond the grid), E in lane 1 level with the ego
    w = hand_built_world(road, s=[500, 530, 490, 600, 606, 500.0], lane=[2, 2, 3, 4, 2, 1],
                         speed=[25, 20, 30, 25, 25, 22])
    w.psi[2] = 0.05
    g = observation_grid(w, np.array([0]))[0]
    assert g.shape == (5, 25, 4)
    # rows are lane offsets -2..+2: row 2 own lane, row 3 lane 3 (left)
    # A: Δs = 30 → cell floor((30 + 20) / 5) = 10
    assert g[2, 10].tolist() == pytest.approx([1.0, (20 - 25) / V_MAX, 0.0, 0.0])
    # B: Δs = -10 → cell 2; yaw 0.05 rad → Δe = 0.05 / 0.2, lateral speed 30 sin 0.05 / 2
    assert g[3, 2].tolist() == pytest.approx([1.0, 5 / V_MAX, 30 * np.sin(0.05) / 2.0, 0.25])
    # C: Δs = 100 → cell 24, row 4
    assert g[4, 24, 0] == 1.0
    # E: Δs = 0 → cell 4 of the right neighbour lane
    assert g[1, 4].tolist() == pytest.approx([1.0, -3 / V_MAX, 0.0, 0.0])
    # row 0 is lane 0, the merge lane, which does not exist at s < 600: cell centres 482.5 + 5c
    # are on the road from c = 24 (602.5 m) only
    assert (g[0, :24, 0] == -1.0).all() and g[0, 24, 0] == 0.0
    # everything else is empty road
    expected_nonzero = {(2, 10), (3, 2), (4, 24), (1, 4)} | {(0, c) for c in range(24)}
    nz = {(r, c) for r in range(5) for c in range(25) if np.any(g[r, c] != 0)}
    assert nz == expected_nonzero


def test_grid_marks_lanes_beyond_the_road_edges(road):
    # ego in lane 4 (leftmost): offsets +1 and +2 are off the road everywhere
    w = hand_built_world(road, s=[300.0], lane=[4], speed=[25.0])
    g = observation_grid(w, np.array([0]))[0]
    assert (g[3:, :, 0] == -1.0).all()
    assert (g[:3, :, 0] == 0.0).all()


def test_grid_is_built_for_all_vehicles_at_once(road):
    w = hand_built_world(road, s=[500, 515], lane=[2, 2], speed=[25, 20])
    g = observation_grid(w, np.array([0, 1]))
    # vehicle 0 sees vehicle 1 at Δs = +15 (cell 7); vehicle 1 sees vehicle 0 at Δs = -15 (cell 1)
    assert g[0, 2, 7].tolist() == pytest.approx([1.0, -5 / V_MAX, 0.0, 0.0])
    assert g[1, 2, 1].tolist() == pytest.approx([1.0, 5 / V_MAX, 0.0, 0.0])
    assert np.count_nonzero(g[:, 2:, :, 0]) == 2


def test_action_thresholds():
    a = np.array([-1.0, -0.34, -0.33, 0.0, 0.33, 0.34, 1.0])
    assert action_to_lane_change(a).tolist() == [-1, -1, 0, 0, 0, 1, 1]


def test_rule_constraint_off_road_change_becomes_keep(road):
    # lane 1 at s = 500: a right change would go to the merge lane, which starts at 600
    # lane 4: a left change leaves the road
    w = hand_built_world(road, s=[500, 300, 700], lane=[1, 4, 1], speed=[25, 25, 25])
    requested = np.array([-1, 1, -1])
    executed = apply_rule_constraints(w, np.array([0, 1, 2]), requested)
    assert executed.tolist() == [0, 0, -1]  # at s = 700 the merge lane exists
    r = individual_reward(np.full(3, 50.0), np.full(3, 50.0), np.ones(3), requested, executed, np.full(3, 50.0),
                          HAND)
    # J_req = -0.5 where the request was rewritten; vehicle 2 pays J_lc = -0.3 for its executed change
    assert r == pytest.approx([-0.5 + 0.25, -0.5 + 0.25, -0.3 + 0.25])


def test_forced_merge_on_the_last_120_m_of_the_merge_lane(road):
    # the merge lane (0) ends at s = 960; the mainline lanes 1-4 all end at the road's end (2393.76)
    assert road.lane_end_s[0] == pytest.approx(960.0)
    w = hand_built_world(road, s=[850, 830, 900, 900, 2300, 880, 884], lane=[0, 0, 0, 1, 4, 0, 1],
                         speed=[5, 5, 0, 25, 25, 0, 10])
    idx = np.arange(7)
    requested = np.array([0, 0, -1, -1, 0, 0, 0])
    forced = forced_merge_requests(w, idx, requested)
    # 110 m before the end: left; 130 m: the policy's keep; 60 m, asking right (off the road): left;
    # lane 1 and lane 4 near the road's end: no neighbouring lane goes on further -> unchanged
    assert forced.tolist() == [1, 0, 1, -1, 0, 1, 0]
    assert requested.tolist() == [0, 0, -1, -1, 0, 0, 0]  # not modified in place
    # the rule constraints still apply: vehicle 5 (s 880) has vehicle 6 (lane 1, s 884) beside it
    executed = apply_rule_constraints(w, idx, forced)
    assert executed[5] == 0 and executed[0] == 1


def test_rule_constraint_cut_in_within_10_m_becomes_keep(road):
    # ego in lane 2 at 300 asks to go left; lane 3 has a vehicle whose bumper gap is 7.2 m (12 m centre to centre)
    near = hand_built_world(road, s=[300, 312], lane=[2, 3], speed=[25, 25])
    assert apply_rule_constraints(near, np.array([0]), np.array([1])).tolist() == [0]
    behind = hand_built_world(road, s=[300, 291], lane=[2, 3], speed=[25, 25])  # 4.2 m bumper gap behind
    assert apply_rule_constraints(behind, np.array([0]), np.array([1])).tolist() == [0]
    level = hand_built_world(road, s=[300, 300], lane=[2, 3], speed=[25, 25])  # side by side
    assert apply_rule_constraints(level, np.array([0]), np.array([1])).tolist() == [0]
    far = hand_built_world(road, s=[300, 316], lane=[2, 3], speed=[25, 25])  # 11.2 m bumper gap
    assert apply_rule_constraints(far, np.array([0]), np.array([1])).tolist() == [1]
    # a vehicle changing from lane 4 into lane 3, 5 m ahead, counts as in lane 3
    merging = hand_built_world(road, s=[300, 310, 260], lane=[2, 4, 3], speed=[25, 25, 25])
    merging.step(np.zeros(3), np.array([0, -1, 0]))
    assert merging.target_lane[1] == 3 and merging.lane[1] == 4
    assert apply_rule_constraints(merging, np.array([0]), np.array([1])).tolist() == [0]
    r = individual_reward(np.array([40.0]), np.array([40.0]), np.ones(1), np.array([1]), np.array([0]),
                          np.array([40.0]), HAND)
    assert r == pytest.approx([-0.5 + 0.16])


def test_rule_constraint_gap_grows_with_the_closing_speed(road):
    # [choice] the 10 m grow by 1.5 s of closing speed. Ego at 10 m/s; the follower in lane 3 is 30.2 m behind
    # (bumper) at 25 m/s: needed 10 + 1.5 * 15 = 32.5 m > 30.2 -> keep; at 35.2 m behind -> change
    close = hand_built_world(road, s=[300, 265], lane=[2, 3], speed=[10, 25])
    assert apply_rule_constraints(close, np.array([0]), np.array([1])).tolist() == [0]
    enough = hand_built_world(road, s=[300, 260], lane=[2, 3], speed=[10, 25])
    assert apply_rule_constraints(enough, np.array([0]), np.array([1])).tolist() == [1]
    # a slower vehicle ahead in the target lane: ego 25 m/s, leader 15 m/s 20.2 m ahead: needed 25 m -> keep
    slow_ahead = hand_built_world(road, s=[300, 325], lane=[2, 3], speed=[25, 15])
    assert apply_rule_constraints(slow_ahead, np.array([0]), np.array([1])).tolist() == [0]
    # the same leader faster than the ego: no closing speed, 10 m suffice
    fast_ahead = hand_built_world(road, s=[300, 325], lane=[2, 3], speed=[15, 25])
    assert apply_rule_constraints(fast_ahead, np.array([0]), np.array([1])).tolist() == [1]


def test_drivable_area(road):
    # ego lane 2 at 300, leader at 340 (gap 40 - 4.8 = 35.2 m); lane 3 empty (O_max = 100); merge lane near its end
    w = hand_built_world(road, s=[300, 340, 900], lane=[2, 2, 0], speed=[25, 25, 25])
    assert drivable_area(w, np.array([0, 0]), np.array([0, 1]), 100.0).tolist() == pytest.approx([35.2, 100.0])
    # vehicle 2 on the merge lane ending at 960: 60 m - half its length (2.4 m)
    assert drivable_area(w, np.array([2]), np.array([0]), 100.0).tolist() == pytest.approx([57.6])


def test_individual_reward_terms_by_hand():
    p = HAND
    # gain: ϑ O_t - O_c = 1.1·60 - 40 = 26 → 26² / 2500 = 0.2704; negative when the target is worse
    assert lane_change_gain(np.array([40.0]), np.array([60.0]), np.array([1.1]), p) == pytest.approx([0.2704])
    assert lane_change_gain(np.array([60.0]), np.array([40.0]), np.array([1.0]), p) == pytest.approx([-0.16])
    # a left change, as requested: gain + J_lc + O_c'² / O_max² = 0.2704 - 0.3 + 0.25
    r = individual_reward(np.array([40.0]), np.array([60.0]), np.array([1.1]), np.array([1]), np.array([1]),
                          np.array([50.0]), p)
    assert r == pytest.approx([0.2204])
    # keep: O_t = O_c, no gain, no penalty
    r = individual_reward(np.array([30.0]), np.array([30.0]), np.array([1.0]), np.array([0]), np.array([0]),
                          np.array([30.0]), p)
    assert r == pytest.approx([0.09])


def test_lane_change_penalty_differs_by_type():
    p = RewardParams(lane_change_penalty=-0.8, comp_lane_change_penalty=-0.4, coop_lane_change_penalty=-1.2)
    args = (np.array([50.0]), np.array([50.0]), np.ones(1), np.array([1]), np.array([1]), np.array([0.0]), p)
    assert individual_reward(*args, "mutual") == pytest.approx([-0.8])
    assert individual_reward(*args, "competitive") == pytest.approx([-0.4])
    assert individual_reward(*args, "cooperative") == pytest.approx([-1.2])


def test_social_terms_by_hand(road):
    p = HAND
    # ego (0) lane 2 at 300; b1 lane 2 at 290 (gap to the ego 10 - 4.8 = 5.2 m), b2 lane 3 at 285 (empty lane ahead),
    # far: lane 2 at 250 (outside the 20 m back part), ahead: lane 2 at 350 (in front: not in Ω_b)
    w = hand_built_world(road, s=[300, 290, 285, 250, 350], lane=[2, 2, 3, 2, 2], speed=[25, 20, 30, 25, 25])
    w.accel[:] = [0.0, -4.0, 2.0, -8.0, -8.0]
    assert back_vehicles(w, 0).tolist() == [1, 2]
    space, brake, speed = social_terms(w, 0, p)
    # b1: O = 5.2 m, ϑ = 1 → 0.002704; b2 is left of the ego: ϑ = 1.1, O = O_max → 1.21
    assert space == pytest.approx(0.002704 + 1.21)
    # s̈|s̈|/s̈_max²: -16/64 = -0.25, and 4/64 = 0.0625 (below the bound z = 0.1)
    assert brake == pytest.approx(-0.25 + 0.0625)
    # ṡ|ṡ|/ṡ_max²: 400/33.33², 900/33.33² (below y = 1)
    assert speed == pytest.approx((400 + 900) / V_MAX**2)
    assert social_reward("mutual", space, brake, speed, p) == 0.0
    # competitive: -u·space - v·brake
    assert social_reward("competitive", space, brake, speed, p) == pytest.approx(-0.3 * 1.212704 + 0.5 * 0.1875)
    # cooperative: +m·space + n·speed
    assert social_reward("cooperative", space, brake, speed, p) == pytest.approx(
        0.3 * 1.212704 + 0.3 * 1300 / V_MAX**2)
    # the bounds z and y cap the positive parts
    w.accel[1] = 8.0
    assert social_terms(w, 0, p)[1] == pytest.approx(0.1 + 0.0625)
    with pytest.raises(ValueError, match="unknown reward kind"):
        social_reward("selfish", 0, 0, 0, p)


def test_grid_off_road_cells_equal_the_roads_lane_existence(road):
    # vehicles along the whole road, every lane: the compiled grid's off-road marks (-1) are exactly the cells
    # whose lane does not exist at the cell centre (RoadModel.lane_exists), incl. the merge lane's start and end
    s = np.array([5.0, 590.0, 620.0, 880.0, 905.0, 955.0, 1500.0, 2380.0])
    lane = np.array([1, 1, 0, 0, 1, 0, 4, 2])
    w = hand_built_world(road, s=s, lane=lane, speed=[20.0] * s.size)
    g = observation_grid(w, np.arange(s.size))
    lanes = lane[:, None, None] + np.arange(-2, 3)[None, :, None]
    cells = s[:, None, None] + cell_centres_m()[None, None, :]
    lanes, cells = np.broadcast_arrays(lanes, cells)
    exists = road.lane_exists(lanes, cells)
    assert np.array_equal(g[..., 0] == -1.0, ~exists)
    assert (~exists).any() and exists.any()


def test_rule_constraint_no_change_into_a_lane_about_to_end(road):
    # the merge lane (0) ends at 960 m: from lane 1 at 800 m (160 m before its end, < 200 m) a change right becomes
    # keep; at 700 m (260 m before) it is allowed
    w = hand_built_world(road, s=[800.0, 700.0], lane=[1, 1], speed=[20.0, 20.0])
    assert apply_rule_constraints(w, np.array([0, 1]), np.array([-1, -1])).tolist() == [0, -1]


def test_never_into_a_lane_that_ends_when_the_margin_is_infinite(road):
    # models.learned.into_ending_lane: false: the change at 700 m (260 m before the merge lane's end)
    # becomes keep too; a change between lanes that go on is untouched
    w = hand_built_world(road, s=[800.0, 700.0, 1500.0], lane=[1, 1, 2], speed=[20.0, 20.0, 20.0])
    out = apply_rule_constraints(w, np.array([0, 1, 2]), np.array([-1, -1, -1]), end_margin_m=float("inf"))
    assert out.tolist() == [0, 0, -1]


def test_forced_merge_from_the_merge_lanes_start_with_a_longer_reach(road):
    # 1,000 m reach (models.learned.forced_merge_m): at 610 m (350 m before the end) the merge is requested
    w = hand_built_world(road, s=[610.0, 1500.0], lane=[0, 2], speed=[22.0, 25.0])
    assert forced_merge_targets(w, np.array([0, 1]), 1000.0).tolist() == [1, 0]
    assert forced_merge_targets(w, np.array([0, 1])).tolist() == [0, 0]  # 120 m: not yet


def test_the_learned_driver_takes_both_merge_keys_from_the_scenario():
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config

    # every BV node's driver (bvs.nodes: by_policy, three of them) takes them
    sc = build_scenario(load_scenario_config(None, {"bvs.makeup": "uniform", "traffic.warmup_s": 0}))
    drivers = [d for _, d in sc.bv_driver.parts]
    assert len(drivers) == 3
    assert all(d.end_margin_m == float("inf") and d.forced_merge_m == 1000.0 for d in drivers)
    sc = build_scenario(load_scenario_config(None, {"bvs.makeup": "uniform", "traffic.warmup_s": 0, "models": {"learned": {
        "into_ending_lane": True, "forced_merge_m": 120.0}}}))
    drivers = [d for _, d in sc.bv_driver.parts]
    assert all(d.end_margin_m == 200.0 and d.forced_merge_m == 120.0 for d in drivers)
    assert all(d.merge_seek is True and d.hold_on_entry is True for d in drivers)  # the defaults
    sc = build_scenario(load_scenario_config(None, {"bvs.makeup": "uniform", "traffic.warmup_s": 0, "models.learned.merge_seek": False,
                                                    "models.learned.hold_on_entry": False}))
    assert all(d.merge_seek is False and d.hold_on_entry is False for _, d in sc.bv_driver.parts)


def test_merge_seek_drops_back_behind_a_blocker_alongside_or_just_ahead(road):
    # the merging vehicle 0 on the merge lane (0) at 700 m, its forced target lane 1 (+1); vehicles 4.8 m long
    one = np.array([1])
    des = np.array([30.0])
    # alongside at the same speed: a negative bumper gap -> the bounded braking of 3 m/s²
    w = hand_built_world(road, s=[700, 702], lane=[0, 1], speed=[25, 25])
    assert merge_seek_accel(w, np.array([0]), one, des).tolist() == [-3.0]
    # 30 m ahead at the same speed: bumper gap 25.2 m >= the 10 m the change needs -> no bound
    w = hand_built_world(road, s=[700, 730], lane=[0, 1], speed=[25, 25])
    assert merge_seek_accel(w, np.array([0]), one, des).tolist() == [np.inf]
    # wholly behind (front 0.2 m behind its rear), too close for the change: it never makes it brake
    w = hand_built_world(road, s=[700, 690.2], lane=[0, 1], speed=[25, 25])
    assert merge_seek_accel(w, np.array([0]), one, des).tolist() == [np.inf]
    # just ahead and faster (v 20 behind 25): bumper gap 9.2 m < 10 m; IDM with s* = max(10 + 20·1 +
    # 20·(-5)/(2·sqrt(1·1.5)), 10) = 10: a = 1·(1 - (20/30)^4 - (10/9.2)^2) = -0.3789
    w = hand_built_world(road, s=[700, 714], lane=[0, 1], speed=[20, 25])
    a = merge_seek_accel(w, np.array([0]), one, des)[0]
    assert a == pytest.approx(1.0 - (20 / 30) ** 4 - (10 / 9.2) ** 2, abs=1e-9)
    # no forced target: no bound
    w = hand_built_world(road, s=[700, 702], lane=[0, 1], speed=[25, 25])
    assert merge_seek_accel(w, np.array([0]), np.array([0]), des).tolist() == [np.inf]
    # two blockers (one alongside, one 9.2 m ahead): the rearmost, alongside, sets the bound
    w = hand_built_world(road, s=[700, 702, 723.8], lane=[0, 1, 1], speed=[25, 25, 25])
    assert merge_seek_accel(w, np.array([0]), one, des).tolist() == [-3.0]
    # 30 m ahead, 10 m/s slower: bumper gap 25.2 m >= 10 + 1.5·10 = 25 m -> no bound; the profile's
    # closing term (c²/(2b), b = 4) widens what blocks: 10 + 15 + 100/8 = 37.5 m > 25.2 m
    w = hand_built_world(road, s=[700, 730], lane=[0, 1], speed=[25, 15])
    assert merge_seek_accel(w, np.array([0]), one, des).tolist() == [np.inf]
    assert merge_seek_accel(w, np.array([0]), one, des, closing_decel_mps2=4.0)[0] < 0.0
