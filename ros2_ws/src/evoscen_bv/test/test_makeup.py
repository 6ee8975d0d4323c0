"""The ``highd`` traffic make-up (docs/bv-profiles.md, "Traffic make-up"): draws, truck drivers, uncapped cars.

Hand-derived expectations: the truck count of n slots is floor(n·share) or one more, with the remainder as
the probability of the larger; lengths and speeds follow the piecewise-linear inverse CDF through
(0.05, p5), (0.5, p50), (0.95, p95), continued with the end segments' slopes; a truck's acceleration is the
IDM's, a[1 − (v/v0)^δ − (s*/s)²], s* = s0 + max(0, vT + vΔv/(2√(ab))), with the truck set T = 1.8 s,
s0 = 3 m, a = 1 m/s², b = 2 m/s², δ = 4, at least −5 m/s².
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_bv.truck import APPROACH, MakeupDriver, TruckDriver, TruckParams
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.errors import InputError
from evoscen_sim.traffic.makeup import HighdMakeupParams, draw_makeup, from_quantiles, is_truck, quantile_curve
from evoscen_sim.physics.vehicle import VehicleParams
from evoscen_sim.physics.world import ROLE_BV, InitialState, ReentryParams, World
from evoscen_sim.road.road_model import load_road

P = HighdMakeupParams()


@pytest.fixture(scope="module")
def road():
    return load_road()


def world_of(road, s, lane, speed, length):
    n = len(s)
    init = InitialState(ids=np.arange(n), roles=np.full(n, ROLE_BV, dtype=np.int64), policies=np.zeros(n, dtype=np.int64),
                        s_m=np.asarray(s, dtype=float), lane=np.asarray(lane, dtype=np.int64),
                        speed_mps=np.asarray(speed, dtype=float), length_m=np.asarray(length, dtype=float),
                        width_m=np.where(np.asarray(length) > 7.0, 2.5, 1.9))
    from evoscen_sim.physics.control import ControlParams

    return World(road, init, vehicle=VehicleParams(), control=ControlParams(), reentry=ReentryParams(), dt_s=0.1,
                 rng=np.random.default_rng(0))


# ---------------------------------------------------------------- draws
def test_truck_count_and_slots_within_binomial_bounds() -> None:
    rng = np.random.default_rng(123)
    draws, n = 2000, 20
    quota = n * P.truck_share  # 20 x 0.229 = 4.58: 4 or 5 trucks, 5 with probability 0.58
    lo = math.floor(quota)
    counts = np.array([draw_makeup(n, P, 1.9, rng).truck.sum() for _ in range(draws)])
    assert set(counts.tolist()) <= {lo, lo + 1}
    frac = quota - lo
    sd = math.sqrt(draws * frac * (1 - frac))
    assert abs((counts == lo + 1).sum() - draws * frac) < 4 * sd
    # every slot equally likely a truck: share per slot within 4 binomial sd of 0.229
    rng = np.random.default_rng(7)
    per_slot = np.mean([draw_makeup(n, P, 1.9, rng).truck for _ in range(draws)], axis=0)
    assert np.all(np.abs(per_slot - P.truck_share) < 4 * math.sqrt(P.truck_share * (1 - P.truck_share) / draws))


def test_lengths_widths_and_speeds_follow_the_quantiles() -> None:
    m = draw_makeup(20000, P, 1.9, np.random.default_rng(5))
    t, c = m.length_m[m.truck], m.length_m[~m.truck]
    assert np.all(is_truck(m.length_m) == m.truck)
    assert t.min() >= 7.1 and t.max() <= 19.5 + (19.5 - 16.7) / 9 + 1e-9
    assert c.min() >= 3.94 - (4.75 - 3.94) / 9 - 1e-9 and c.max() <= 6.9
    assert np.median(t) == pytest.approx(16.7, abs=0.15)
    assert np.percentile(c, [5, 50, 95]) == pytest.approx([3.94, 4.75, 6.16], abs=0.05)
    assert set(m.width_m[m.truck]) == {2.5} and set(m.width_m[~m.truck]) == {1.9}
    v = m.desired_speed_mps
    assert np.percentile(v[~m.truck], [5, 50, 95]) == pytest.approx([P.car_speed_p5_mps, 31.45, 37.51], abs=0.15)
    assert np.percentile(v[m.truck], [50, 95]) == pytest.approx([24.13, 26.52], abs=0.15)
    assert v[~m.truck].max() > 33.34  # faster than the lane's limit: the limit is no cap


def test_quantile_curve_by_hand() -> None:
    u, x = quantile_curve(10.0, 19.0, 28.0)  # end segments continued: 10 - 9 x 0.05/0.45 = 9, 28 + 1 = 29
    assert u.tolist() == [0.0, 0.05, 0.5, 0.95, 1.0]
    assert x == pytest.approx([9.0, 10.0, 19.0, 28.0, 29.0])
    assert from_quantiles(np.array([0.275, 0.975]), 10.0, 19.0, 28.0) == pytest.approx([14.5, 28.5])


# ---------------------------------------------------------------- truck driver
def idm(v, v0, gap, dv, T=1.8, s0=3.0, a=1.0, b=2.0) -> float:
    s_star = s0 + max(0.0, v * T + v * dv / (2.0 * math.sqrt(a * b)))
    inter = 0.0 if math.isinf(gap) else (s_star / gap) ** 2
    return max(a * (1.0 - (v / v0) ** 4 - inter), -5.0)


def test_truck_idm_acceleration_by_formula(road) -> None:
    # truck (16 m) at 22 m/s in lane 1, its desired 24 m/s; a car (4 m) 40 m ahead (centres) at 20 m/s
    w = world_of(road, [300.0, 340.0, 300.0], [1, 1, 3], [22.0, 20.0, 22.0], [16.0, 4.0, 16.0])
    d = TruckDriver(np.array([0, 2]), TruckParams(), np.array([24.0, 24.0]), VehicleParams())
    acc = d.accel(w)
    gap = 40.0 - 8.0 - 2.0  # 30 m bumper to bumper
    assert acc[0] == pytest.approx(idm(22.0, 24.0, gap, 2.0), abs=1e-9)
    assert acc[1] == pytest.approx(1.0 * (1.0 - (22.0 / 24.0) ** 4), abs=1e-9)  # free road
    thr, _ = d.act(w)
    assert thr[0] == pytest.approx(acc[0] / 8.0 if acc[0] < 0 else acc[0] / 3.0)


def test_truck_braking_bounded(road) -> None:
    w = world_of(road, [300.0, 311.0], [1, 1], [25.0, 0.0], [16.0, 4.0])  # gap 1 m to a standing car
    d = TruckDriver(np.array([0]), TruckParams(), np.array([24.0]), VehicleParams())
    assert d.accel(w)[0] == pytest.approx(-5.0)


def test_truck_never_changes_into_the_leftmost_lane(road) -> None:
    # a truck at 15 m/s (desired 24) behind a car at 10 m/s; the lane to its left is empty, a car beside it
    # on its right
    for lane, expected in ((3, 0), (2, 1)):  # from lane IV (left: V, the leftmost): keep; from III: go left
        w = world_of(road, [1200.0, 1230.0, 1200.0], [lane, lane, lane - 1], [15.0, 10.0, 15.0],
                     [16.0, 4.0, 4.0])
        d = TruckDriver(np.array([0]), TruckParams(), np.array([24.0]), VehicleParams())
        assert d.act(w)[1][0] == expected


def test_content_truck_does_not_overtake(road) -> None:
    # the situation from lane III that made a truck go left, but its own desired speed is 16 m/s: within
    # 3 m/s of it, it stays
    w = world_of(road, [1200.0, 1230.0, 1200.0], [2, 2, 1], [15.0, 10.0, 15.0], [16.0, 4.0, 4.0])
    d = TruckDriver(np.array([0]), TruckParams(), np.array([16.0]), VehicleParams())
    assert d.act(w)[1][0] == 0


# ---------------------------------------------------------------- cars
class _Car:
    """A car driver that asks for full throttle (to see the approach bound alone)."""

    def __init__(self, vehicles):
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.vehicle_params = VehicleParams()

    def restrict(self, positions):
        self.vehicles = self.vehicles[positions]

    def act(self, view):
        return np.ones(self.vehicles.size), np.zeros(self.vehicles.size, dtype=np.int64)


def test_approach_braking_by_formula(road) -> None:
    # a car at 30 m/s, 30 m (bumpers) behind one at 20 m/s: b = 10² / (2 (30 - 5)) = 2.0 >= 1.5
    w = world_of(road, [300.0, 334.0], [2, 2], [30.0, 20.0], [4.0, 4.0])
    md = MakeupDriver(np.array([0, 1]), np.array([False, False]), _Car([0, 1]),
                      TruckDriver(np.zeros(0, dtype=np.int64), TruckParams(), np.zeros(0), VehicleParams()))
    thr, _ = md.act(w)
    assert APPROACH.trigger_mps2 == 1.5 and APPROACH.margin_m == 5.0
    assert thr[0] == pytest.approx(-2.0 / 8.0)
    assert thr[1] == 1.0  # no leader
    w = world_of(road, [300.0, 354.0], [2, 2], [30.0, 20.0], [4.0, 4.0])  # 50 m: b = 100 / 90 < 1.5
    assert md.act(w)[0][0] == 1.0


def test_uncapped_learned_car_exceeds_the_limit(road) -> None:
    from evoscen_sim.model_registry import create_driver

    cfg = load_scenario_config(None)
    top = {}
    for cap in (True, False):
        w = world_of(road, [100.0], [2], [30.0], [4.5])
        car = create_driver("learned", "bv", np.array([0]), cfg, np.random.default_rng(0))
        car.desired_speed_mps = np.array([37.0])
        car.speed_cap = cap
        vmax = 0.0
        for _ in range(300):
            thr, _ = car.act(w)
            w.step(np.asarray(thr, dtype=float), np.zeros(1, dtype=np.int64))
            vmax = max(vmax, float(w.v[0]))
        top[cap] = vmax
    assert float(w.speed_limit_mps[0]) == pytest.approx(33.33, abs=0.01)
    assert top[True] <= 33.34
    assert top[False] > 33.34


# ---------------------------------------------------------------- a run
def test_highd_run_trucks_keep_right_and_split_does_not_matter() -> None:
    from evoscen_bringup.scenario import build_scenario

    worlds = []
    for nodes in ("single", "by_policy"):
        cfg = load_scenario_config(None, {"bvs.makeup": "highd", "seed": 4242, "bvs.nodes": nodes,
                                          "traffic.warmup_s": 5.0})
        sc = build_scenario(cfg)
        w = sc.world
        truck = w.length > 7.0
        assert truck.sum() in (4, 5) and not truck[0]
        for _ in range(300):
            sc.step()
            assert not np.any(w.lane[truck] == 4)
        worlds.append(np.concatenate([w.s, w.v, w.lane]))
    assert np.array_equal(worlds[0], worlds[1])


def test_config_errors_and_metadata() -> None:
    from evoscen_record.scenario_record import SCENARIO_KEY, scenario_metadata

    with pytest.raises(InputError, match=r"key 'bvs.makeup' = 'highd': expected uniform with traffic.mode = loop"):
        load_scenario_config(None, {"bvs.makeup": "highd", "traffic.mode": "loop"})
    from evoscen_sim.model_registry import ModelSpec, register_model, unregister_model

    register_model(ModelSpec(name="own_bv", roles=("bv",), factory=lambda *a: None))
    try:
        with pytest.raises(InputError, match=r"key 'bvs.makeup' = 'highd': expected uniform with bvs.driver = own_bv "
                                             r"\(the highd make-up's cars are learned, level0, nilsson, mobil drivers; set bvs.makeup: uniform\)"):
            load_scenario_config(None, {"bvs.makeup": "highd", "bvs.driver": "own_bv"})
    finally:
        unregister_model("own_bv")
    for driver in ("nilsson", "mobil"):  # the rule-based baselines drive the make-up's cars
        assert load_scenario_config(None, {"bvs.makeup": "highd", "bvs.driver": driver}).bvs.driver == driver
    with pytest.raises(InputError, match=r"bvs.makeup"):
        load_scenario_config(None, {"bvs.makeup": "cars"})
    # the default is highd (recorded); absent in a bag means uniform, so 0.6's bags keep their bytes
    assert load_scenario_config(None).bvs.makeup == "highd"
    assert "makeup: highd" in scenario_metadata(load_scenario_config(None))[SCENARIO_KEY]
    assert "makeup" not in scenario_metadata(load_scenario_config(None, {"bvs.makeup": "uniform"}))[SCENARIO_KEY]
    from evoscen_sim.config.scenario_config import config_from_dict

    assert config_from_dict({}).bvs.makeup == "highd"  # a user's file without the key gets the default too
    with pytest.raises(InputError, match=r"key 'bvs.makeup' = 'highd' \(default\): expected uniform with "
                                         r"traffic.mode = loop .*set bvs.makeup: uniform"):
        config_from_dict({"traffic": {"mode": "loop"}}, source="s.yaml")


# ---------------------------------------------------------------- rule-based cars (nilsson, mobil)
@pytest.mark.parametrize("driver", ["nilsson", "mobil"])
def test_rule_based_car_follows_its_own_desired_speed_uncapped(road, driver) -> None:
    """Krauss with a per-vehicle desired speed (docs/bv-profiles.md, "Rule-based cars in the highD make-up"):
    v_max = the car's own desired speed, not models.krauss's 33.33 x a speed factor, not capped at the
    lane's 33.33 m/s limit. Krauss never exceeds v_max, and its dawdling (sigma 0.5, at most accel x sigma
    x dt = 0.13 m/s below the safe speed a step) keeps a free car within a few tenths of it."""
    from evoscen_sim.model_registry import create_driver

    cfg = load_scenario_config(None)
    for desired, cap in ((37.0, False), (25.0, False), (37.0, True)):
        w = world_of(road, [100.0], [2], [20.0], [4.5])
        car = create_driver(driver, "bv", np.array([0]), cfg, np.random.default_rng(0))
        car.desired_speed_mps = np.array([desired])
        car.speed_cap = cap
        speeds = []
        for _ in range(400):
            thr, _ = car.act(w)
            w.step(np.asarray(thr, dtype=float), np.zeros(1, dtype=np.int64))
            speeds.append(float(w.v[0]))
        top = min(desired, 33.33) if cap else desired
        assert max(speeds) <= top + 0.05, (desired, cap)
        assert np.mean(speeds[-100:]) > top - 0.6, (desired, cap)


def test_rule_based_cars_highd_run_split_does_not_matter() -> None:
    """nilsson cars among the make-up's trucks: the world is the same whether one BV node drives all or
    three split by id (the Krauss dawdling draws are those of the driver of all cars: CutShare)."""
    from evoscen_bringup.scenario import build_scenario

    worlds = []
    for nodes in ("single", 3):
        cfg = load_scenario_config(None, {"bvs.makeup": "highd", "bvs.driver": "nilsson", "seed": 4243,
                                          "bvs.nodes": nodes, "traffic.warmup_s": 5.0})
        sc = build_scenario(cfg)
        w = sc.world
        truck = w.length > 7.0
        for _ in range(200):
            sc.step()
        assert truck.sum() >= 1
        worlds.append(np.concatenate([w.s, w.v, w.lane]))
    assert np.array_equal(worlds[0], worlds[1])


# ---------------------------------------------------------------- car lanes (models.highd.car_lanes)
def test_cars_by_speed_spawn_sorts_the_lanes_right_to_left() -> None:
    from evoscen_sim.traffic.makeup import Makeup
    from evoscen_sim.traffic.spawn import window_layout_makeup
    from evoscen_sim.scenario_builders import traffic_params_from_config

    cfg = load_scenario_config(None, {"bvs.makeup": "highd"})
    rd = load_road(cfg.map)
    tp = traffic_params_from_config(cfg, rd)
    n = 8  # two per mainline lane (equal densities); slots 0 and 5 trucks
    speeds = np.array([24.0, 35.0, 21.0, 30.0, 27.0, 22.0, 33.0, 25.0])
    truck = np.zeros(n, dtype=bool)
    truck[[0, 5]] = True
    mk = Makeup(truck=truck, length_m=np.where(truck, 16.0, 4.5), width_m=np.where(truck, 2.5, 1.9),
                desired_speed_mps=speeds)
    kw = dict(bv_policies=np.zeros(n, dtype=np.int64), sut_policy=0, sut_lane=2, sut_s_m=1000.0,
              sut_speed_mps=28.0, sut_length_m=4.5, sut_width_m=1.9)
    by_speed = window_layout_makeup(rd, tp, mk, 1, cars_by_speed=True, rng=np.random.default_rng(1), **kw)
    by_index = window_layout_makeup(rd, tp, mk, 1, cars_by_speed=False, rng=np.random.default_rng(1), **kw)
    lanes = sorted(set(by_speed.lane[1:].tolist()))
    assert len(lanes) == 4
    # trucks take the rightmost lane; the cars, slowest first, fill the rest from right to left:
    # cars by speed 21 (2), 25 (7), 27 (4), 30 (3), 33 (6), 35 (1)
    want = {0: lanes[0], 5: lanes[0], 2: lanes[1], 7: lanes[1], 4: lanes[2], 3: lanes[2], 6: lanes[3], 1: lanes[3]}
    assert {k: int(by_speed.lane[k + 1]) for k in range(n)} == want
    # by_density keeps index order: cars 1, 2 | 3, 4 | 6, 7
    assert [int(by_index.lane[k + 1]) for k in (1, 2, 3, 4, 6, 7)] == [lanes[1]] * 2 + [lanes[2]] * 2 + [lanes[3]] * 2


def test_cars_by_speed_entry_prefers_the_lane_nearest_in_speed() -> None:
    from evoscen_sim.physics.window import _by_speed, _lane_mean_speeds

    s = np.array([0.0, 50.0, 60.0, 500.0, 70.0, 80.0])
    v = np.array([28.0, 20.0, 24.0, 40.0, 31.0, 33.0])
    lane = np.array([2, 1, 1, 3, 2, 4], dtype=np.int64)
    target = lane.copy()
    change = np.zeros(6, dtype=np.int64)
    target[5], change[5] = 3, 1  # the vehicle changing to lane 3 counts there
    m = _lane_mean_speeds(s, v, lane, target, change, -100.0, 200.0, 5)
    assert np.isnan(m[0]) and np.isnan(m[4])
    assert m[1:4].tolist() == pytest.approx([22.0, 29.5, 33.0])  # vehicle 3 (s = 500) outside the window
    rows = [(-0.5, 1, 26.0, 1.5), (-0.3, 2, 28.0, 1.5), (-0.2, 3, 30.0, 1.5), (-0.1, 4, 32.0, 1.5)]
    # wish 34: |33 − 34| = 1 (lane 3), |32 − 34| = 2 (lane 4, empty: its entry mean), 4.5, 12
    assert [r[1] for r in _by_speed(rows, 34.0, m)] == [3, 4, 2, 1]
    # wish 22: lane 1 (0), lane 2 (7.5), lane 4 (10), lane 3 (11)
    assert [r[1] for r in _by_speed(rows, 22.0, m)] == [1, 2, 4, 3]


def test_car_lanes_is_checked() -> None:
    with pytest.raises(InputError, match=r"car_lanes"):
        load_scenario_config(None, {"bvs.makeup": "highd", "models.highd.car_lanes": "by_colour"})


def test_rule_based_makeup_driver_copies_and_pickles() -> None:
    """The experiments copy a seed's BV driver for every variant (evoscen_bringup.starts) and Ray pickles
    it: a CutShare of nilsson cars survives both and drives as the original (same answer)."""
    import copy
    import pickle

    from evoscen_bringup.scenario import build_scenario

    cfg = load_scenario_config(None, {"bvs.makeup": "highd", "bvs.driver": "nilsson", "seed": 5, "traffic.warmup_s": 1.0})
    sc = build_scenario(cfg)
    from evoscen_sim.scenario_builders import build_bv_driver

    driver = build_bv_driver(cfg)
    want = copy.deepcopy(driver).act(sc.world)  # a copy: the original's random stream stays where it is
    for other in (copy.deepcopy(driver), pickle.loads(pickle.dumps(driver))):
        got = other.act(sc.world)
        assert np.array_equal(np.asarray(got[0]), np.asarray(want[0])) and np.array_equal(got[1], want[1])


def test_the_report_names_the_traffic(tmp_path) -> None:
    """The report's run section and report.md's first lines say which traffic the run had: the make-up, the
    cars' driver and policy set (``shipped`` resolved), the cars and trucks among the BVs (a truck longer
    than 7 m) — counted here from the world the run started with."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.scenario_builders import build_world

    for makeup, policies in (("highd", "shipped (highd_trained)"), ("uniform", "shipped (v0.6.0)")):
        cfg = load_scenario_config(None, {"steps": 30, "seed": 11, "bvs.makeup": makeup})
        w = build_world(cfg)
        trucks = int(np.count_nonzero(w.length[1:] > 7.0))
        assert (trucks >= 4) == (makeup == "highd") and (trucks == 0) == (makeup == "uniform")
        run_inprocess(cfg, bag_dir=None, report_dir=tmp_path / makeup, plots=False)
        import json

        run = json.loads((tmp_path / makeup / "report.json").read_text(encoding="utf-8"))["run"]
        assert (run["makeup"], run["policy_set"], run["bv_cars"], run["bv_trucks"]) == (makeup, policies, 20 - trucks,
                                                                                       trucks)
        md = (tmp_path / makeup / "report.md").read_text(encoding="utf-8")
        assert f"; {20 - trucks} cars and {trucks} trucks; cars driven by learned, policy set {policies}." in md
        assert ("Traffic: highD make-up" if makeup == "highd" else "Traffic: uniform make-up") in md
