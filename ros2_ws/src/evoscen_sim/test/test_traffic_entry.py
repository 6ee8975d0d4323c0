"""The traffic window's compiled entry search (evoscen_sim.physics.window, docs/method.md §1) against
a straightforward numpy reference of the same rule (kept here): the same placement, speed and random
draws on random worlds, step by step over random runs, and cases derived by hand."""

from __future__ import annotations

import copy
import math
import types
from dataclasses import replace

import numpy as np
import pytest
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.physics.window import (
    MERGE_LANE,
    TrafficParams,
    _lane_counts,
    _np_clip,
    _place_in_lane,
    insertion_speed,
    required_gap,
)
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.world import ROLE_BV, ROLE_SUT, World
from evoscen_sim.road.road_kernels import lane_borders, lane_present
from evoscen_sim.road.road_model import load_road

P = TrafficParams()


@pytest.fixture(scope="module")
def road():
    return load_road(load_scenario_config(None).map)


# ---------------------------------------------------------------- the reference: the rule in numpy
def _ref_targets(win, world, s_sut):
    p = win.p
    road = world.road
    lo, hi = s_sut - p.behind_m, s_sut + p.ahead_m
    inside = (world.s >= lo) & (world.s <= hi)
    inside[win.sut] = False
    occupied = np.where(world.lane_change != 0, world.target_lane, world.lane)
    rows = []
    length_km = (hi - lo) / 1000.0
    for j, lane in enumerate(win.mainline):
        target = p.lane_density_per_km[j] * length_km
        if target <= 0.0:
            continue
        count = int(np.count_nonzero(inside & (occupied == lane)))
        mean, sd = p.lane_speed_mps[j]
        rows.append(((count - target) / target, lane, mean, sd))
    if win.has_ramp and p.ramp_density_per_km > 0.0:
        start, end = float(road.lane_start_s[MERGE_LANE]), float(road.lane_end_s[MERGE_LANE])
        target = p.ramp_density_per_km * (min(end, hi) - start) / 1000.0
        if lo <= start <= hi and target > 0.0:
            count = int(np.count_nonzero(inside & (occupied == MERGE_LANE)))
            rows.append(((count - target) / target, MERGE_LANE, *p.ramp_speed_mps))
    rows.sort(key=lambda r: (r[0], r[1]))
    return [r for r in rows if r[0] < 0.0] or rows


def _ref_enter(win, world, i):
    p = win.p
    road = world.road
    s_sut, v_sut = float(world.s[win.sut]), float(world.v[win.sut])
    half = 0.5 * world.vehicle.length_m
    for _, lane, mean, sd in _ref_targets(win, world, s_sut):
        v = float(np.clip(world.rng.normal(mean, sd), mean - 2.0 * sd, mean + 2.0 * sd))
        v_floor = max(0.0, mean - 2.0 * sd)
        if lane == MERGE_LANE:
            s_new = float(road.lane_start_s[MERGE_LANE]) + half
        elif v < v_sut:
            s_new = s_sut + p.ahead_m
        else:
            s_new = s_sut - p.behind_m
        found, s_try, v_try = _ref_place(p, world, i, lane, s_new, s_sut, v, v_floor, half)
        if found:
            world._place(i, lane, s_try, v_try)
            return (i, int(lane), float(s_try))
    return None


def _ref_place(p, world, i, lane, s_new, s_sut, v, v_floor, half):
    for s_try in _ref_positions(p, world, i, lane, s_new, s_sut):
        if not bool(world.road.lane_exists(np.array([lane]), np.array([s_try]))[0]):
            continue
        v_try = _ref_safe_speed(p, world, i, lane, s_try, v, half)
        if v_try >= v_floor:
            return True, s_try, v_try
    return False, 0.0, 0.0


def _ref_positions(p, world, i, lane, s_edge, s_sut):
    band = p.insertion_band_m
    if lane == MERGE_LANE or band <= 0.0:
        return [s_edge]
    inward = -1.0 if s_edge > s_sut else 1.0
    a, b = sorted((s_edge, s_edge + inward * band))
    cand = ((world.lane == lane) | (world.target_lane == lane)) & (world.s >= a - 100.0) & (world.s <= b + 100.0)
    cand[i] = False
    s = np.sort(np.concatenate([world.s[cand], [a - 1e9, b + 1e9]]))
    s = np.clip(s, a, b)
    k = int(np.argmax(np.diff(s)))
    mid = 0.5 * (s[k] + s[k + 1])
    return [s_edge] if abs(mid - s_edge) < 1e-9 else [s_edge, float(mid)]


def _ref_safe_speed(p, world, i, lane, s_new, v, half):
    leader, follower = _ref_neighbours(world, i, lane, s_new)
    if leader >= 0:
        gap = world.s[leader] - s_new - 0.5 * world.length[leader] - half
        v = insertion_speed(v, gap, float(world.v[leader]), p)
    if follower >= 0:
        gap = s_new - world.s[follower] - 0.5 * world.length[follower] - half
        if gap < required_gap(float(world.v[follower]), v, p):
            return -math.inf
    return v


def _ref_neighbours(world, i, lane, s_new):
    look = world.road.lane_lookup(np.array([max(s_new, 0.0)]), np.zeros(1))
    right, left = float(look.d_right[0, lane]), float(look.d_left[0, lane])
    half_w = 0.5 * world.width
    across = (world.d + half_w > right) & (world.d - half_w < left)
    cand = (world.lane == lane) | (world.target_lane == lane) | across
    cand[i] = False
    k = np.flatnonzero(cand)
    if not k.size:
        return -1, -1
    ds = world.s[k] - s_new
    ahead, behind = k[ds >= 0.0], k[ds < 0.0]
    leader = int(ahead[np.argmin(world.s[ahead])]) if ahead.size else -1
    follower = int(behind[np.argmax(world.s[behind])]) if behind.size else -1
    return leader, follower


# ---------------------------------------------------------------- worlds
def _world(road, s, lane, v, params: TrafficParams, seed: int = 0) -> World:
    """Vehicle 0 the SUT, the others BVs, in the traffic window ``params``."""
    return hand_built_world(road, s, lane, v, roles=[ROLE_SUT] + [ROLE_BV] * (len(s) - 1), seed=seed, traffic=params)


def _random_world(road, seed: int) -> World:
    """A crowded window, some vehicles changing lanes or off their lane's centre (straddling a border)."""
    g = np.random.default_rng(1000 + seed)
    n = int(g.integers(8, 45))
    s_sut = float(g.choice([g.uniform(300.0, 1900.0), g.uniform(550.0, 800.0)]))  # often with the merge lane
    s = s_sut + g.uniform(-170.0, 270.0, n)
    s[0] = s_sut
    lane = g.integers(1, 5, n)
    if seed % 3 == 0:  # on a grid with the window's edges, in two lanes: ties of positions and of gaps
        s_sut = s[0] = np.round(s_sut / 25.0) * 25.0
        s[1:] = s_sut + 25.0 * g.integers(-7, 11, n - 1)
        lane[1:] = g.integers(1, 3, n - 1)
    ramp = (s >= 610.0) & (s <= 890.0) & (g.random(n) < 0.3)
    lane[ramp] = 0
    lane[0] = g.integers(1, 5)
    v = g.uniform(15.0, 36.0, n)
    band = float(g.choice([0.0, 50.0, 80.0]))
    speeds = tuple((float(g.uniform(22.0, 33.0)), float(g.choice([0.0, 1.5, 4.0]))) for _ in range(4))
    params = replace(
        P, insertion_band_m=band,
        lane_speed_mean_mps=tuple(mean for mean, _ in speeds), lane_speed_sd_mps=tuple(sd for _, sd in speeds),
        lane_density_per_km=tuple(float(x) for x in g.choice([0.0, 12.5, 30.0], 4)),
        ramp_density_per_km=float(g.choice([0.0, 10.0])))
    w = _world(road, s, lane, v, params, seed=seed)
    changing = g.random(n) < 0.2
    changing[0] = False
    for j in np.flatnonzero(changing):
        to = int(lane[j]) + int(g.choice([-1, 1]))
        if 1 <= to <= 4:
            w.target_lane[j] = to
            w.lane_change[j] = to - int(lane[j])
    w.d += np.where(g.random(n) < 0.3, g.uniform(-1.8, 1.8, n), 0.0)
    return w


def _same_world(a: World, b: World) -> None:
    for name in ("s", "d", "psi", "v", "accel", "steer", "lane", "target_lane", "lane_change", "off_road"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name, strict=True)
    assert a.rng.bit_generator.state == b.rng.bit_generator.state  # the same number of draws


# ---------------------------------------------------------------- tests
def test_lane_borders_and_presence_match_the_road_model(road) -> None:
    bt = road.border_tables()
    g = np.random.default_rng(3)
    s = np.concatenate([g.uniform(-30.0, road.length_m + 30.0, 400), g.uniform(890.0, 970.0, 200),
                        [0.0, -0.0, 600.0, 900.0, 930.0, 960.0, road.length_m]])
    look = road.lane_lookup(np.maximum(s, 0.0), np.zeros_like(s))
    for k, sk in enumerate(s):
        for lane in range(road.num_lanes):
            assert lane_borders(bt, lane, float(sk)) == (look.d_right[k, lane], look.d_left[k, lane])
            assert lane_present(bt, lane, float(sk)) == bool(road.lane_exists(lane, float(sk)))
    assert not lane_present(bt, -1, 700.0) and not lane_present(bt, road.num_lanes, 700.0)


def test_clip_of_a_draw_is_numpys() -> None:
    g = np.random.default_rng(4)
    x = np.concatenate([g.normal(0.0, 3.0, 2000), [-2.0, 2.0, 0.0, -0.0, 1e300, -np.inf, np.inf, np.nan]])
    for lo, hi in ((-2.0, 2.0), (0.0, 0.0), (-0.0, -0.0), (0.0, -0.0), (-0.0, 0.0), (1.0, -1.0), (np.nan, 1.0),
                   (-1.0, np.nan), (-np.inf, np.inf)):
        for xk in x:
            got, want = _np_clip(float(xk), lo, hi), float(np.clip(xk, lo, hi))
            assert (got == want and math.copysign(1.0, got) == math.copysign(1.0, want)) or (
                math.isnan(got) and math.isnan(want)), (xk, lo, hi)


def test_lane_counts_match_numpy(road) -> None:
    for seed in range(20):
        w = _random_world(road, seed)
        lo, hi = float(w.s[0]) - 150.0, float(w.s[0]) + 250.0
        inside = (w.s >= lo) & (w.s <= hi)
        inside[0] = False
        occupied = np.where(w.lane_change != 0, w.target_lane, w.lane)
        want = [int(np.count_nonzero(inside & (occupied == k))) for k in range(road.num_lanes)]
        got = _lane_counts(w.s, w.lane, w.target_lane, w.lane_change, 0, lo, hi, road.num_lanes)
        assert got.tolist() == want


def test_entries_equal_the_reference_on_random_worlds(road) -> None:
    outcomes = {"placed": 0, "none": 0}
    for seed in range(150):
        w = _random_world(road, seed)
        for i in range(1, w.n, 3):
            a = copy.deepcopy(w, memo={id(road): road})
            b = copy.deepcopy(w, memo={id(road): road})
            got = a.window._enter(a, i)
            want = _ref_enter(b.window, b, i)
            assert got == want, (seed, i)
            _same_world(a, b)
            if got is None:
                outcomes["none"] += 1
            else:
                outcomes["placed"] += 1
    # the random worlds reach both outcomes
    assert min(outcomes.values()) >= 20, outcomes


def test_the_placement_kernel_equals_the_reference_per_lane(road) -> None:
    # every lane, both edges, random wishes and floors: (found, s, speed) identical to the bit
    n_found = n_mid = n_lowered = 0
    for seed in range(60):
        w = _random_world(road, seed)
        p = w.window.p
        g = np.random.default_rng(seed)
        s_sut = float(w.s[0])
        for _ in range(20):
            i = int(g.integers(1, w.n))
            lane = int(g.integers(0, road.num_lanes))
            edge = float(g.choice([s_sut + p.ahead_m, s_sut - p.behind_m, 600.0 + 2.4]))
            v, v_floor = float(g.uniform(10.0, 38.0)), float(g.choice([0.0, g.uniform(5.0, 30.0)]))
            want = _ref_place(p, w, i, lane, edge, s_sut, v, v_floor, 2.4)
            got = _place_in_lane(w.s, w.d, w.v, w.length, w.width, w.lane, w.target_lane, i, lane, edge, s_sut,
                                 v, v_floor, 2.4, p.insertion_band_m, p.insertion_min_gap_m, p.insertion_headway_s,
                                 p.insertion_decel_mps2, (p.insertion_decel_mps2 * p.insertion_headway_s) ** 2,
                                 road.border_tables(), 0.0)
            assert (bool(got[0]), got[1], got[2]) == (want[0], want[1], want[2]), (seed, i, lane, edge)
            n_found += int(want[0])
            n_mid += int(want[0] and want[1] != edge)
            n_lowered += int(want[0] and want[2] < v)
    assert n_found >= 100 and n_mid >= 20 and n_lowered >= 20, (n_found, n_mid, n_lowered)


def _args(w, i, lane, edge, v, v_floor, p=P, v_raise=0.0):
    return (w.s, w.d, w.v, w.length, w.width, w.lane, w.target_lane, i, lane, edge, float(w.s[0]), v, v_floor,
            0.5 * w.vehicle.length_m, p.insertion_band_m, p.insertion_min_gap_m, p.insertion_headway_s,
            p.insertion_decel_mps2, (p.insertion_decel_mps2 * p.insertion_headway_s) ** 2, w.road.border_tables(),
            v_raise)


def test_a_leader_at_a_known_gap_gives_the_krauss_speed(road) -> None:
    # SUT at 1,500 m in lane 2; the front edge of lane 1 is 1,750 m; a leader at 25 m/s 40 m
    # (bumper to bumper, 4.8 m vehicles) ahead of it: v = -b tau + sqrt((b tau)^2 + v_l^2 + 2 b (40 - g0))
    edge = 1750.0
    w = _world(road, [1500.0, 1200.0, edge + 44.8], [2, 3, 1], [30.0, 27.0, 25.0], P)
    found, s_new, v = _place_in_lane(*_args(w, 1, 1, edge, 30.0, 0.0))
    assert found and s_new == edge
    gap = w.s[2] - edge - 2.4 - 2.4  # 40 m, as the rule computes it in floating point
    assert gap == pytest.approx(40.0) and v == insertion_speed(30.0, gap, 25.0, P)
    assert v == pytest.approx(-4.5 + math.sqrt(4.5 ** 2 + 25.0 ** 2 + 2.0 * 4.5 * 37.5))
    assert required_gap(v, 25.0, P) == pytest.approx(40.0)
    # that speed below the floor: the middle of the band (1,700 .. 1,750 m, the leader beyond it), 65 m
    # behind the leader; without the band, no place in this lane
    found, s_new, v_mid = _place_in_lane(*_args(w, 1, 1, edge, 30.0, v + 0.01))
    assert found and s_new == 1725.0 and v_mid == insertion_speed(30.0, w.s[2] - 1725.0 - 2.4 - 2.4, 25.0, P)
    assert v_mid == 30.0  # 65 m >= required_gap(30, 25) = 32.5 + 275 / 9
    assert not _place_in_lane(*_args(w, 1, 1, edge, 30.0, v + 0.01, replace(P, insertion_band_m=0.0)))[0]


def test_a_follower_that_could_not_follow_moves_the_entry_into_the_band(road) -> None:
    # a vehicle at 30 m/s 10 m behind the front edge: 5.2 m bumper gap, too short for it behind
    # anything. The band (1,700 .. 1,750 m) with that vehicle at 1,740 and the leader beyond the
    # edge: the largest gap is 1,700 .. 1,740, its middle 1,720 m, 20 m behind the vehicle at 30 m/s,
    # now the leader: 15.2 m gap, slower or as fast as it, only the headway binds: (15.2 - 2.5) / 1 s
    edge = 1750.0
    w = _world(road, [1500.0, 1200.0, edge + 44.8, edge - 10.0], [2, 3, 1, 1], [30.0, 27.0, 25.0, 30.0], P)
    found, s_new, v = _place_in_lane(*_args(w, 1, 1, edge, 30.0, 0.0))
    assert found and s_new == 1720.0
    assert v == insertion_speed(30.0, w.s[3] - 1720.0 - 2.4 - 2.4, 30.0, P) and v == pytest.approx(12.7)
    # without the band only the edge is tried
    assert not _place_in_lane(*_args(w, 1, 1, edge, 30.0, 0.0, replace(P, insertion_band_m=0.0)))[0]


def test_a_front_entry_raised_to_the_lowest_speed_its_follower_can_follow(road) -> None:
    # highd's front_entry_speed raise. A vehicle wishing 22 m/s at the front edge (1,750 m), a follower
    # at 32 m/s 60 m behind it (bumper to bumper), no band: at 22 m/s the follower needs
    # 2.5 + 32 + (32² − 22²) / 9 = 94.5 m, so it does not enter; raised, the lowest speed the follower
    # can follow at 60 m: sqrt(32² − 9 (60 − 2.5 − 32)) = sqrt(794.5) = 28.19 m/s, allowed up to the SUT's 33
    edge = 1750.0
    narrow = replace(P, insertion_band_m=0.0)
    w = _world(road, [1500.0, 1200.0, edge - 60.0 - 4.8], [2, 3, 1], [33.0, 27.0, 32.0], P)
    assert required_gap(32.0, 22.0, P) == pytest.approx(94.5)
    assert not _place_in_lane(*_args(w, 1, 1, edge, 22.0, 0.0, narrow))[0]  # 0: never raised
    found, s_new, v = _place_in_lane(*_args(w, 1, 1, edge, 22.0, 0.0, narrow, v_raise=33.0))
    assert found and s_new == edge and v == pytest.approx(math.sqrt(794.5))
    assert required_gap(32.0, v, P) == pytest.approx(60.0)
    assert not _place_in_lane(*_args(w, 1, 1, edge, 22.0, 0.0, narrow, v_raise=28.0))[0]  # 28.19 > the cap
    # a leader 40 m beyond the edge at 25 m/s allows at most insertion_speed(33, 40, 25) = 26.85 < 28.19: no place
    w = _world(road, [1500.0, 1200.0, edge - 60.0 - 4.8, edge + 44.8], [2, 3, 1, 1], [33.0, 27.0, 32.0, 25.0], P)
    assert insertion_speed(33.0, 40.0, 25.0, P) == pytest.approx(-4.5 + math.sqrt(4.5 ** 2 + 25.0 ** 2 + 9.0 * 37.5))
    assert not _place_in_lane(*_args(w, 1, 1, edge, 22.0, 0.0, narrow, v_raise=33.0))[0]
    # a follower too close for any leader speed (gap < g0 + v tau = 34.5 m): never raised into it
    w = _world(road, [1500.0, 1200.0, edge - 30.0 - 4.8], [2, 3, 1], [33.0, 27.0, 32.0], P)
    assert not _place_in_lane(*_args(w, 1, 1, edge, 22.0, 0.0, narrow, v_raise=33.0))[0]


def test_runs_with_the_compiled_search_equal_the_reference_step_by_step(road) -> None:
    # random throttles and lane-change requests over a crowded window: every step's state and draws equal
    entries = 0
    for seed in range(3):
        worlds = []
        for ref in (False, True):
            w = _random_world(road, 200 + seed)
            w.window.p = replace(w.window.p, lane_density_per_km=(20.0,) * 4, ramp_density_per_km=10.0)
            if ref:
                w.window._enter = types.MethodType(lambda win, world, i: _ref_enter(win, world, i), w.window)
            worlds.append(w)
        cmd = np.random.default_rng(seed)
        for _ in range(400):
            throttle = cmd.uniform(-0.4, 0.4, worlds[0].n)
            request = np.where(cmd.random(worlds[0].n) < 0.02, cmd.choice([-1, 1], worlds[0].n), 0)
            ra, rb = (w.step(throttle.copy(), request.copy()) for w in worlds)
            assert ra.reentries == rb.reentries
            entries += len(ra.reentries)
            _same_world(*worlds)
    assert entries >= 15


@pytest.mark.parametrize("car_lanes", ["by_speed", "by_density"])
def test_the_compiled_entry_rows_are_pythons_for_cars_and_trucks_of_highd(car_lanes) -> None:
    # every vehicle of a highd world over a run, the window's lanes as _targets and _by_speed build them in Python
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.physics.window import _entry_rows

    cfg = load_scenario_config(None, {"bvs.nodes": "single", "seed": "1031003", "models.highd.car_lanes": car_lanes})
    sc = build_scenario(cfg)
    w, win = sc.world, sc.world.window
    mk, p = win.makeup, win.p
    kinds = {"truck": 0, "car": 0, "several": 0}
    for step in range(240):
        sc.step()
        if step % 8:
            continue
        for i in range(1, w.n):
            truck = bool(mk.truck[i])
            lanes, means, sds = _entry_rows(
                w.s, w.v, w.lane, w.target_lane, w.lane_change, win.sut, float(w.s[win.sut]), float(p.behind_m),
                float(p.ahead_m), win._num_lanes, *win._row_arrays, win.has_ramp and p.ramp_density_per_km > 0.0,
                float(p.ramp_density_per_km), win._ramp_start_s, win._ramp_end_s, float(p.ramp_speed_mps[0]),
                float(p.ramp_speed_mps[1]), MERGE_LANE, win._truck_mask if truck else win._all_lanes,
                mk.cars_by_speed and not truck, float(mk.wish_mps[i]))
            want = win._enter_rows(w, i)
            assert lanes.tolist() == [r[1] for r in want], (step, i)
            assert means.tolist() == [float(r[2]) for r in want] and sds.tolist() == [float(r[3]) for r in want]
            kinds["truck" if truck else "car"] += 1
            kinds["several"] += len(want) > 1
    assert min(kinds.values()) > 0, kinds  # trucks, cars, and rows to order were all seen


# ---------------------------------------------------------------- the retry rule (traffic.entry_retry_s)
def test_entry_retry_steps_by_hand():
    from evoscen_sim.physics.window import entry_retry_steps

    assert entry_retry_steps(1.0, 0.1) == 10 and entry_retry_steps(0.3, 0.1) == 3 and entry_retry_steps(2.0, 0.05) == 40
    assert entry_retry_steps(0.0, 0.1) == 0  # at the next step
    assert entry_retry_steps(0.01, 0.1) == 1  # never sooner than the next step


@pytest.mark.parametrize("makeup", ["uniform", "highd"])
@pytest.mark.parametrize(("retry_s", "every"), [(1.0, 10), (0.3, 3), (0.0, 1)])
def test_a_vehicle_without_a_place_tries_again_after_the_retry_time(monkeypatch, makeup, retry_s, every):
    """Every entry search fails (no place anywhere): each waiting vehicle searches again exactly ``every`` steps
    after its last search, under both make-ups, never sooner."""
    from evoscen_bringup.inprocess import run_plan
    from evoscen_bringup.plan import plan_of
    from evoscen_sim.physics.window import TrafficWindow

    tries: dict[int, list[int]] = {}

    def no_place(self, world, i):
        tries.setdefault(int(i), []).append(int(world.step_index))
        return None

    monkeypatch.setattr(TrafficWindow, "_enter", no_place)
    cfg = load_scenario_config(None, {"steps": "200", "seed": "11", "bvs.makeup": makeup, "bvs.driver": "level0",
                                      "traffic.warmup_s": "0", "traffic.entry_retry_s": str(retry_s),
                                      "recording.enabled": "false"})
    run_plan(plan_of(cfg, recorded=False), bag_dir=None, evaluate=False)
    gaps = [b - a for steps in tries.values() for a, b in zip(steps, steps[1:])]
    assert len(tries) >= 3 and gaps, tries  # vehicles left the window and waited
    assert min(gaps) == every
