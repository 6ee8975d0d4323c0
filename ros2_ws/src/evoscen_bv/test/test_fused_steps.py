"""The BV drivers' fused steps equal their calls one by one, bit for bit (docs/performance.md "Per-step work of the
world and of the BV drivers"): a learned driver's :func:`evoscen_bv.learned_step.driver_step` against its throttle, forced-merge,
hard-braking and lane-hold calls made separately, and :meth:`evoscen_bv.truck.MakeupDriver.act` against
:meth:`~evoscen_bv.truck.MakeupDriver.act_unfused`, on every state of runs with learned and with rule-based cars."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from evoscen_bv.lane_change_decision import forced_merge_targets
from evoscen_bv.learned import HARD_BRAKE_VIEW_M, _hard_brake_scan, _lane_hold_step
from evoscen_bv.learned_step import driver_step
from evoscen_contract.contract import ROLE_SUT
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.physics.window import NEW_TRIP_MAX_SPEED_MPS


def scenario(overrides: dict):
    from evoscen_bringup.scenario import build_scenario

    return build_scenario(load_scenario_config(None, {"bvs.nodes": "single", "traffic.warmup_s": 5.0, **overrides}))


def one_by_one(drv, w):
    """The four calls :func:`driver_step` fuses, in the driver's own order."""
    throttle = drv.throttle(w)
    targets = forced_merge_targets(w, drv.vehicles, drv.forced_merge_m)
    hb = drv.hard_brake
    scan = _hard_brake_scan(drv.vehicles, hb.until_step, w.v, w.role, w.s, w.d, w.length, w.width, w.lane_change,
                            float(hb.params.min_speed_mps), int(w.step_index), HARD_BRAKE_VIEW_M, ROLE_SUT)
    dt = float(w.dt_s)
    changing, s = _lane_hold_step(drv.vehicles, w.lane_change, w.s, drv._changing, drv.hold_until_step, drv._last_s,
                                  int(w.step_index), int(round(drv.lane_hold_s / dt)), drv.hold_on_entry,
                                  NEW_TRIP_MAX_SPEED_MPS * dt + 10.0)
    drv._changing, drv._last_s = changing, s
    return throttle, targets, scan


def state_of(drv) -> list[np.ndarray]:
    return [drv.reaction.seen, drv.reaction.em_count, drv.hard_brake.until_step, drv.hold_until_step, drv._changing,
            drv._last_s]


def test_a_learned_drivers_fused_step_equals_its_calls_one_by_one():
    sc = scenario({"seed": 4301})
    car = sc.bv_driver.car_driver
    assert car.profile.name != "safety_net" and car.hard_brake is not None and car.lane_hold_s > 0.0
    assert car.forced_merge and car.merge_seek and car.compete_with_sut  # every part of the fused call runs
    leaders = 0
    for _ in range(300):
        a, b = copy.deepcopy(car), copy.deepcopy(car)
        got, want = driver_step(a, sc.world), one_by_one(b, sc.world)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
        assert np.array_equal(got[2][0], want[2][0]) and got[2][1] == want[2][1]
        leaders += got[2][1] >= 0
        for x, y in zip(state_of(a), state_of(b)):
            assert np.array_equal(x, y)
        sc.step()
    assert leaders > 0  # the SUT's leader was hosted (the hard-braking odometer ran)


@pytest.mark.parametrize("driver", ["learned", "nilsson"])
def test_the_makeup_drivers_fused_act_equals_its_unfused_act(driver):
    fused, unfused = scenario({"seed": 4302, "bvs.driver": driver}), scenario({"seed": 4302, "bvs.driver": driver})
    unfused.bv_driver.act = unfused.bv_driver.act_unfused
    for _ in range(300):
        a, b = fused.commands(), unfused.commands()
        for x, y in zip(a, b):
            assert np.array_equal(x, y)
        fused.apply(*a)
        unfused.apply(*b)
    assert fused.bv_driver.truck.any()
    assert np.array_equal(fused.world.s, unfused.world.s) and np.array_equal(fused.world.v, unfused.world.v)
