"""The traffic window (evoscen_sim.physics.window; docs/method.md §1): safe insertion, exits and entries,
the shift, the window's spawn, and what a run with it looks like."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.errors import InputError
from evoscen_sim.physics.window import (
    TrafficParams,
    check_shift_points,
    common_shift,
    insertion_speed,
    new_trips,
    required_gap,
)
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.world import ROLE_BV, ROLE_SUT, World
from evoscen_sim.road.road_model import load_road
from evoscen_sim.scenario_builders import build_world

L = 4.8
P = TrafficParams()


@pytest.fixture(scope="module")
def road():
    return load_road(load_scenario_config(None).map)


def test_required_gap_and_insertion_speed_by_hand() -> None:
    # 2.5 + 30*1 + (30^2 - 25^2) / (2*4.5) = 32.5 + 275/9
    assert required_gap(30.0, 25.0, P) == pytest.approx(32.5 + 275.0 / 9.0)
    # slower than the leader: only the headway binds
    assert required_gap(20.0, 25.0, P) == pytest.approx(22.5)
    # 40 m behind a leader at 25 m/s: v = -4.5 + sqrt(4.5^2 + 25^2 + 2*4.5*37.5)
    v = insertion_speed(30.0, 40.0, 25.0, P)
    assert v == pytest.approx(-4.5 + math.sqrt(20.25 + 625.0 + 337.5))
    assert required_gap(v, 25.0, P) == pytest.approx(40.0)
    assert insertion_speed(24.0, 40.0, 25.0, P) == 24.0  # fits as it is
    assert insertion_speed(30.0, 12.5, 25.0, P) == pytest.approx(10.0)  # (12.5 - 2.5) / 1 s
    assert insertion_speed(30.0, 2.0, 25.0, P) == -math.inf  # closer than the standstill gap


def _world(road, s, lane, v, params: TrafficParams, seed: int = 0) -> World:
    """Vehicle 0 the SUT, the others BVs, in the traffic window ``params``."""
    return hand_built_world(road, s, lane, v, roles=[ROLE_SUT] + [ROLE_BV] * (len(s) - 1), seed=seed, traffic=params)


def _coast(w: World):
    return w.step(np.zeros(w.n), np.zeros(w.n, dtype=np.int64))


def test_shift_moves_every_vehicle_by_one_distance(road) -> None:
    w = _world(road, [1999.0, 2050.0, 1900.0], [2, 3, 1], [30.0, 30.0, 30.0], P)
    before = w.s.copy()
    res = _coast(w)
    assert res.shift_m == pytest.approx(1700.0)
    # each moved the same (same speed, no throttle) and back by 1,700 m
    moved = w.s - before + 1700.0
    np.testing.assert_allclose(moved, moved[0], atol=1e-9)
    assert 2.9 < moved[0] <= 3.0
    assert w.lane.tolist() == [2, 3, 1] and not res.reentries
    res = _coast(w)
    assert res.shift_m == 0.0


def test_a_bv_beyond_the_window_enters_at_the_front_edge_into_the_most_wanted_lane(road) -> None:
    p = replace(P, lane_speed_mean_mps=(25.0,) * 4, lane_speed_sd_mps=(0.0,) * 4)
    # the BV is 164.3 m behind the SUT after the step: beyond behind_m + exit_margin_m = 160
    # (1,500 m: the merge lane is far from the window)
    w = _world(road, [1500.0, 1336.0], [2, 3], [30.0, 27.0], p)
    res = _coast(w)
    assert res.reentries == [(1, 1, pytest.approx(w.s[0] + 250.0))]  # empty window: lanes tie, the first wins
    assert w.v[1] == 25.0 and w.lane[1] == 1 and w.target_lane[1] == 1


def test_an_entry_goes_where_both_it_and_its_follower_can_follow(road) -> None:
    p = replace(P, lane_speed_mean_mps=(25.0,) * 4, lane_speed_sd_mps=(0.0,) * 4)
    # lane 1 is the most wanted (1 of 5 vehicles; lanes 2-4 hold 2 of 5 each) but its front edge is
    # taken; the middle of the band's largest gap (1,726.75 m) is 18.95 m behind that vehicle,
    # too close for 25 m/s, the lane's only speed: lane 2 (first of the tied rest) takes it
    s = [1500.0, 1336.0, 1748.0, 1450.0, 1400.0, 1450.0, 1400.0, 1450.0, 1400.0]
    lane = [2, 3, 1, 2, 2, 3, 3, 4, 4]
    w = _world(road, s, lane, [30.0, 27.0, 25.0] + [27.0] * 6, p)
    res = _coast(w)
    assert res.reentries == [(1, 2, pytest.approx(w.s[0] + 250.0))]
    assert w.v[1] == 25.0


def test_a_faster_entry_comes_from_behind(road) -> None:
    p = replace(P, lane_speed_mean_mps=(35.0,) * 4, lane_speed_sd_mps=(0.0,) * 4)
    w = _world(road, [1500.0, 1765.0], [2, 3], [30.0, 27.0], p)  # 264.7 m ahead after the step: out
    res = _coast(w)
    assert res.reentries == [(1, 1, pytest.approx(w.s[0] - 150.0))]
    assert w.v[1] == 35.0


def test_check_shift_points(road) -> None:
    assert check_shift_points(road, P) is None
    assert "below traffic.shift_from_m" in check_shift_points(road, replace(P, shift_to_m=2000.0))
    # 1,200 m is on the arc: not uniform
    assert "traffic.shift_from_m = 1200: the road is not uniform" in check_shift_points(road, replace(P, shift_from_m=1200.0))
    # the window around 500 m reaches the merge lane (600 m)
    assert "traffic.shift_to_m = 500" in check_shift_points(road, replace(P, shift_to_m=500.0))


def test_bad_shift_point_is_one_line_naming_the_key() -> None:
    cfg = load_scenario_config(None, {"traffic.shift_from_m": 1200.0})
    with pytest.raises(InputError, match=r"^traffic.shift_from_m = 1200: the road is not uniform"):
        build_world(cfg)
    cfg = load_scenario_config(None, {"traffic.lane_density_per_km": [10.0, 10.0]})
    with pytest.raises(InputError, match=r"traffic.lane_density_per_km: expected one entry per mainline lane of the map \(4\), got 2"):
        build_world(cfg)


def test_new_trips_and_common_shift() -> None:
    prev = np.array([100.0, 200.0, 300.0, 400.0])
    assert common_shift(prev, prev + 3.0) == 0.0
    assert common_shift(prev, prev + 3.0 - 1700.0) == pytest.approx(-1697.0)
    # a shift is no new trip; a vehicle moved by 400 m (an entry) is
    now = prev + 3.0 - 1700.0
    now[2] += 400.0
    assert new_trips(prev, now, 0.1).tolist() == [False, False, True, False]
    assert new_trips(prev, prev + np.array([3.0, -11.0, 14.5, 0.0]), 0.1).tolist() == [False, True, True, False]


def test_common_shift_median_is_numpys() -> None:
    """The compiled median: numpy's to the bit (a zero's sign aside), for odd and even counts, ties,
    a NaN; by hand: the middle of 5, the mean of the middle two of 4, and the shift it gives."""
    from evoscen_sim.physics.window import _median

    assert _median(np.array([5.0, -1.0, 3.0, 9.0, 2.0])) == 3.0
    assert _median(np.array([4.0, 1.0, 3.0, 2.0])) == 2.5
    assert math.isnan(_median(np.array([1.0, np.nan, 3.0])))
    rng = np.random.default_rng(7)
    for _ in range(3000):
        n = int(rng.integers(3, 45))
        x = rng.normal(0.0, 500.0, n)
        if rng.random() < 0.3:
            x = np.round(x / 100.0) * 100.0  # ties
        got, ref = _median(x), np.median(x)
        assert got == ref
        assert np.float64(got).tobytes() == np.float64(ref).tobytes() or got == 0.0
        prev = rng.uniform(0.0, 2000.0, n)
        step = float(np.median((prev + x) - prev))  # common_shift's numpy form
        ref_shift = step if step < -50.0 else 0.0
        assert np.float64(common_shift(prev, prev + x)).tobytes() == np.float64(ref_shift).tobytes()


def test_window_spawn_fills_the_window_at_its_densities() -> None:
    cfg = load_scenario_config(None, {"seed": 12, "traffic.warmup_s": 0.0, "bvs.makeup": "uniform"})
    w = build_world(cfg)
    rel = w.s[1:] - w.s[0]
    assert w.n == 21 and (np.abs(rel) > 0).all()
    assert (rel >= -150.0).all() and (rel <= 250.0).all()
    # 20 BVs over 4 lanes of equal density: 5 each, none on the merge lane
    assert np.bincount(w.lane[1:], minlength=5).tolist() == [0, 5, 5, 5, 5]
    # every BV can follow its leader by the insertion rule (the SUT counts)
    for lane in range(1, 5):
        k = np.flatnonzero(w.lane == lane)
        k = k[np.argsort(w.s[k])]
        for back, front in zip(k[:-1], k[1:]):
            if back == 0:
                continue
            gap = w.s[front] - w.s[back] - L
            assert gap >= required_gap(float(w.v[back]), float(w.v[front]), P) - 1e-9


def _ttc(gap: float, v_back: float, v_front: float) -> float:
    return gap / (v_back - v_front) if v_back > v_front else math.inf


@pytest.mark.parametrize("driver, makeup", [("learned", "uniform"), ("level0", "uniform"), ("learned", "highd"),
                                            ("level0", "highd")])
def test_a_run_keeps_its_traffic_and_never_moves_the_sut(driver: str, makeup: str) -> None:
    """2,000 steps, MOBIL as SUT: the SUT moves only by driving (and the shifts), every entry starts
    without a conflict (TTC >= 2 s to its leader and from its follower, with the vehicles' own lengths:
    under uniform in its first 3 s; under highd at its entry — there a leader on the ramp may brake at up
    to 7 m/s² for a gap within those 3 s: seed 40123, step 1985, a car entered 18 m behind a merging car
    that braked from 24 to 11 m/s, TTC 1.97 s after the follower's reaction time), and BVs are around the
    SUT all the time."""
    from evoscen_bringup.scenario import build_scenario

    watch_steps = 30 if makeup == "uniform" else 1
    sc = build_scenario(load_scenario_config(None, {"seed": 40123, "sut.model": "mobil", "bvs.driver": driver,
                                                    "bvs.makeup": makeup}))
    w = sc.world
    watch: dict[int, int] = {}  # vehicle -> steps left to watch
    near = []
    shifts = 0
    for k in range(2000):
        s0, lane0, target0 = float(w.s[0]), int(w.lane[0]), int(w.target_lane[0])
        res = sc.step()
        shifts += bool(res.shift_m)
        ds = float(w.s[0]) - s0 + res.shift_m
        assert 0.0 <= ds <= 4.0 + 1e-9, f"step {k}: the SUT moved by {ds} m"
        assert int(w.lane[0]) in (lane0, target0), f"step {k}: the SUT jumped lanes"
        for i, _, _ in res.reentries:
            watch[i] = watch_steps
        for i in list(watch):
            lane = w.lane[i]
            same = np.flatnonzero((w.lane == lane) & (np.arange(w.n) != i))
            ahead = same[w.s[same] > w.s[i]]
            behind = same[w.s[same] < w.s[i]]
            if ahead.size:
                j = ahead[np.argmin(w.s[ahead])]
                gap = w.s[j] - w.s[i] - 0.5 * (w.length[i] + w.length[j])  # the vehicles' own lengths (highd)
                assert _ttc(gap, w.v[i], w.v[j]) >= 2.0, f"step {k}: entered vehicle {i}"
            if behind.size:
                j = behind[np.argmax(w.s[behind])]
                gap = w.s[i] - w.s[j] - 0.5 * (w.length[i] + w.length[j])
                assert _ttc(gap, w.v[j], w.v[i]) >= 2.0, f"step {k}: follower of entered {i}"
            watch[i] -= 1
            if not watch[i]:
                del watch[i]
        near.append(np.count_nonzero(np.abs(w.s[1:] - w.s[0]) <= 100.0))
    assert shifts >= 1
    means = [np.mean(near[a:a + 300]) for a in range(0, 1800, 300)]
    assert min(means) >= 4.0, means


def test_warm_up_gives_every_sut_variant_the_same_start() -> None:
    """traffic.warmup_s: the intact SUT and a mutant on the same seed meet byte-identical first states."""
    from evoscen_sut.mutants import mutant_overrides

    def first_state(overrides: dict) -> bytes:
        w = build_world(load_scenario_config(None, {"seed": 70001, **overrides}))
        floats, ints = w.state_arrays()
        return b"".join(np.ascontiguousarray(a).tobytes() for a in (*floats, *ints))

    intact = first_state({"sut.model": "mobil"})
    assert first_state(mutant_overrides("mobil", "blind_behind")) == intact
    assert first_state({"sut.model": "stackelberg"}) == intact
    # another seed: another start
    assert first_state({"sut.model": "mobil", "seed": 70002}) != intact


def test_warm_up_evolves_the_traffic_and_keeps_the_sut_at_its_start() -> None:
    cfg = load_scenario_config(None, {"seed": 70001})
    cold = build_world(load_scenario_config(None, {"seed": 70001, "traffic.warmup_s": 0.0}))
    warm = build_world(cfg)
    assert warm.step_index == 0 and warm.time_s == 0.0
    assert warm.s[0] == pytest.approx(cfg.sut.s_m) and warm.lane[0] == cfg.sut.lane
    # the BVs have driven 200 steps: none is where the spawn put it, speeds are their drivers'
    assert (np.abs((warm.s[1:] - warm.s[0]) - (cold.s[1:] - cold.s[0])) > 0.5).all()
    rel = warm.s[1:] - warm.s[0]
    assert np.count_nonzero((rel >= -160.0) & (rel <= 260.0)) >= 18  # in the window (a vehicle may wait outside)
    # a lane change under way at step 0 started at a negative time
    started = warm.lane_change_start_s[warm.lane_change != 0]
    assert (started <= 0.0).all()


def test_a_start_where_the_sut_cannot_be_held_is_one_line() -> None:
    cfg = load_scenario_config(None, {"sut.s_m": 500.0})
    with pytest.raises(InputError, match=r"^sut.s_m \(held there during traffic.warmup_s\) = 500: the road is not uniform"):
        build_world(cfg)
    build_world(load_scenario_config(None, {"sut.s_m": 500.0, "traffic.warmup_s": 0.0}))  # no warm-up: allowed


def test_the_merge_lanes_start_exactly_at_the_front_edge_is_no_wanted_lane() -> None:
    # SUT at 350 m: the window's front edge (600 m) is the merge lane's start, no room there yet
    w = build_world(load_scenario_config(None, {"traffic.warmup_s": 0.0}))
    rows = w.window._targets(w, 350.0)
    assert [r[1] for r in rows if r[1] == 0] == []
    assert any(r[1] == 0 for r in w.window._targets(w, 360.0))  # 10 m of it in the window: wanted


def test_the_traffic_section_is_the_windows_parameters(road) -> None:
    """One declaration (docs/architecture.md §1): the ``traffic`` section's dataclass is the window's
    TrafficParams, defaults and checks included; the window reads the section as it is, its lanes'
    entry speeds paired from the section's means and standard deviations."""
    from evoscen_sim.config.config_schema import TrafficConfig
    from evoscen_sim.traffic.scenario_params import traffic_params_from_config

    assert TrafficParams is TrafficConfig
    assert P.lane_speed_mps == ((26.0, 1.5), (28.0, 1.5), (30.0, 1.5), (32.0, 1.5))
    cfg = load_scenario_config(None, {"traffic.lane_speed_mean_mps": [20.0, 21.0, 22.0, 23.0],
                                      "traffic.lane_speed_sd_mps": [0.0, 1.0, 2.0, 3.0]})
    params = traffic_params_from_config(cfg, road)
    assert params is cfg.traffic
    assert params.lane_speed_mps == ((20.0, 0.0), (21.0, 1.0), (22.0, 2.0), (23.0, 3.0))
    with pytest.raises(InputError, match=r"traffic\.insertion_decel_mps2"):
        load_scenario_config(None, {"traffic.insertion_decel_mps2": 0.0})  # the section's check: (0, 10]
    assert traffic_params_from_config(load_scenario_config(None, {"traffic.mode": "loop", "bvs.makeup": "uniform"}), road) is None
