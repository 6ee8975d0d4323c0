"""World: construction, re-entry rules (by hand), constant density over 10,000 steps of the
default scenario, and the spawn layout of the default scenario."""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_bringup.scenario import build_scenario
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.errors import InputError
from evoscen_sim.physics.collision import overlapping_pairs
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.traffic.spawn import spawn_layout
from evoscen_sim.physics.world import ROLE_BV, ROLE_SUT, ReentryParams, World
from evoscen_sim.road.road_model import RoadModel, load_road

DT = 0.1
L = 4.8
ROAD_LENGTH = 2393.76
CENTRE = {4: -1.75, 3: -5.25, 2: -8.75, 1: -12.25, 0: -15.75}


@pytest.fixture(scope="module")
def road() -> RoadModel:
    return load_road()


def make_world(road: RoadModel, s, lane, speed, reentry: ReentryParams = ReentryParams(), seed: int = 0) -> World:
    return hand_built_world(road, s, lane, speed, reentry=reentry, dt_s=DT, seed=seed, first_id=10)


def keep(n: int):
    return np.zeros(n), np.zeros(n, dtype=np.int64)


# ---------------------------------------------------------------- construction
def test_initial_state_centred_in_lanes(road: RoadModel) -> None:
    w = make_world(road, [100.0, 650.0, 2000.0], [4, 0, 1], [30.0, 20.0, 0.0])
    np.testing.assert_allclose(w.d, [CENTRE[4], CENTRE[0], CENTRE[1]])
    np.testing.assert_array_equal(w.psi, 0.0)
    np.testing.assert_array_equal(w.target_lane, [4, 0, 1])
    np.testing.assert_array_equal(w.lane_change, 0)
    np.testing.assert_array_equal(w.lane_change_count, 0)
    assert w.time_s == 0.0 and w.step_index == 0
    cols = w.columns()
    np.testing.assert_array_equal(cols["id"], [10, 11, 12])
    np.testing.assert_array_equal(cols["lane"], [4, 0, 1])
    np.testing.assert_allclose(cols["length"], L)


def test_initial_state_in_missing_lane_rejected(road: RoadModel) -> None:
    with pytest.raises(ValueError, match="lane 0"):
        make_world(road, [300.0], [0], [20.0])  # the merge lane starts at s = 600
    with pytest.raises(ValueError):
        make_world(road, [1000.0], [0], [20.0])  # and ends at 960


def test_step_rejects_wrong_command_shapes(road: RoadModel) -> None:
    w = make_world(road, [100.0, 200.0], [1, 2], [30.0, 30.0])
    with pytest.raises(ValueError):
        w.step(np.zeros(3), np.zeros(2, dtype=np.int64))
    with pytest.raises(ValueError):
        w.step(np.zeros(2), np.zeros(1, dtype=np.int64))


# ---------------------------------------------------------------- re-entry, by hand
def test_reentry_on_empty_road_goes_to_rightmost_mainline_lane(road: RoadModel) -> None:
    # 1 m before the end at 30 m/s: after one step s = L + 2 > L -> re-enters at s = 0 of the
    # mainline lane with the most free space; all are empty (inf), the first (rightmost, 1) wins
    w = make_world(road, [ROAD_LENGTH - 1.0], [3], [30.0], ReentryParams(ramp_share=0.0))
    res = w.step(*keep(1))
    assert res.reentries == [(0, 1, 0.0)]
    assert w.s[0] == 0.0 and w.lane[0] == 1 and w.target_lane[0] == 1
    assert w.d[0] == pytest.approx(CENTRE[1]) and w.psi[0] == 0.0 and w.steer[0] == 0.0
    assert w.v[0] == 30.0  # keeps its speed (nothing ahead)
    assert w.accel[0] == 0.0


def test_reentry_at_end_during_lane_change_resets_it(road: RoadModel) -> None:
    w = make_world(road, [ROAD_LENGTH - 20.0], [3], [30.0], ReentryParams(ramp_share=0.0))
    res = w.step(np.zeros(1), np.array([1]))
    assert res.executed_lane_change[0] == 1
    for _ in range(6):
        res = w.step(*keep(1))
        if res.reentries:
            break
    assert res.reentries and res.reentries[0][0] == 0
    assert w.lane_change[0] == 0 and w.target_lane[0] == w.lane[0] == 1
    assert np.isnan(w.lane_change_start_s[0])
    assert w.lane_change_count[0] == 0


def test_reentry_picks_lane_with_most_space_and_matches_speed(road: RoadModel) -> None:
    # lanes 1..4 have their first vehicle at s = 60, 20, 150, 90 (all 20 m/s, stopped would
    # not matter); free space from s = 0: 60-4.8, 20-4.8, 150-4.8, 90-4.8 -> lane 3 at s = 0.
    # The vehicle ahead (150 m) is beyond the 100 m speed-match range: speed kept.
    s = [60.0, 20.0, 150.0, 90.0, ROAD_LENGTH - 1.0]
    w = make_world(road, s, [1, 2, 3, 4, 2], [20.0, 20.0, 20.0, 20.0, 30.0], ReentryParams(ramp_share=0.0))
    res = w.step(*keep(5))
    assert res.reentries == [(4, 3, 0.0)]
    assert w.v[4] == 30.0
    # lane 3's vehicle now 60 m ahead of the entry: within 100 m -> capped at its speed (20)
    s = [60.0, 20.0, 60.0, 50.0, ROAD_LENGTH - 1.0]
    w = make_world(road, s, [1, 2, 3, 4, 2], [20.0, 21.0, 22.0, 23.0, 30.0], ReentryParams(ramp_share=0.0))
    res = w.step(*keep(5))
    # after the step the vehicles are at 62, 22.1, 62.2, 52.3: lane 3 has the most space
    assert res.reentries == [(4, 3, 0.0)]
    assert w.v[4] == 22.0


def test_reentry_behind_last_vehicle_when_crowded(road: RoadModel) -> None:
    # every mainline lane has a vehicle at s = 10 (after the step: 10 + 3 = 13): free space
    # 13 - 4.8 = 8.2 < 15 everywhere -> rightmost lane, s = 8.2 - 15 = -6.8 (on the approach,
    # 15 m bumper gap to the vehicle ahead), speed capped by that vehicle (30 -> 30)
    s = [10.0, 10.0, 10.0, 10.0, ROAD_LENGTH - 1.0]
    w = make_world(road, s, [1, 2, 3, 4, 3], [30.0] * 4 + [35.0], ReentryParams(ramp_share=0.0))
    res = w.step(*keep(5))
    assert len(res.reentries) == 1
    i, lane, s_entry = res.reentries[0]
    assert (i, lane) == (4, 1)
    assert s_entry == pytest.approx(13.0 - 4.8 - 15.0)
    assert w.s[4] == pytest.approx(-6.8)
    assert w.v[4] == 30.0
    assert w.d[4] == pytest.approx(CENTRE[1])  # road look-ups at s = 0
    assert res.collisions == []
    # on the approach it drives on like anyone else and enters the road
    for _ in range(5):
        res = w.step(*keep(5))
        assert res.collisions == [] and res.off_road == []
    assert w.s[4] == pytest.approx(-6.8 + 15.0)


def test_two_reentries_into_crowded_entry_do_not_overlap(road: RoadModel) -> None:
    s = [10.0, 10.0, 10.0, 10.0, ROAD_LENGTH - 1.0, ROAD_LENGTH - 1.5]
    w = make_world(road, s, [1, 2, 3, 4, 2, 3], [30.0] * 6, ReentryParams(ramp_share=0.0))
    res = w.step(*keep(6))
    assert len(res.reentries) == 2
    assert res.collisions == []
    a, b = res.reentries
    if a[1] == b[1]:  # same lane: at least the minimum bumper gap apart
        assert abs(a[2] - b[2]) - L >= ReentryParams().min_gap_m - 1e-9


def test_reentry_on_ramp(road: RoadModel) -> None:
    # ramp_share 1: always the start of the merge lane (s = 600) when 15 m are free there
    w = make_world(road, [ROAD_LENGTH - 1.0], [2], [30.0], ReentryParams(ramp_share=1.0))
    res = w.step(*keep(1))
    assert res.reentries == [(0, 0, 600.0)]
    assert w.lane[0] == 0 and w.d[0] == pytest.approx(CENTRE[0])
    # merge-lane entry blocked (a vehicle at 610: free space 10 - 4.8 < 15) -> mainline instead
    w = make_world(road, [607.0, ROAD_LENGTH - 1.0], [0, 2], [30.0, 30.0], ReentryParams(ramp_share=1.0))
    res = w.step(*keep(2))
    assert res.reentries == [(1, 1, 0.0)]


def test_reentry_ramp_share_uses_seeded_generator(road: RoadModel) -> None:
    def lanes(seed: int) -> list[int]:
        w = make_world(road, [ROAD_LENGTH - 1.0], [2], [30.0], ReentryParams(ramp_share=0.5), seed=seed)
        out = []
        for _ in range(30):
            w.s[0] = ROAD_LENGTH - 1.0  # send it off the end again
            res = w.step(*keep(1))
            out.append(res.reentries[0][1])
        return out

    a = lanes(3)
    assert a == lanes(3)
    assert set(a) == {0, 1}  # both ramp and mainline occur at a share of 0.5


# ---------------------------------------------------------------- density over 10,000 steps
def test_density_constant_over_10000_steps() -> None:
    """docs/method.md §1, ``traffic.mode: loop``: vehicles leaving the map re-enter, so the number on
    the road never changes.

    world.py allows a re-entering vehicle on the approach (s < 0, at most min_gap_m + L
    behind s = 0) when every entry is crowded; in the default scenario that never happens,
    so all 21 vehicles have s in [0, length] at every step.
    """
    sc = build_scenario(load_scenario_config(None, {"steps": 10000, "traffic.mode": "loop", "bvs.makeup": "uniform"}))
    w = sc.world
    road = sc.road
    n = w.n
    assert n == 21
    length = road.length_m
    approach = -(sc.config.reentry.min_gap_m + sc.config.vehicle.length_m)
    reentries = 0
    min_s, max_s = np.inf, -np.inf
    on_road_counts = np.empty(10000, dtype=np.int64)
    for k in range(10000):
        res = sc.step()
        s = w.s
        lo, hi = s.min(), s.max()
        min_s, max_s = min(min_s, lo), max(max_s, hi)
        on_road_counts[k] = np.count_nonzero((s >= 0.0) & (s <= length))
        reentries += len(res.reentries)
        if res.off_road:
            raise AssertionError(f"step {res.step}: off-road {res.off_road}")
        if k % 50 == 0:
            assert (road.lane_of(s, w.d) >= 0).all()
        for _, lane, s_entry in res.reentries:
            assert (lane == 0 and s_entry == 600.0) or (lane >= 1 and approach <= s_entry <= 0.0)
    assert w.n == 21 and w.s.shape == (21,)
    assert min_s >= approach and max_s <= length
    assert reentries > 0
    assert (on_road_counts == 21).all()
    assert min_s >= 0.0


# ---------------------------------------------------------------- spawn layout
@pytest.fixture(scope="module")
def default_scenario():
    """The spawn layout of ``traffic.mode: loop`` (the window's: test_traffic.py)."""
    return build_scenario(load_scenario_config(None, {"traffic.mode": "loop", "bvs.makeup": "uniform"}))


def test_spawn_sut_and_roles(default_scenario) -> None:
    sc = default_scenario
    cfg, w = sc.config, sc.world
    assert w.n == cfg.bvs.count + 1 == 21
    np.testing.assert_array_equal(w.ids, np.arange(21))
    assert w.role[0] == ROLE_SUT and (w.role[1:] == ROLE_BV).all()
    assert w.lane[0] == cfg.sut.lane == 2
    assert w.s[0] == cfg.sut.s_m == 300.0
    assert w.v[0] == cfg.sut.speed_mps == 27.0


def test_spawn_ramp_and_mainline_positions(default_scenario) -> None:
    sc = default_scenario
    cfg, w = sc.config, sc.world
    pitch = cfg.spawn.mainline_gap_m + L  # 44.8
    jitter = cfg.spawn.jitter_m  # 5 (< mainline_gap / 2 - 0.5)
    ramp = np.flatnonzero(w.lane == 0)
    assert ramp.size == cfg.spawn.ramp_vehicles == 3
    np.testing.assert_array_equal(ramp, [1, 2, 3])
    assert ((w.s[ramp] >= 600.0) & (w.s[ramp] < 960.0)).all()
    # front first from the merge lane's start: 600 + 4.8 + j * 44.8, +- jitter
    assert np.abs(w.s[ramp] - (600.0 + L + pitch * np.arange(3))).max() <= jitter
    main = np.flatnonzero((w.lane >= 1) & (np.arange(w.n) > 0))
    assert main.size == 17
    # mainline slots: 300 + j * pitch + ((lane - 2) % 4) * pitch / 4, +- jitter; not the SUT's slot
    stagger = ((w.lane[main] - 2) % 4) * 0.25 * pitch
    j = np.round((w.s[main] - 300.0 - stagger) / pitch)
    assert np.abs(w.s[main] - (300.0 + j * pitch + stagger)).max() <= jitter
    assert not ((w.lane[main] == 2) & (j == 0)).any()
    # nearest-to-the-SUT-first filling keeps the block tight around it
    assert np.abs(w.s[main] - 300.0).max() <= 3 * pitch + jitter
    lo, hi = cfg.spawn.speed_mps
    assert ((w.v[1:] >= lo) & (w.v[1:] <= hi)).all()


def test_spawn_no_overlap(default_scenario) -> None:
    w = default_scenario.world
    for lane in range(5):
        s = np.sort(w.s[w.lane == lane])
        assert (np.diff(s) > L).all(), lane
    assert overlapping_pairs(w.s, w.d, w.psi, w.length, w.width).shape == (0, 2)


def test_spawn_deterministic_in_seed() -> None:
    def state(seed: int):
        w = build_scenario(load_scenario_config(None, {"seed": seed})).world
        return w.s.copy(), w.lane.copy(), w.v.copy()

    a, b, c = state(5), state(5), state(6)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a[0], c[0])
    assert not np.array_equal(a[2], c[2])


def test_spawn_layout_too_many_ramp_vehicles(road: RoadModel) -> None:
    kwargs = dict(bv_policies=np.zeros(12, dtype=np.int64), sut_policy=4, sut_lane=2, sut_s_m=300.0,
                  sut_speed_mps=27.0, mainline_gap_m=40.0, speed_range_mps=(24.0, 30.0), jitter_m=5.0,
                  vehicle_length_m=L)
    # merge lane 600..960, a slot must be <= 960 - 30: 604.8 + 7 * 44.8 = 918.4 (the 8th) fits,
    # 604.8 + 8 * 44.8 = 963.2 (the 9th) does not
    init = spawn_layout(road, ramp_vehicles=8, rng=np.random.default_rng(0), **kwargs)
    assert (init.lane == 0).sum() == 8
    with pytest.raises(InputError):
        spawn_layout(road, ramp_vehicles=9, rng=np.random.default_rng(0), **kwargs)
    with pytest.raises(InputError):
        spawn_layout(road, **{**kwargs, "sut_lane": 0}, ramp_vehicles=0, rng=np.random.default_rng(0))


def test_spawn_jitter_never_puts_a_ramp_vehicle_before_the_merge_lane(road: RoadModel) -> None:
    # the first ramp slot is 604.8 m; a jitter of -5 m would put its centre at 599.8 m, before the
    # merge lane starts (600 m): it is held at 600 + L/2 (this seed drew such a jitter: a World error before)
    kwargs = dict(bv_policies=np.zeros(20, dtype=np.int64), sut_policy=4, sut_lane=2, sut_s_m=300.0,
                  sut_speed_mps=27.0, mainline_gap_m=40.0, speed_range_mps=(24.0, 30.0), jitter_m=5.0,
                  vehicle_length_m=L, ramp_vehicles=3)
    lowest = min(spawn_layout(road, rng=np.random.default_rng(seed), **kwargs).s_m[1] for seed in range(200))
    assert lowest == pytest.approx(600.0 + L / 2)


def test_the_world_table_is_the_columns_stacked_as_the_evaluator_stacks_them():
    # World.table (one compiled pass) against its definition: the columns of state_columns, in the contract's order,
    # stacked as rows and transposed (evoscen_eval's add_world_columns), bit for bit, on every state of a run
    from evoscen_bringup.scenario import build_scenario
    from evoscen_contract.contract import WORLD_FIELDS
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.physics.world import TABLE_FIELDS

    assert TABLE_FIELDS == WORLD_FIELDS
    sc = build_scenario(load_scenario_config(None, {"bvs.nodes": "single", "seed": 4303, "traffic.warmup_s": 5.0}))
    w = sc.world
    w.s[3] = -12.5  # a vehicle waiting on the approach: looked up at s = 0, its own s kept
    for _ in range(150):
        cols = w.columns()
        want = np.array([cols[f] for f in WORLD_FIELDS], dtype=np.float64).T.copy()
        got = w.table()
        assert got.dtype == np.float64 and got.flags.c_contiguous
        assert np.array_equal(got.view(np.int64), want.view(np.int64))  # the same bits, NaN included
        sc.step()


def test_the_step_hands_back_the_look_ups_of_the_new_positions():
    # the world's step makes the lane look-up and the speed limits in its compiled pass; after every step they are
    # those of the road at the new positions (entries and window shifts included), bit for bit
    sc = build_scenario(load_scenario_config(None, {"bvs.nodes": "single", "seed": "1031000"}))
    w = sc.world
    rows = np.arange(w.n)
    entries = shifts = 0
    for _ in range(700):  # the window shifts first at step 627 of this seed
        result = sc.step()
        entries += len(result.reentries)
        shifts += bool(result.shift_m)
        fresh = w.road.lane_lookup(np.maximum(w.s, 0.0), w.d)
        got = w.lane_lookup()
        for name in ("d_right", "d_left", "present", "max_speed_mps", "lane", "curvature"):
            a, b = np.asarray(getattr(got, name)), np.asarray(getattr(fresh, name))
            assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), name
        assert w.speed_limit_mps.tobytes() == fresh.max_speed_mps[rows, w.lane].tobytes()
        assert w.speed_limit_mps.dtype == np.float64 and w.speed_limit_mps.shape == (w.n,)
    assert entries > 0 and shifts > 0  # both ways the look-ups are made again were taken
