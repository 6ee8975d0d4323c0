"""BV run-time rule profiles (docs/bv-profiles.md): reaction time, bounded braking, the old rules kept exactly."""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_bringup.model_testing import commands_digest
from evoscen_bv.lane_change_decision import apply_rule_constraints
from evoscen_bv.learned import LearnedDriver, load_policies, shipped_policy_dir
from evoscen_bv.profile import PROFILES, get_profile
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.road.road_model import load_road

N = 10
"""Reaction steps of the driver profile: τ / dt = 1.0 s / 0.1 s."""
CAP = 7.0 / 8.0
"""Its braking bound as a throttle: 7 m/s² of the vehicle's 8 m/s² full brake."""


@pytest.fixture(scope="module")
def road():
    return load_road()


@pytest.fixture(scope="module")
def policies():
    return load_policies(shipped_policy_dir())


def _driver(policies, world, vehicles, profile):
    controller, _, training = policies
    return LearnedDriver(np.asarray(vehicles), controller, {}, training, np.random.default_rng(0), world.vehicle,
                         profile=profile)


def test_profile_parameters():
    assert get_profile("driver").reaction_steps(0.1) == N
    assert get_profile("driver").max_decel_mps2 == 7.0
    assert get_profile("safety_net").reaction_time_s == 0.0 and get_profile("safety_net").max_decel_mps2 is None
    assert {p.cut_in_closing_headway_s for p in PROFILES.values()} == {1.5}
    assert {p.cut_in_closing_decel_mps2 for p in PROFILES.values()} == {None}  # the term is opt-in
    with pytest.raises(ValueError, match="unknown BV profile 'nice': expected one of driver, safety_net"):
        get_profile("nice")


def _cut_in(road, policies, profile: str, cut_in: bool, steps: int) -> tuple[list[float], list[int]]:
    """BV 0 at 25 m/s in lane 2; vehicle 1 at 20 m/s in lane 3, its rear bumper 8 m ahead of the BV's
    front (closing 5 m/s), changes into lane 2 after the first step when ``cut_in``. Returns the BV's
    throttles from the first step on which vehicle 1 occupies lane 2, and vehicle 1's lane-change flags."""
    w = hand_built_world(road, s=[300.0, 312.8], lane=[2, 3], speed=[25.0, 20.0])  # 12.8 m - 4.8 m of length = 8 m
    assert w.s[1] - w.s[0] - 0.5 * (w.length[0] + w.length[1]) == pytest.approx(8.0)
    bv = _driver(policies, w, [0], profile)
    w.step(np.array([bv.throttle(w)[0], 0.0]), np.array([0, -1 if cut_in else 0]))  # the first call: before the cut-in
    out, changing = [], []
    for _ in range(steps):
        u = float(bv.throttle(w)[0])
        out.append(u)
        changing.append(int(w.lane_change[1]))
        w.step(np.array([u, 0.0]), np.zeros(2, dtype=np.int64))
    return out, changing


def test_safety_net_brakes_at_once_for_a_cut_in(road, policies):
    cut, changing = _cut_in(road, policies, "safety_net", True, 3)
    free, _ = _cut_in(road, policies, "safety_net", False, 3)
    assert changing[0] == -1  # vehicle 1 is changing into lane 2 from the first step on
    assert cut[0] < 0.0 < free[0]  # the BV brakes on step 0 of the cut-in (without it, it would accelerate)


def test_driver_keeps_its_throttle_for_the_reaction_time_then_brakes_at_most_at_the_cap(road, policies):
    cut, changing = _cut_in(road, policies, "driver", True, N + 5)
    free, _ = _cut_in(road, policies, "driver", False, N + 5)
    assert changing[0] == -1
    # steps 0 … N-1: the cut-in vehicle is not perceived yet, the BV drives exactly as without it
    assert cut[:N] == free[:N]
    assert free[0] > 0.0
    # step N (1 s): it responds, braking, but never harder than the driver's 7 m/s²
    assert cut[N] < 0.0 and cut[N] < free[N]
    assert min(cut) >= -CAP - 1e-12


def test_bounded_braking_for_a_standing_vehicle(road, policies):
    """BV at 30 m/s, a standing vehicle 20.2 m ahead (bumper gap) from the start: the emergency brake wants
    30² / (2 (20.2 - 2)) = 24.7 m/s²: full brake (-1) with safety_net, the 7 m/s² bound (-0.875) with driver
    (at the first step every situation counts as having persisted)."""
    for profile, expected in (("safety_net", -1.0), ("driver", -CAP)):
        w = hand_built_world(road, s=[400.0, 425.0], lane=[2, 2], speed=[30.0, 0.0])
        bv = _driver(policies, w, [0], profile)
        assert bv.throttle(w)[0] == pytest.approx(expected), profile
        # a second call at the same step changes nothing (the reaction state advances once per step)
        assert bv.throttle(w)[0] == pytest.approx(expected), profile


def test_driver_emergency_brake_waits_for_the_reaction_time(road, policies):
    """A leader 30.2 m ahead at the BV's speed (25 m/s) brakes at the world's full 8 m/s² from step 0 on.
    From step 1 its deceleration is visible and the emergency brake asks for b ≈ 4.85 m/s² (stop behind
    the point where the leader stops) >= the 4 m/s² trigger. safety_net: the throttle is -b/8 at step 1.
    driver: the trigger holds from step 1, so the emergency brake acts from step 1 + N on (at -b/8, b < 7);
    before that the BV keeps its controller's 0."""
    from evoscen_bv.car_following import _emergency_need

    res, needs = {}, {}
    for profile in ("safety_net", "driver"):
        w = hand_built_world(road, s=[400.0, 435.0], lane=[2, 2], speed=[25.0, 25.0])
        # a controller that asks for 0 whatever it sees, so that only the emergency brake brakes
        bv = LearnedDriver(np.array([0]), _constant_controller(0.0), {}, policies[2], np.random.default_rng(0),
                           w.vehicle, profile=profile)
        us, bs = [], []
        for _ in range(N + 3):
            gap = w.s[1] - w.s[0] - 0.5 * (w.length[0] + w.length[1])
            bs.append(_emergency_need(gap, w.v[1], w.accel[1], w.v[0], 2.0))
            u = float(bv.throttle(w)[0])
            us.append(u)
            w.step(np.array([u, -1.0]), np.zeros(2, dtype=np.int64))
        res[profile], needs[profile] = us, bs
    sn, dr, b = res["safety_net"], res["driver"], needs["driver"]
    assert needs["safety_net"][0] == 0.0 and needs["safety_net"][1] >= 4.0
    assert sn[1] == pytest.approx(-needs["safety_net"][1] / 8.0)  # at once
    assert all(b[k] >= 4.0 for k in range(1, N + 3))
    assert all(dr[k] > -b[k] / 8.0 + 1e-9 for k in range(1, N + 1))  # steps 1 … N: not yet
    assert dr[N + 1] == pytest.approx(-min(b[N + 1], 7.0) / 8.0)  # step N + 1: the trigger held at steps 1 … N + 1
    assert min(dr) >= -CAP - 1e-12


def _commands_digest(cfg_overrides: dict, steps: int) -> str:
    """:func:`evoscen_bringup.model_testing.commands_digest` with learned BVs."""
    return commands_digest({"bvs.driver": "learned", "bvs.makeup": "uniform", **cfg_overrides}, steps)


OLD_COMMANDS_SHA256 = "c156b9b4e8f8b032f478a0f2ef18fa95e8884facaf2f9a9c8df1081f4edb08fb"
"""Every BV and SUT command of 400 steps of the default scenario with learned BVs, seed 3, SUT mobil,
computed with the code before profiles existed (commit 33305ed) on the development machine."""


def test_safety_net_reproduces_the_old_commands_exactly():
    # the old commands came from the first shipped policies (kept as policy_dir: v0.1.0) and a
    # lateral loop without the heading-reference cap (evoscen_sim.physics.control; 1.5 rad never binds: asin(0.6) < 0.65)
    # and no lane hold (lane_hold_s: 0; docs/learned-bvs.md), no speed adaptation of merging BVs (merge_seek),
    # every BV yielding on the SUT's lane-change intent (competitive_cut_in: yield)
    old = {"models": {"learned": {"profile": "safety_net", "policy_dir": "v0.1.0", "lane_hold_s": 0,
                                  "into_ending_lane": True, "forced_merge_m": 120.0, "merge_seek": False,
                                  "competitive_cut_in": "yield"}},
           "control.max_heading_ref_rad": 1.5, "traffic.mode": "loop", "bvs.makeup": "uniform"}  # and re-entry at the road's start
    assert _commands_digest(old, 400) == OLD_COMMANDS_SHA256
    # the driver profile drives differently
    assert _commands_digest({"models": {"learned": {"policy_dir": "v0.1.0"}}}, 400) != OLD_COMMANDS_SHA256


def test_cut_in_gap_headway_is_a_parameter(road):
    """Vehicle 0 (25 m/s, lane 1) asks to move left; vehicle 1 in lane 2 is 12.2 m ahead (bumper gap) at 20 m/s:
    closing 5 m/s. h = 1.5 s needs 10 + 7.5 = 17.5 m → keep; the method's plain 10 m (h = 0) → change."""
    w = hand_built_world(road, s=[300.0, 317.0], lane=[1, 2], speed=[25.0, 20.0])
    assert apply_rule_constraints(w, np.array([0]), np.array([1])).tolist() == [0]
    assert apply_rule_constraints(w, np.array([0]), np.array([1]), 1.5).tolist() == [0]
    assert apply_rule_constraints(w, np.array([0]), np.array([1]), 0.0).tolist() == [1]


def test_cut_in_gap_quadratic_term_for_followers_that_react_late(road):
    """Vehicle 0 (5 m/s, lane 1, leaving a queue) asks to move left in front of vehicle 1 in lane 2 at 25 m/s:
    closing c = 20 m/s. Linear gap 10 + 1.5·20 = 40 m; with b = 4 m/s² a further c²/(2b) = 400/8 = 50 m: 90 m.
    Bumper gaps (centres 5 m longer): 60 m → change under the linear rule only; 91 m → change under both;
    89 m → keep under b = 4 (R5, docs/bv-profiles.md: models.learned.cut_in_decel_mps2)."""
    for gap, linear, quadratic in ((60.0, 1, 0), (89.0, 1, 0), (91.0, 1, 1)):
        w = hand_built_world(road, s=[400.0, 400.0 - gap - 5.0], lane=[1, 2], speed=[5.0, 25.0])
        assert apply_rule_constraints(w, np.array([0]), np.array([1]), 1.5).tolist() == [linear]
        assert apply_rule_constraints(w, np.array([0]), np.array([1]), 1.5, None).tolist() == [linear]
        assert apply_rule_constraints(w, np.array([0]), np.array([1]), 1.5, 4.0).tolist() == [quadratic]
    # a faster vehicle ahead closes nothing: the plain 10 m whatever b (bumper gap 10.5 m)
    w = hand_built_world(road, s=[400.0, 415.5], lane=[1, 2], speed=[20.0, 30.0])
    assert apply_rule_constraints(w, np.array([0]), np.array([1]), 1.5, 4.0).tolist() == [1]


def test_profile_config_errors_are_one_line(tmp_path):
    from evoscen_bv.training_config import load_training_config
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.errors import InputError

    with pytest.raises(InputError, match=r"models\.learned\.profile.*expected one of driver, safety_net") as e:
        config_from_dict({"models": {"learned": {"profile": "nice"}}})
    assert "\n" not in str(e.value)
    bad = tmp_path / "t.yaml"
    bad.write_text("env: {profile: nice}\n")
    with pytest.raises(InputError, match=r"'env\.profile' = 'nice': expected one of driver, safety_net") as e:
        load_training_config(bad)
    assert "\n" not in str(e.value)


def test_training_config_records_the_profile(tmp_path, policies):
    from evoscen_bv.training_config import load_training_config

    assert load_training_config().env.profile == "driver"  # new trainings: the driver profile
    assert policies[2].env.profile == "driver"  # the shipped policies were trained under driver
    assert load_policies(shipped_policy_dir() / "v0.1.0")[2].env.profile == "safety_net"  # the first set: the old rules
    (tmp_path / "t.yaml").write_text("env: {profile: safety_net}\n")
    cfg = load_training_config(tmp_path / "t.yaml")
    assert cfg.to_dict()["env"]["profile"] == "safety_net"
    w = hand_built_world(load_road(), s=[300.0], lane=[2], speed=[25.0])
    controller, _, _ = policies
    # the training environments' drivers take the config's profile; the scenario's key overrides it at run time
    assert LearnedDriver(np.array([0]), controller, {}, cfg, np.random.default_rng(0), w.vehicle).profile.name == "safety_net"
    assert LearnedDriver(np.array([0]), controller, {}, cfg, np.random.default_rng(0), w.vehicle,
                         profile="driver").profile.name == "driver"


def test_scenario_default_profile_is_driver():
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.scenario_builders import build_bv_driver

    drv = build_bv_driver(config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"}}))
    assert drv.profile.name == "driver"
    drv = build_bv_driver(config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"}, "models": {"learned": {"profile": "safety_net"}}}))
    assert drv.profile.name == "safety_net"


def _constant_actor(side: int):
    """A decision actor whose output is tanh(±2) = ±0.96 whatever it sees: it asks for ``side`` always."""
    from evoscen_bv.lane_change_decision import OBS_DIM
    from evoscen_bv.td3 import NumpyActor

    h = 4
    return NumpyActor({"W1": np.zeros((OBS_DIM, h)), "b1": np.zeros(h), "W2": np.zeros((h, h)), "b2": np.zeros(h),
                       "W3": np.zeros((h, 1)), "b3": np.array([2.0 * side]), "max_action": np.array(1.0)})


def _lane_change_starts(road, policies, hold_s: float, steps: int) -> tuple[list[int], list[int]]:
    """A lone BV in lane 1 at 25 m/s whose policy always asks to go left: (steps at which a change starts,
    steps at which one ends — the lane_change column back to 0)."""
    controller, _, training = policies
    w = hand_built_world(road, s=[1200.0], lane=[1], speed=[25.0])
    bv = LearnedDriver(np.array([0]), controller, {1: _constant_actor(+1)}, training, np.random.default_rng(0),
                       w.vehicle, forced_merge=True, profile="driver", lane_hold_s=hold_s)
    starts, ends, was = [], [], 0
    for k in range(steps):
        assert w.step_index == k
        u, req = bv.act(w)
        w.step(u, req)
        now = int(w.lane_change[0])
        if now and not was:
            starts.append(k)
        if was and not now:
            ends.append(k + 1)  # the state after step k is the first with the column back to 0
        was = now
    return starts, ends


def test_lane_hold_keeps_the_new_lane_for_the_hold_then_decides_again(road, policies):
    # decisions every 10 steps (1 s). Without a hold the next change starts at the first decision step
    # at or after the previous change ended; with a 20 s hold (200 steps) at the first one at or after end + 200.
    free_starts, free_ends = _lane_change_starts(road, policies, 0.0, 400)
    held_starts, held_ends = _lane_change_starts(road, policies, 20.0, 400)
    assert free_starts[0] == held_starts[0] == 0 and free_ends[0] == held_ends[0]
    end = held_ends[0]
    assert 10 < end < 100  # one lane change takes a few seconds

    def next_decision(k):
        return -(-k // 10) * 10

    assert free_starts[1] == next_decision(end)
    assert held_starts[1] == next_decision(end + 200)
    assert len(free_starts) == 3 and len(held_starts) == 2  # lane 1 -> 2 -> 3 -> 4 (the left edge) vs 1 -> 2 -> 3


def test_lane_hold_spares_the_forced_merge_and_is_reset_by_a_reentry(road, policies):
    controller, _, training = policies
    # vehicle 0 on the merge lane 110 m before its end (the forced zone), vehicle 1 in lane 2: both held
    w = hand_built_world(road, s=[850.0, 1500.0], lane=[0, 2], speed=[20.0, 25.0])
    bv = LearnedDriver(np.array([0, 1]), controller, {1: _constant_actor(-1)}, training, np.random.default_rng(0),
                       w.vehicle, forced_merge=True, profile="driver", lane_hold_s=20.0)
    bv.hold_until_step[:] = 10**6
    _, requested, executed = bv.decide(w, np.array([0, 1]))
    assert requested.tolist() == [1, -1]  # the forced merge's left; the policy's right
    assert executed.tolist() == [1, 0]  # the forced merge goes ahead, the held policy request becomes keep
    unheld = LearnedDriver(np.array([0, 1]), controller, {1: _constant_actor(-1)}, training,
                           np.random.default_rng(0), w.vehicle, forced_merge=True, profile="driver", lane_hold_s=20.0)
    assert unheld.decide(w, np.array([0, 1]))[2].tolist() == [1, -1]
    # a fall of s is a re-entry (a new vehicle at the road's start): its hold ends
    bv.act(w)
    w.s[1] = 100.0
    bv.act(w)
    assert bv.hold_until_step.tolist() == [10**6, -1]
    # with hold_on_entry the entered vehicle starts a fresh hold of 20 s = 200 steps from this step
    entry = LearnedDriver(np.array([0, 1]), controller, {1: _constant_actor(-1)}, training,
                          np.random.default_rng(0), w.vehicle, forced_merge=True, profile="driver", lane_hold_s=20.0,
                          hold_on_entry=True)
    entry.hold_until_step[:] = 10**6
    entry.act(w)
    w.s[1] = 1400.0  # 1,300 m forwards in one step: an entry
    entry.act(w)
    assert entry.hold_until_step.tolist() == [10**6, int(w.step_index) + 200]
    _, requested, executed = entry.decide(w, np.array([0, 1]))
    assert requested.tolist() == [1, -1] and executed.tolist() == [1, 0]  # the forced merge exempt, the entry held
    with pytest.raises(ValueError, match="lane_hold_s must be >= 0"):
        LearnedDriver(np.array([0]), controller, {}, training, np.random.default_rng(0), w.vehicle, lane_hold_s=-1.0)


def test_lane_hold_is_a_scenario_key_with_the_old_form_selectable():
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.errors import InputError
    from evoscen_sim.scenario_builders import build_bv_driver

    assert build_bv_driver(config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"}})).lane_hold_s == 20.0
    assert build_bv_driver(config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"},
                                             "models": {"learned": {"lane_hold_s": 0}}})).lane_hold_s == 0.0
    with pytest.raises(InputError, match=r"models\.learned\.lane_hold_s") as e:
        config_from_dict({"models": {"learned": {"lane_hold_s": -3}}})
    assert "\n" not in str(e.value)


def test_cut_in_decel_is_a_scenario_key_with_the_old_rule_selectable():
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.errors import InputError
    from evoscen_sim.scenario_builders import build_bv_driver

    def b(models: dict) -> float | None:
        return build_bv_driver(config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"}, "models": models})).profile \
            .cut_in_closing_decel_mps2

    assert b({}) is None  # the linear gap only
    assert b({"learned": {"cut_in_decel_mps2": 4}}) == 4.0
    assert b({"learned": {"cut_in_decel_mps2": 0}}) is None
    assert b({"learned": {"profile": "safety_net", "cut_in_decel_mps2": 6}}) is None  # safety_net: rules as they were
    with pytest.raises(InputError, match=r"models\.learned\.cut_in_decel_mps2") as e:
        config_from_dict({"models": {"learned": {"cut_in_decel_mps2": -1}}})
    assert "\n" not in str(e.value)


def _constant_controller(throttle_z: float):
    """A car-following actor whose output is tanh(z) whatever it sees."""
    from evoscen_bv.td3 import NumpyActor

    h = 4
    return NumpyActor({"W1": np.zeros((4, h)), "b1": np.zeros(h), "W2": np.zeros((h, h)), "b2": np.zeros(h),
                       "W3": np.zeros((h, 1)), "b3": np.array([throttle_z]), "max_action": np.array(1.0)})


@pytest.mark.parametrize("at_once", [True, False])
def test_driver_brakes_at_once_for_a_standing_leader_it_has_perceived(road, policies, at_once):
    """R2, standing leaders: a BV at rest 3 m (bumper gap) behind a standing vehicle, its controller
    asking for tanh(2) = 0.96 throttle whatever it sees (as a BV creeping into a lane change does).
    At rest the emergency brake wants nothing (no closing speed), so the driver is not alerted; as it
    rolls, b = v² / (2 (gap - 2 m)) grows. With ``standing_leader_at_once`` the brake acts at the first
    step b >= 4 m/s², at -min(b, 7) / 8, as safety_net's does (then it creeps on, braking whenever b
    reaches the trigger: R9's creep past a standing leader); without it the brake waits N steps of
    alert and the BV runs into the standing vehicle at ~4 m/s within 2 s."""
    from evoscen_bv.car_following import _emergency_need

    _, _, training = policies
    w = hand_built_world(road, s=[400.0, 408.0], lane=[2, 2], speed=[0.0, 0.0])  # bumper gap 8 - 5 = 3 m
    bv = LearnedDriver(np.array([0]), _constant_controller(2.0), {}, training, np.random.default_rng(0), w.vehicle,
                       profile="driver", standing_leader_at_once=at_once)
    assert bv.profile.standing_leader_at_once is at_once
    first, collisions, us = None, 0, []
    for k in range(20):
        gap = w.s[1] - w.s[0] - 0.5 * (w.length[0] + w.length[1])
        need = _emergency_need(gap, 0.0, 0.0, w.v[0], 2.0)
        u = float(bv.throttle(w)[0])
        us.append(u)
        if first is None and need >= 4.0:
            first = (k, need, u)
        collisions += len(w.step(np.array([u, 0.0]), np.zeros(2, dtype=np.int64)).collisions)
    k, need, u = first
    assert k > 0  # it rolled first
    if at_once:
        assert u == pytest.approx(-min(need, 7.0) / 8.0)
        assert collisions == 0
        w = hand_built_world(road, s=[400.0, 408.0], lane=[2, 2], speed=[0.0, 0.0])
        sn = LearnedDriver(np.array([0]), _constant_controller(2.0), {}, training, np.random.default_rng(0),
                           w.vehicle, profile="safety_net")
        for k in range(20):
            assert float(sn.throttle(w)[0]) == pytest.approx(us[k], abs=1e-12)  # as safety_net (braking < 7 m/s²)
            w.step(np.array([us[k], 0.0]), np.zeros(2, dtype=np.int64))
    else:
        assert u > 0.0  # still the controller's throttle: the alert has just begun
        assert collisions > 0


def test_standing_leader_rule_is_a_scenario_key_with_the_old_rule_selectable():
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.scenario_builders import build_bv_driver

    def at_once(models: dict) -> bool:
        return build_bv_driver(config_from_dict({"bvs": {"driver": "learned", "makeup": "uniform"}, "models": models})).profile \
            .standing_leader_at_once

    assert at_once({}) is True and get_profile("driver").standing_leader_at_once is True
    assert at_once({"learned": {"standing_leader_at_once": False}}) is False
    assert at_once({"learned": {"profile": "safety_net"}}) is False  # safety_net: the rules as they were
