"""Closed-loop behaviour shared by the lane-change models (MOBIL, Nilsson) driven by Krauss.

Each test runs once per model (evoscen_sut.mobil and evoscen_sut.nilsson, default parameters).
Vehicles are 4.8 m long; v0 = 120 km/h = 33.33 m/s (the road's limit).
Road: lane 0 (merge lane) exists for 600 ≤ s ≤ 960 (stop point 960 − 15 = 945), lanes 1..4 everywhere.
"""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_bringup.model_testing import model_scenario, run_checked
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.vehicle import VehicleParams
from evoscen_sim.road.road_model import load_road
from evoscen_sut import mobil, nilsson
from evoscen_sut.krauss import KraussCarFollowing, KraussParams
from evoscen_sut.krauss_lane_change import KraussLaneChangeDriver

L = 4.8
V0 = 120.0 / 3.6

# (model module, its default parameters, the lane the empty-road run keeps)
MODELS = [
    pytest.param(mobil, mobil.MobilParams(), 1, id="mobil"),
    pytest.param(nilsson, nilsson.NilssonParams(), 2, id="nilsson"),
]


@pytest.fixture(scope="module")
def road():
    return load_road()


def _factory_driver(model, vehicles, params):
    cfg = load_scenario_config(overrides={"recording.enabled": False})
    return model.SPEC.factory(np.asarray(vehicles), params, cfg, np.random.default_rng(7))


@pytest.mark.parametrize(("model", "params", "lane"), MODELS)
def test_empty_road_speed_converges_to_desired_speed(road, model, params, lane) -> None:
    # from s = 100 at 20 m/s, 400 steps (lane 1 passes the merge lane, which it must not enter)
    w = hand_built_world(road, s=[100.0], lane=[lane], speed=[20.0])
    drv = _factory_driver(model, [0], params)
    speeds, requests = [], []
    for _ in range(400):
        thr, lc = drv.act(w)
        requests.append(int(lc[0]))
        w.step(thr, lc)
        speeds.append(w.v[0])
    assert requests == [0] * 400 and w.lane[0] == lane
    # Krauss free road: commanded speeds i.i.d. in (v_max − σ a Δt, v_max] = (33.20, 33.33], mean 33.27
    # (the vehicle model tracks the command to within a few mm/s)
    assert np.mean(speeds[-100:]) == pytest.approx(V0 - 0.5 * 2.6 * 0.1 / 2, abs=0.03)
    assert V0 - 0.15 < min(speeds[-100:]) and max(speeds[-100:]) < V0 + 0.01


@pytest.mark.parametrize(("model", "params", "lane"), MODELS)
def test_merge_lane_blocked_waits_before_the_lane_end(road, model, params, lane) -> None:
    # ego on lane 0 at s = 800, a blocker in lane 1 level with it, driven with the ego's own command:
    # the ego can never merge and must stop before the stop point (945 m) without leaving the road.
    w = hand_built_world(road, s=[800.0, 800.0], lane=[0, 1], speed=[20.0, 20.0])
    krauss = KraussCarFollowing(KraussParams(sigma=0.5), np.random.default_rng(0), 0.1)
    drv = KraussLaneChangeDriver(np.array([0]), model.lane_change_decision, params, krauss, VehicleParams(),
                                 params.merge_stop_margin_m)
    for _ in range(300):
        thr, lc = drv.act(w)
        assert lc[0] == 0
        r = w.step(np.array([thr[0], thr[0]]), np.array([lc[0], 0]))
        assert not r.off_road and not r.collisions
        assert abs(w.s[0] - w.s[1]) < 0.5
    assert w.lane[0] == 0
    assert w.s[0] + L / 2 <= 945.0 and w.v[0] < 0.1


@pytest.mark.parametrize(("model", "params", "lane"), MODELS)
def test_merge_in_closed_loop(road, model, params, lane) -> None:
    # ego on lane 0 at s = 650, 20 m/s, lane 1 empty: merges, no off-road
    w = hand_built_world(road, s=[650.0], lane=[0], speed=[20.0])
    drv = _factory_driver(model, [0], params)
    for _ in range(200):
        thr, lc = drv.act(w)
        r = w.step(thr, lc)
        assert not r.off_road
    assert w.lane[0] >= 1


# ------------------------------------------------------------------ scenario runs
@pytest.mark.parametrize(("model", "params", "lane"), MODELS)
def test_default_scenario_3000_steps_as_sut(model, params, lane) -> None:
    sc = model_scenario(model.SPEC, params, "sut")
    collisions, changes = run_checked(sc, 3000, np.array([sc.sut_index]))
    assert not [c for c in collisions if sc.sut_index in c], collisions
    assert changes >= 1  # the model does change lanes in the default traffic
    assert np.all(np.isfinite(sc.world.v))


@pytest.mark.parametrize(("model", "params", "lane"), MODELS)
def test_default_scenario_as_bv_driver(model, params, lane) -> None:
    sc = model_scenario(model.SPEC, params, "bv")
    _collisions, changes = run_checked(sc, 1000, sc.bv_indices)
    assert changes >= 1
    assert np.all(np.isfinite(sc.world.v))


def test_kernel_params_are_the_dataclass_fields_declared_once() -> None:
    """The kernels' tuple type is derived from the parameter dataclass: same fields, same order,
    the values of a parameter set as floats (flags as bools)."""
    from dataclasses import dataclass

    from evoscen_sut.krauss_lane_change import kernel_params, kernel_params_type

    @dataclass(frozen=True)
    class ToyParams:
        gain: float = 2
        on: bool = True
        gap_m: float = 1.5

    toy = kernel_params_type(ToyParams)
    assert toy.__name__ == "ToyKernelParams" and toy._fields == ("gain", "on", "gap_m")
    got = kernel_params(toy, ToyParams())
    assert tuple(got) == (2.0, True, 1.5) and type(got[0]) is float and type(got[1]) is bool
    assert mobil.MobilKernelParams.__name__ == "MobilKernelParams"
    assert mobil.MobilKernelParams._fields[:3] == ("politeness", "threshold_mps2", "bias_mps2")
    assert nilsson.NilssonKernelParams._fields[:2] == ("desired_speed_mps", "look_ahead_time_s")
    assert kernel_params(mobil.MobilKernelParams, mobil.MobilParams()).politeness == 0.25


def test_kernel_params_and_conflict_rules_are_built_once_per_parameter_set() -> None:
    """A model asks for its kernel tuple and pair test every decision: one object per parameter set,
    the values of each set (an equal but distinct set gives equal values)."""
    import dataclasses

    from evoscen_sut.krauss_lane_change import kernel_params

    p = mobil.MobilParams()
    q = dataclasses.replace(p, politeness=0.5)
    a = kernel_params(mobil.MobilKernelParams, p)
    assert kernel_params(mobil.MobilKernelParams, p) is a
    assert kernel_params(mobil.MobilKernelParams, q).politeness == 0.5 and a.politeness == 0.25
    assert kernel_params(mobil.MobilKernelParams, mobil.MobilParams()) == a
    assert mobil.conflict_rule(p) is mobil.conflict_rule(p)
    assert mobil.conflict_rule(q).safe_decel_mps2 == 4.0 and mobil.conflict_rule.__wrapped__(p) == mobil.conflict_rule(p)
