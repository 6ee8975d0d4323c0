"""Level-0 traffic (docs/method.md §3.3) and the IDM it follows.

IDM (evoscen_sim/physics/idm.py): a = a_max [1 - (v/v0)^δ - (s*/s)²], s* = s0 + max(0, v T + v Δv / (2 √(a_max b))),
defaults T = 1.5 s, s0 = 2 m, a_max = 1.5 m/s², b = 2 m/s², δ = 4.
Merge rule (level0.py): change from lane 0 to lane 1 when the front and rear bumper gaps in
lane 1 are ≥ 8 m + 1.5 s × closing speed; the merge-lane end (960 m) minus 15 m is a standing
obstacle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_bringup.scenario import build_scenario
from evoscen_bv.level0 import Level0Driver, Level0Params
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.idm import IdmParams, idm_acceleration
from evoscen_sim.physics.vehicle import VehicleParams
from evoscen_sim.physics.world import World
from evoscen_sim.road.road_model import RoadModel, load_road

DT = 0.1
L = 4.8
IDM = IdmParams()
MERGE_END = 960.0
STOP_LINE = MERGE_END - 15.0


def idm(v, v0, gap, vl, max_decel=9.0) -> float:
    return float(idm_acceleration(np.array([v], dtype=float), np.array([v0], dtype=float), np.array([gap], dtype=float),
                                  np.array([vl], dtype=float), IDM, max_decel)[0])


# ---------------------------------------------------------------- IDM
def test_idm_free_road() -> None:
    assert idm(30.0, 30.0, math.inf, math.nan) == pytest.approx(0.0, abs=1e-12)  # at v0: 0
    assert idm(0.0, 30.0, math.inf, math.nan) == pytest.approx(1.5)  # standstill: a_max
    # v = v0 / 2: a_max (1 - 1/16)
    assert idm(15.0, 30.0, math.inf, math.nan) == pytest.approx(1.5 * 15.0 / 16.0)
    # above v0: braking, 1.5 (1 - 1.2^4)
    assert idm(36.0, 30.0, math.inf, math.nan) == pytest.approx(1.5 * (1.0 - 1.2**4))
    # no leader = infinite gap, whatever the (nan) leader speed; vectorised
    a = idm_acceleration(np.array([10.0, 20.0]), np.array([30.0, 30.0]), np.array([np.inf, np.inf]),
                         np.array([np.nan, 5.0]), IDM)
    np.testing.assert_allclose(a, [1.5 * (1 - (1 / 3) ** 4), 1.5 * (1 - (2 / 3) ** 4)])


def test_idm_with_closing_leader_by_hand() -> None:
    # v = 20, v0 = 30, leader 15 m/s, gap 40 m:
    # s* = 2 + 20 * 1.5 + 20 * 5 / (2 sqrt(1.5 * 2)) = 32 + 100 / (2 sqrt 3) = 60.8675...
    s_star = 2.0 + 30.0 + 100.0 / (2.0 * math.sqrt(3.0))
    assert s_star == pytest.approx(60.8675, abs=1e-4)
    expected = 1.5 * (1.0 - (20.0 / 30.0) ** 4 - (s_star / 40.0) ** 2)  # = -2.2696...
    assert expected == pytest.approx(-2.2696, abs=1e-4)
    assert idm(20.0, 30.0, 40.0, 15.0) == pytest.approx(expected, rel=1e-12)


def test_idm_equal_speeds_and_opening_leader() -> None:
    # equal speeds: s* = 2 + 20 * 1.5 = 32; gap 64: interaction (1/2)^2
    assert idm(20.0, 30.0, 64.0, 20.0) == pytest.approx(1.5 * (1 - (2 / 3) ** 4 - 0.25))
    # fast leader: v T + v Δv / (2 sqrt(ab)) = 15 - 200 / 3.4641 < 0 -> s* = s0 = 2; gap 10
    assert idm(10.0, 20.0, 10.0, 30.0) == pytest.approx(1.5 * (1 - 0.5**4 - (2.0 / 10.0) ** 2))


def test_idm_clipped_at_max_decel() -> None:
    assert idm(30.0, 30.0, 0.5, 0.0) == -9.0
    assert idm(30.0, 30.0, 0.5, 0.0, max_decel=8.0) == -8.0
    assert idm(10.0, 30.0, 0.0, 10.0, max_decel=8.0) == -8.0  # touching
    assert idm(10.0, 30.0, -3.0, 10.0, max_decel=8.0) == -8.0  # overlapping
    # a mild case stays unclipped: v = 0, leader stopped 4 m ahead: s* = 2, a = 1.5 (1 - 1/4)
    assert idm(0.0, 30.0, 4.0, 0.0) == pytest.approx(1.125)


# ---------------------------------------------------------------- hand-built merges
@pytest.fixture(scope="module")
def road() -> RoadModel:
    return load_road()


def make_world(road: RoadModel, s, lane, speed) -> World:
    return hand_built_world(road, s, lane, speed, dt_s=DT)


def _hand_merge_ok(s_m, v_m, s_o, v_o) -> bool:
    """The merge rule against one vehicle in lane 1 (level counts as behind)."""
    if s_o > s_m:
        return s_o - s_m - L >= 8.0 + 1.5 * max(0.0, v_m - v_o)
    return s_m - s_o - L >= 8.0 + 1.5 * max(0.0, v_o - v_m)


@pytest.mark.parametrize("s_other,v_other", [(650.0, 30.0), (630.0, 33.0), (665.0, 20.0)])
def test_merge_waits_for_gap_then_changes(road: RoadModel, s_other: float, v_other: float) -> None:
    """Merger (0) on lane 0 at s = 650, 25 m/s, level-0 driven; vehicle 1 in lane 1 at constant
    speed (no throttle). The merger requests the change exactly while the rule holds."""
    w = make_world(road, [650.0, s_other], [0, 1], [25.0, v_other])
    driver = Level0Driver(np.array([0]), Level0Params(), np.random.default_rng(1), VehicleParams())
    assert not _hand_merge_ok(650.0, 25.0, s_other, v_other)  # unsafe at the start
    executed_at = None
    done_at = None
    for _ in range(300):
        thr, req = driver.act(w)
        if w.lane[0] == 0 and w.lane_change[0] == 0:
            assert bool(req[0]) == _hand_merge_ok(w.s[0], w.v[0], w.s[1], w.v[1])
        else:
            assert req[0] == 0  # never on the mainline
        res = w.step(np.array([thr[0], 0.0]), np.array([req[0], 0]))
        if res.executed_lane_change[0]:
            assert executed_at is None and res.executed_lane_change[0] == 1
            executed_at = res.step
        for veh, a, b, _ in res.lane_changes_completed:
            assert (veh, a, b) == (0, 0, 1)
            done_at = res.step
        assert res.collisions == [] and res.off_road == []
        assert not (w.lane[0] == 0 and w.s[0] >= MERGE_END)
    assert executed_at is not None and done_at is not None and executed_at < done_at
    assert w.lane[0] == 1 and w.lane_change_count[0] == 1


def test_merge_lane_end_is_a_stop_when_lane1_blocked(road: RoadModel) -> None:
    """Lane 1 is blocked by a standing platoon every 10 m (bumper gaps 5.2 m < 8 m) from
    s = 400 to 1000; the merger (0) at 650, 25 m/s, must stop before 960 - 15 = 945 m
    (front bumper; IDM standstill gap s0 = 2 m before it) without leaving the road."""
    platoon = np.arange(400.0, 1000.1, 10.0)
    n = platoon.size + 1
    w = make_world(road, np.concatenate([[650.0], platoon]), [0] + [1] * platoon.size,
                   np.concatenate([[25.0], np.zeros(platoon.size)]))
    driver = Level0Driver(np.array([0]), Level0Params(), np.random.default_rng(2), VehicleParams())
    throttle = np.full(n, -1.0)
    request = np.zeros(n, dtype=np.int64)
    for _ in range(450):
        thr, req = driver.act(w)
        assert req[0] == 0
        throttle[0], request[0] = thr[0], req[0]
        res = w.step(throttle, request)
        assert res.executed_lane_change[0] == 0
        assert res.collisions == [] and res.off_road == []
        assert w.lane[0] == 0 and road.lane_of(w.s[0], w.d[0]) == 0
        assert w.s[0] + 0.5 * L <= STOP_LINE
    assert w.v[0] < 0.1
    front = w.s[0] + 0.5 * L
    # IDM standstill: a = 0 at v = 0 when the gap equals s0 = 2 m -> front bumper at 943 m
    assert front == pytest.approx(STOP_LINE - IDM.min_gap_m, abs=0.3)
    assert (w.v[1:] == 0.0).all() and np.array_equal(w.s[1:], platoon)


# ---------------------------------------------------------------- default scenario
def test_default_scenario_level0_traffic() -> None:
    """3,000 steps of the default scenario with level-0 BVs: lane changes only from the merge
    lane into lane 1, every merging vehicle leaves lane 0 before 960 m, nobody leaves the road,
    no collisions."""
    sc = build_scenario(load_scenario_config(None, {"bvs.driver": "level0", "bvs.makeup": "uniform"}))
    w = sc.world
    changes = []
    executed = 0
    for _ in range(3000):
        lane_before = w.lane.copy()
        res = sc.step()
        lc = res.executed_lane_change
        if lc.any():
            who = np.flatnonzero(lc)
            assert (lc[who] == 1).all() and (lane_before[who] == 0).all(), (res.step, who)
            executed += who.size
        changes.extend(res.lane_changes_completed)
        assert res.collisions == [], (res.step, res.collisions)
        assert res.off_road == [], (res.step, res.off_road)
        on_merge = w.lane == 0
        if on_merge.any():
            assert (w.s[on_merge] < MERGE_END).all(), res.step
    assert len(changes) >= 3  # at least the three vehicles spawned on the merge lane
    assert all((a, b) == (0, 1) for _, a, b, _ in changes)
    assert all(3.0 <= t <= 6.0 for *_, t in changes)
    assert executed - len(changes) in (0, 1, 2)  # at most a change or two still in progress


# ---------------------------------------------------------------- same decisions from the wire
@pytest.mark.parametrize("driver", ["level0", "learned"])
def test_bv_driver_decides_identically_on_the_world_and_on_its_table_view(driver: str):
    """A node sees only the world table: rebuilt into a WorldView it must give the same commands
    (level-0 and the learned BVs, which the graph/in-process bag identity relies on)."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_contract.tables import table_columns, table_message
    from evoscen_contract.topics import MAP_FRAME, WORLD_FIELDS
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.loop.view import WorldView

    sc = build_scenario(load_scenario_config(None, {"bvs.driver": driver}))
    for _ in range(1500):  # through merges, lane changes and re-entries
        w = sc.world
        cols = w.columns()
        msg = table_message(WORLD_FIELDS, np.column_stack([cols[f] for f in WORLD_FIELDS]), w.time_ns, MAP_FRAME)
        view = WorldView(w.road, table_columns(msg), w.step_index, w.dt_s)
        thr_w, lc_w = sc.bv_driver.act(w)
        thr_v, lc_v = sc.bv_driver.act(view)
        assert np.array_equal(thr_w, thr_v) and np.array_equal(lc_w, lc_v)
        sc.apply(thr_w, lc_w, *sc.sut.act(w))
