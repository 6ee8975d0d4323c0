"""Stackelberg lane-change decision: hand-built situations, expectations derived by hand.

Default parameters throughout unless a test says otherwise: 3 game steps of 1 s; leader and
followers accelerate +2 m/s², decelerate −3 m/s²; d_v = 100 m, T = 1.5 s, d_min = 2.5 m;
vehicles are 4.8 m long, so two centres 30 m apart are a 25.2 m bumper gap. With nobody
behind, U_neg = d_v − d_min = 97.5; with nobody ahead, U_pos = d_v = 100.

Distances a vehicle covers in the three 1 s phases (constant acceleration per phase):

* the ego (leader) holds a1 in phases 1–2 and picks a2 in phase 3; from 25 m/s:
  dec/dec 23.5 + 20.5 + 17.5 = 61.5 m (ends at 16 m/s), keep/dec 25 + 25 + 23.5 = 73.5 m,
  keep/acc 25 + 25 + 26 = 76 m (27 m/s), acc/acc 26 + 28 + 30 = 84 m (31 m/s);
* a player keeps its speed in phase 1 and responds in phases 2–3; from 25 m/s:
  acc 25 + 26 + 28 = 79 m (29 m/s), keep 75 m, dec 25 + 23.5 + 20.5 = 69 m (19 m/s);
  from 20 m/s: acc 20 + 21 + 23 = 64 m, keep 60 m, dec 20 + 18.5 + 15.5 = 54 m.
"""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_sim.config.scenario_config import config_from_dict
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.road.road_model import load_road
from evoscen_sut.stackelberg import (
    FOLLOWER_RESPONSES,
    LEADER_ACTIONS,
    SPEC,
    StackelbergDriver,
    StackelbergParams,
    decide,
    game_values,
    lane_change_decision,
    relevant_followers,
)

ROW = {action: k for k, action in enumerate(LEADER_ACTIONS)}
COL = {response: k for k, response in enumerate(FOLLOWER_RESPONSES)}


@pytest.fixture(scope="module")
def road():
    return load_road()


def _decision(world, params=StackelbergParams()) -> int:
    return int(lane_change_decision(world, np.array([0]), params)[0])


def test_matrix_layout():
    assert len(LEADER_ACTIONS) == 9 and len(FOLLOWER_RESPONSES) == 9
    assert LEADER_ACTIONS[:3] == ((0, "keep"), (0, "accelerate"), (0, "decelerate"))  # ties keep the lane
    assert {lane for lane, _ in LEADER_ACTIONS} == {-1, 0, 1}


def test_slow_leader_and_free_left_lane_changes_left(road):
    # ego lane 2 at 30 m/s, 25.2 m behind a 20 m/s leader; a 20 m/s vehicle in lane 1 ahead
    # (so the right lane is no better than the own); lane 3 empty.
    w = hand_built_world(road, s=[300, 330, 340], lane=[2, 2, 1], speed=[30, 20, 20])
    g = game_values(w, 0)
    # left: nobody in lane 3 -> 100 + 97.5 whatever anyone does
    assert np.allclose(g[3:6], 197.5)
    # keep, best case: the leader accelerates (64 m), the ego brakes twice
    # (30 -> 27 -> 24 -> 21: 28.5 + 25.5 + 22.5 = 76.5 m): 25.2 + 64 - 76.5 = 12.7 -> 110.2
    assert g[:3].max() == pytest.approx(110.2)
    assert _decision(w) == 1


def test_fast_vehicle_closing_in_the_left_lane_keeps_the_lane(road):
    # ego lane 1 at 25 m/s, leader 35.2 m ahead at 22 m/s; lane 0 does not exist at 300 m.
    free = hand_built_world(road, s=[300, 340], lane=[1, 1], speed=[25, 22])
    assert _decision(free) == 1  # the left lane is free: 197.5 beats keeping (131.2, below)
    # now a 35 m/s vehicle 10.2 m behind in lane 2: already within the safety margin
    # (10.2 - 10 * 1.5 - 2.5 < 0)
    w = hand_built_world(road, s=[300, 340, 285], lane=[1, 1, 2], speed=[25, 22, 35])
    g = game_values(w, 0)
    # players: own leader (constant-speed gap after 3 s 35.2 - 3 * 3 = 26.2) and the closing
    # vehicle (10.2 - 10 * 3 = -19.8, first)
    assert relevant_followers(w, 0).tolist() == [2, 1]
    assert np.all(np.isneginf(g[6:]))  # no lane 0 at s = 300
    # keep, worst case: the leader brakes (22 + 20.5 + 17.5 = 60 m); the ego brakes twice
    # (61.5 m): 35.2 + 60 - 61.5 = 33.7 -> 33.7 + 97.5 = 131.2
    assert g[:3].min(axis=1).max() == pytest.approx(131.2)
    # left, worst case: the fast vehicle accelerates (35 + 36 + 38 = 109 m, ends at 39 m/s);
    # the ego's best reply is acc/acc (84 m, 31 m/s): d_back = 10.2 + 84 - 109 = -14.8,
    # U_neg = -14.8 - (39 - 31) * 1.5 - 2.5 = -29.3 -> 70.7
    assert g[ROW[(1, "accelerate")], COL[("accelerate", "keep")]] == pytest.approx(70.7)
    assert g[3:6].min(axis=1).max() == pytest.approx(70.7)
    assert _decision(w) == 0


def test_merge_lane_near_its_end_changes_onto_the_mainline(road):
    # alone on the merge lane (ends at 960 m) at 880 m, 25 m/s: the end is 960 - 880 - 2.4 =
    # 77.6 m ahead; braking twice (61.5 m) leaves 16.1 -> keep is worth at most 113.6
    w = hand_built_world(road, s=[880], lane=[0], speed=[25])
    g = game_values(w, 0)
    assert g[:3].max() == pytest.approx(16.1 + 97.5)
    assert np.allclose(g[3:6], 197.5)
    assert np.all(np.isneginf(g[6:]))  # no lane to the right of lane 0
    assert _decision(w) == 1
    # 260 m before the end the end is beyond the view distance: indifferent, keep the lane
    assert _decision(hand_built_world(road, s=[700], lane=[0], speed=[25])) == 0


@pytest.mark.parametrize("lane", [1, 2, 3, 4])
def test_empty_road_keeps_the_lane(road, lane):
    w = hand_built_world(road, s=[1200], lane=[lane], speed=[30])
    g = game_values(w, 0)
    assert np.allclose(g[np.isfinite(g[:, 0])], 197.5)
    assert np.isneginf(g[3, 0]) == (lane == 4)  # no lane left of lane V
    assert _decision(w) == 0


def test_worst_case_choice_differs_from_the_greedy_best_case(road):
    # ego lane 2 at 500 m, 25 m/s. Own lane: a 20 m/s leader 25.2 m ahead. Right (lane 1): a
    # 25 m/s vehicle 40.2 m ahead, nobody behind. Left (lane 3): a 25 m/s vehicle 25.2 m
    # behind, nobody ahead.
    w = hand_built_world(road, s=[500, 530, 545, 470], lane=[2, 2, 1, 3], speed=[25, 20, 25, 25])
    # players by constant-speed gap after 3 s: own leader 25.2 - 15 = 10.2, left follower
    # 25.2; the right-lane vehicle (40.2) keeps its speed
    assert relevant_followers(w, 0).tolist() == [1, 3]
    g = game_values(w, 0)
    up, keep, down = "accelerate", "keep", "decelerate"
    # right: 40.2 + 75 - x_ego, nobody behind; the best a2 is to brake
    assert np.allclose(g[ROW[(-1, down)]], 40.2 + 75 - 61.5 + 97.5)  # 151.2
    assert np.allclose(g[ROW[(-1, keep)]], 40.2 + 75 - 73.5 + 97.5)  # 139.2
    # left: 100 + min(d_back - v_r T, 100) - 2.5 with d_back = 25.2 + x_ego - x_follower;
    # ego acc/acc (84 m, 31 m/s) against the follower's
    #   acc (79 m, 29 m/s): 30.2 + 2 * 1.5 = 33.2  -> 130.7
    #   keep (75 m, 25 m/s): 34.2 + 6 * 1.5 = 43.2 -> 140.7
    #   dec (69 m, 19 m/s): 40.2 + 12 * 1.5 = 58.2 -> 155.7
    # (the own leader's response does not matter in lane 3)
    for own in (up, keep, down):
        assert g[ROW[(1, up)], COL[(own, up)]] == pytest.approx(130.7)
        assert g[ROW[(1, up)], COL[(own, keep)]] == pytest.approx(140.7)
        assert g[ROW[(1, up)], COL[(own, down)]] == pytest.approx(155.7)
    # left with a1 = keep: best a2 = accelerate (76 m, 27 m/s) against an accelerating
    # follower: 25.2 + 76 - 79 = 22.2, - 2 * 1.5 = 19.2 -> 116.7
    assert g[ROW[(1, keep)], COL[(keep, up)]] == pytest.approx(116.7)
    # keep lane, ego brakes twice (61.5 m) behind the leader who
    #   accelerates (64 m): 27.7 -> 125.2, keeps (60 m): 23.7 -> 121.2, brakes (54 m): 17.7 -> 115.2
    assert g[ROW[(0, down)], COL[(up, keep)]] == pytest.approx(125.2)
    assert g[ROW[(0, down)], COL[(keep, keep)]] == pytest.approx(121.2)
    assert g[ROW[(0, down)], COL[(down, keep)]] == pytest.approx(115.2)
    worst = g.min(axis=1)
    best = g.max(axis=1)
    assert worst[:3].max() == pytest.approx(115.2)
    assert worst[3:6].max() == pytest.approx(130.7)
    assert worst[6:].max() == pytest.approx(151.2)
    # greedy (best case): left, 155.7 > 151.2; worst case: right, 151.2 > 130.7 > 115.2
    assert LEADER_ACTIONS[int(np.argmax(best))] == (1, up)
    assert LEADER_ACTIONS[int(np.argmax(worst))] == (-1, down)
    assert decide(g, 1.0) == -1
    assert _decision(w) == -1


def test_hysteresis_keeps_the_lane_for_a_small_gain(road):
    # the left lane's worst case (197.5) beats keeping by 197.5 - 131.2 = 66.3 m
    w = hand_built_world(road, s=[300, 340], lane=[1, 1], speed=[25, 22])
    assert _decision(w, StackelbergParams(lane_change_threshold_m=66.0)) == 1
    assert _decision(w, StackelbergParams(lane_change_threshold_m=67.0)) == 0


def test_one_step_game_ignores_the_followers(road):
    w = hand_built_world(road, s=[500, 530, 545, 470], lane=[2, 2, 1, 3], speed=[25, 20, 25, 25])
    g = game_values(w, 0, StackelbergParams(steps=1))
    assert np.allclose(g, g[:, :1])
    # one second: keep lane, ego brakes (23.5 m), leader keeps (20 m): 25.2 + 20 - 23.5 = 21.7
    assert g[ROW[(0, "decelerate")], 0] == pytest.approx(21.7 + 97.5)


def test_no_request_while_a_lane_change_is_in_progress(road):
    w = hand_built_world(road, s=[300, 330, 340], lane=[2, 2, 1], speed=[30, 20, 20])
    assert _decision(w) == 1
    w.step(np.zeros(3), np.array([1, 0, 0]))
    assert w.lane_change[0] == 1
    assert _decision(w) == 0


def test_driver_lane_request_and_krauss_throttle(road):
    cfg = config_from_dict({}, source="test")
    driver = SPEC.factory(np.array([0]), StackelbergParams(), cfg, np.random.default_rng(0))
    assert isinstance(driver, StackelbergDriver)
    w = hand_built_world(road, s=[300, 330, 340], lane=[2, 2, 1], speed=[30, 20, 20])
    throttle, request = driver.act(w)
    assert request.tolist() == [1]
    assert -1.0 <= throttle[0] < 0.0  # 10 m/s faster than a leader 25 m ahead: Krauss brakes
    # empty road below the limit: keep the lane, Krauss accelerates
    throttle, request = driver.act(hand_built_world(road, s=[1200], lane=[2], speed=[25]))
    assert request.tolist() == [0] and throttle[0] > 0.0


def test_spec():
    assert SPEC.name == "stackelberg" and SPEC.roles == ("sut",)
    assert SPEC.params_type is StackelbergParams
    p = StackelbergParams()
    assert (p.steps, p.view_distance_m, p.time_headway_s, p.min_gap_m) == (3, 100.0, 1.5, 2.5)


def test_a_vehicle_alongside_in_the_target_lane_stops_the_change(road):
    # Ego lane 2 at 30 m/s behind a 20 m/s leader (25.2 m), a 20 m/s vehicle in lane 1 40 m ahead of the
    # ego's centre; in lane 3 a 35 m/s car alongside, its centre 2 m ahead of the ego's: bumper gap
    # 2 - 4.8 = -2.8 m. The players are the own leader and the lane-1 vehicle, so the lane-3 car keeps
    # its speed: 105 m in the 3 s. Left with a1 = decelerate and a2 = decelerate (the best second move:
    # nobody behind in lane 3): the ego covers 28.5 + 25.5 + 22.5 = 76.5 m, d_front = -2.8 + 105 - 76.5
    # = 25.7, U_neg = 100 - 2.5 = 97.5: 123.2 whatever the players do, the best worst case of all rows,
    # so the end-of-game rule changes left into the car's side. d_min now (2.5 m) forbids every left
    # row (-inf); the best is then the right lane: its worst case, the lane-1 player braking (54 m), is
    # 35.2 + 54 - 76.5 + 97.5 = 110.2 against keeping's 100.2.
    w = hand_built_world(road, s=[300, 330, 340, 302], lane=[2, 2, 1, 3], speed=[30, 20, 20, 35])
    old = StackelbergParams(target_gap_rule="end_of_game")
    assert game_values(w, 0, old)[ROW[(1, "decelerate")]] == pytest.approx(np.full(9, 123.2))
    assert _decision(w, old) == 1
    g = game_values(w, 0)
    assert np.all(g[3:6] == -np.inf)
    assert g.min(axis=1)[:3].max() == pytest.approx(100.2) and g.min(axis=1)[6:].max() == pytest.approx(110.2)
    assert _decision(w) == -1
    # a leader 3 m ahead of the ego's front in lane 3 (>= d_min 2.5): allowed again; 2 m: not
    for s_car, allowed in ((307.8, True), (306.8, False)):
        w = hand_built_world(road, s=[300, 330, 340, s_car], lane=[2, 2, 1, 3], speed=[30, 20, 20, 35])
        assert (game_values(w, 0)[3:6].max() > -np.inf) == allowed, s_car
    # behind: a follower with 2 m of bumper gap in lane 3 (< 2.5) forbids it too; the old rule did not
    w = hand_built_world(road, s=[300, 330, 340, 293.2], lane=[2, 2, 1, 3], speed=[30, 20, 20, 20])
    assert np.all(game_values(w, 0)[3:6] == -np.inf)
    assert np.all(game_values(w, 0, old)[3:6] > -np.inf)


def test_a_vehicle_changing_into_the_target_lane_from_the_far_side_counts(road):
    # The lane-3 situation above without the car in lane 3; instead a 17.9-m truck in lane 4 changing into
    # lane 3 (its target lane), its centre 8 m ahead of the ego's: gap 8 - (17.9 + 4.8) / 2 = -3.35 m. By
    # centre it is not in lane 3, so the end-of-game rule changes left towards its side; d_min now does not.
    w = hand_built_world(road, s=[300, 330, 340, 308], lane=[2, 2, 1, 4], speed=[30, 20, 20, 15])
    w.length[3] = 17.9
    w.target_lane[3] = 3
    w.lane_change[3] = -1
    assert _decision(w, StackelbergParams(target_gap_rule="end_of_game")) == 1
    assert np.all(game_values(w, 0)[3:6] == -np.inf)
    # one in lane 3 leaving it to the far side (lane 4) does not count: the left rows are available
    w = hand_built_world(road, s=[300, 330, 340, 308], lane=[2, 2, 1, 3], speed=[30, 20, 20, 15])
    w.length[3] = 17.9
    w.target_lane[3] = 4
    w.lane_change[3] = 1
    from evoscen_sut.stackelberg import _target_lane_neighbours

    gap_f, v_f, gap_r, _ = _target_lane_neighbours(0, w.s, w.v, w.length, w.lane, w.target_lane)
    assert gap_f[2] == np.inf and gap_r[2] == np.inf and np.isnan(v_f[2])
    # entering from lane 4 (the first world): the truck is the leader of lane 3 at -3.35 m, 15 m/s
    w = hand_built_world(road, s=[300, 330, 340, 308], lane=[2, 2, 1, 4], speed=[30, 20, 20, 15])
    w.length[3] = 17.9
    w.target_lane[3] = 3
    gap_f, v_f, gap_r, _ = _target_lane_neighbours(0, w.s, w.v, w.length, w.lane, w.target_lane)
    assert gap_f[2] == pytest.approx(8 - 11.35) and v_f[2] == 15.0 and gap_r[2] == np.inf
    assert gap_f[0] == pytest.approx(40 - 4.8)  # lane 1: the 20 m/s vehicle 40 m ahead
