"""Vehicle model, throttle mapping, dual PID lane keeping and lane changes in the world.

Expectations are derived by hand from the formulas in ``vehicle.py`` / ``control.py`` /
``world.py`` and the shipped map's numbers (lane width 3.5 m, reference line = left edge,
lane index i has its centre at d = -1.75 - 3.5 (4 - i); the border between lanes 2 and 3
is d = -7.0; the arc is s in [1000, 1600] with curvature 1/2000).
"""

from __future__ import annotations

import numpy as np
import pytest
from evoscen_sim.physics.control import ControlParams, DualPidController
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.vehicle import VehicleParams, accel_to_throttle, bicycle_step, throttle_to_accel
from evoscen_sim.physics.world import World
from evoscen_sim.road.road_model import RoadModel, load_road

DT = 0.1
P = VehicleParams()  # max_accel 3, max_brake 8, max_speed 40
CENTRE = {4: -1.75, 3: -5.25, 2: -8.75, 1: -12.25, 0: -15.75}
BORDER_2_3 = -7.0  # left border of lane 2 = right border of lane 3
BORDER_1_2 = -10.5


@pytest.fixture(scope="module")
def road() -> RoadModel:
    return load_road()


def make_world(road: RoadModel, s, lane, speed) -> World:
    return hand_built_world(road, s, lane, speed, dt_s=DT)


def keep(n: int = 1) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(n), np.zeros(n, dtype=np.int64)


# ---------------------------------------------------------------- throttle mapping
def test_throttle_to_accel_mapping() -> None:
    u = np.array([1.0, -1.0, 0.5, -0.5, 0.0, 2.0, -3.0, 0.25])
    expected = np.array([3.0, -8.0, 1.5, -4.0, 0.0, 3.0, -8.0, 0.75])
    np.testing.assert_allclose(throttle_to_accel(u, P), expected, rtol=0, atol=1e-12)


def test_throttle_mapping_uses_params() -> None:
    p = VehicleParams(max_accel_mps2=2.0, max_brake_mps2=6.0)
    np.testing.assert_allclose(throttle_to_accel(np.array([1.0, -1.0, 0.5, -0.5]), p), [2.0, -6.0, 1.0, -3.0])


def test_accel_to_throttle_inverse_and_clipping() -> None:
    a = np.array([3.0, -8.0, 1.5, -4.0, 0.0, 0.3, -0.8])
    np.testing.assert_allclose(accel_to_throttle(a, P), [1.0, -1.0, 0.5, -0.5, 0.0, 0.1, -0.1], atol=1e-12)
    # requests beyond the limits are clipped to full throttle / full brake
    np.testing.assert_allclose(accel_to_throttle(np.array([10.0, -20.0]), P), [1.0, -1.0])
    # round trips
    u = np.linspace(-1.0, 1.0, 41)
    np.testing.assert_allclose(accel_to_throttle(throttle_to_accel(u, P), P), u, atol=1e-12)
    acc = np.linspace(-8.0, 3.0, 45)
    np.testing.assert_allclose(throttle_to_accel(accel_to_throttle(acc, P), P), acc, atol=1e-12)


# ---------------------------------------------------------------- bicycle step
def _straight(s, v, a, n_steps=1):
    s, v = np.atleast_1d(np.asarray(s, dtype=float)), np.atleast_1d(np.asarray(v, dtype=float))
    a = np.broadcast_to(np.asarray(a, dtype=float), s.shape)
    z = np.zeros_like(s)
    d, psi = z.copy(), z.copy()
    realised = z
    for _ in range(n_steps):
        s, d, psi, v, realised = bicycle_step(s, d, psi, v, a, z, z, P, DT)
    return s, d, psi, v, realised


def test_bicycle_constant_speed_straight() -> None:
    s, d, psi, v, acc = _straight([100.0, 0.0], [30.0, 12.5], 0.0)
    np.testing.assert_array_equal(s, [103.0, 1.25])  # s + v dt exactly
    np.testing.assert_array_equal(d, [0.0, 0.0])
    np.testing.assert_array_equal(psi, [0.0, 0.0])
    np.testing.assert_array_equal(v, [30.0, 12.5])
    np.testing.assert_array_equal(acc, [0.0, 0.0])
    s, _, _, v, _ = _straight(0.0, 30.0, 0.0, n_steps=100)
    assert s[0] == pytest.approx(300.0, abs=1e-9)
    assert v[0] == 30.0


def test_bicycle_constant_acceleration() -> None:
    v0, a = 20.0, 2.0
    for n_steps in (1, 10, 50):
        t = n_steps * DT
        s, _, _, v, acc = _straight(0.0, v0, a, n_steps)
        assert v[0] == pytest.approx(v0 + a * t, abs=1e-9)
        assert s[0] == pytest.approx(v0 * t + 0.5 * a * t * t, abs=1e-9)  # x = v t + a t^2 / 2
        assert acc[0] == pytest.approx(a, abs=1e-9)
    # braking without reaching 0: 30 m/s, -4 m/s^2 for 2 s
    s, _, _, v, _ = _straight(0.0, 30.0, -4.0, 20)
    assert v[0] == pytest.approx(22.0, abs=1e-9)
    assert s[0] == pytest.approx(30.0 * 2.0 - 0.5 * 4.0 * 4.0, abs=1e-9)


def test_bicycle_speed_clipped_at_zero() -> None:
    # 1 m/s, full brake -8: step 1 -> 0.2 m/s (s += 0.1 * (1 + 0.2) / 2 = 0.06),
    # step 2 -> clipped at 0 (s += 0.1 * 0.2 / 2 = 0.01, realised accel -2), then standstill
    s, d, psi, v, acc = bicycle_step(*(np.array([x]) for x in (0.0, 0.0, 0.0, 1.0, -8.0, 0.0, 0.0)), P, DT)
    assert v[0] == pytest.approx(0.2) and s[0] == pytest.approx(0.06) and acc[0] == pytest.approx(-8.0)
    s, d, psi, v, acc = bicycle_step(s, d, psi, v, np.array([-8.0]), np.zeros(1), np.zeros(1), P, DT)
    assert v[0] == 0.0
    assert s[0] == pytest.approx(0.07)
    assert acc[0] == pytest.approx(-2.0)
    for _ in range(10):
        s, d, psi, v, acc = bicycle_step(s, d, psi, v, np.array([-8.0]), np.zeros(1), np.zeros(1), P, DT)
        assert v[0] == 0.0 and acc[0] == 0.0
    assert s[0] == pytest.approx(0.07)  # never rolls backwards


def test_bicycle_speed_clipped_at_max() -> None:
    s, _, _, v, acc = _straight(0.0, 39.9, 3.0)
    assert v[0] == 40.0
    assert acc[0] == pytest.approx(1.0)  # (40 - 39.9) / 0.1
    assert s[0] == pytest.approx(0.5 * (39.9 + 40.0) * DT)
    s, _, _, v, acc = _straight(0.0, 40.0, 3.0, n_steps=10)
    assert v[0] == 40.0 and acc[0] == 0.0
    assert s[0] == pytest.approx(40.0, abs=1e-9)


def test_bicycle_heading_and_lateral_motion() -> None:
    # psi = 0.1 rad, no steering, straight road: dd = v sin(psi) dt, ds = v cos(psi) dt
    s, d, psi, v, _ = bicycle_step(np.zeros(1), np.zeros(1), np.array([0.1]), np.array([20.0]),
                                   np.zeros(1), np.zeros(1), np.zeros(1), P, DT)
    assert s[0] == pytest.approx(2.0 * np.cos(0.1))
    assert d[0] == pytest.approx(2.0 * np.sin(0.1))
    assert psi[0] == pytest.approx(0.1)
    # steering on a straight road: beta = atan(tan(delta) / 2), dpsi = v cos(beta) tan(delta) / L dt
    delta = 0.05
    beta = np.arctan(0.5 * np.tan(delta))
    s, d, psi, v, _ = bicycle_step(np.zeros(1), np.zeros(1), np.zeros(1), np.array([20.0]),
                                   np.zeros(1), np.array([delta]), np.zeros(1), P, DT)
    assert d[0] == pytest.approx(2.0 * np.sin(beta))
    assert psi[0] == pytest.approx(20.0 * np.cos(beta) * np.tan(delta) / 2.9 * DT)


# ---------------------------------------------------------------- dual PID
def test_pid_on_centre_gives_curvature_feedforward() -> None:
    ctl = DualPidController(2, ControlParams(), wheelbase_m=2.9, dt_s=DT)
    kappa = np.array([0.0, 1.0 / 2000.0])
    steer = ctl.steering(np.zeros(2), np.zeros(2), np.array([30.0, 30.0]), np.zeros(2), kappa)
    # on the centre line with zero heading error: delta = atan(L kappa)
    np.testing.assert_allclose(steer, [0.0, np.arctan(2.9 / 2000.0)], atol=1e-15)


def test_pid_lateral_speed_saturation() -> None:
    ctl = DualPidController(1, ControlParams(), wheelbase_m=2.9, dt_s=DT)
    # far from the target: w saturates at 0.6 m/s -> psi_ref = asin(0.6 / 30) = asin(0.02),
    # r = 3 * psi_ref, delta = atan(2.9 * r / 30)
    steer = ctl.steering(np.zeros(1), np.zeros(1), np.array([30.0]), np.array([3.5]), np.zeros(1))
    assert steer[0] == pytest.approx(np.arctan(2.9 * 3.0 * np.arcsin(0.02) / 30.0))
    # small error, not saturated: w = 0.8 * 0.5 = 0.4
    steer = ctl.steering(np.zeros(1), np.zeros(1), np.array([20.0]), np.array([-0.5]), np.zeros(1))
    assert steer[0] == pytest.approx(np.arctan(2.9 * 3.0 * np.arcsin(-0.4 / 20.0) / 20.0))


# ---------------------------------------------------------------- world: lane keeping
def test_straight_lane_keeping_exact(road: RoadModel) -> None:
    w = make_world(road, [100.0], [2], [30.0])
    assert w.d[0] == pytest.approx(CENTRE[2])
    for k in range(1, 51):
        w.step(*keep())
        assert w.s[0] == pytest.approx(100.0 + 3.0 * k, abs=1e-9)
        assert w.d[0] == pytest.approx(CENTRE[2], abs=1e-12)
        assert w.v[0] == 30.0


def test_world_constant_acceleration(road: RoadModel) -> None:
    w = make_world(road, [100.0], [3], [20.0])
    for _ in range(30):  # throttle 0.5 -> 1.5 m/s^2 for 3 s
        w.step(np.array([0.5]), np.zeros(1, dtype=np.int64))
    assert w.v[0] == pytest.approx(20.0 + 1.5 * 3.0, abs=1e-9)
    assert w.s[0] == pytest.approx(100.0 + 20.0 * 3.0 + 0.5 * 1.5 * 9.0, abs=1e-9)
    assert w.accel[0] == pytest.approx(1.5)
    assert w.time_s == pytest.approx(3.0)


@pytest.mark.parametrize("lane", [1, 2, 3, 4])
def test_lane_keeping_on_arc(road: RoadModel, lane: int) -> None:
    """s in [1000, 1600] is an arc of radius 2000 m: the feed-forward keeps the lane (< 5 cm)."""
    assert road.curvature(1300.0) == pytest.approx(1.0 / 2000.0)
    assert road.curvature(999.0) == 0.0 and road.curvature(1601.0) == 0.0
    w = make_world(road, [950.0], [lane], [30.0])
    worst = 0.0
    on_arc_steps = 0
    while w.s[0] < 1650.0:
        w.step(*keep())
        if 1000.0 <= w.s[0] <= 1600.0:
            on_arc_steps += 1
            worst = max(worst, abs(w.d[0] - CENTRE[lane]))
        assert w.lane[0] == lane
    assert on_arc_steps >= 190  # 600 m at 30 m/s = 20 s
    assert worst < 0.05


# ---------------------------------------------------------------- world: lane changes
def _run_lane_change(road: RoadModel, lane: int, direction: int, pre_steps: int = 7, total_steps: int = 200):
    w = make_world(road, [200.0], [lane], [30.0])
    for _ in range(pre_steps):
        w.step(*keep())
    t_decision = w.time_s
    thr = np.zeros(1)
    res = w.step(thr, np.array([direction]))
    history = [(res, w.d[0], w.lane[0], int(road.lane_of(w.s[0], w.d[0])))]
    assert res.executed_lane_change[0] == direction
    assert w.target_lane[0] == lane + direction
    assert w.lane_change[0] == direction
    for _ in range(total_steps - 1):
        res = w.step(*keep())
        history.append((res, w.d[0], w.lane[0], int(road.lane_of(w.s[0], w.d[0]))))
    return w, t_decision, history


@pytest.mark.parametrize("lane,direction,border", [(2, +1, BORDER_2_3), (3, -1, BORDER_2_3), (2, -1, BORDER_1_2)])
def test_lane_change_at_30mps(road: RoadModel, lane: int, direction: int, border: float) -> None:
    target = lane + direction
    w, t_decision, history = _run_lane_change(road, lane, direction)
    completed = [(res.step, c) for res, *_ in history for c in res.lane_changes_completed]
    assert len(completed) == 1
    step, (veh, lane_from, lane_to, duration) = completed[0]
    assert (veh, lane_from, lane_to) == (0, lane, target)
    # the centre of mass crosses the border (to the left: d > border; to the right: d <= border,
    # the border belongs to the lane on its right)
    crossed = [res.step for res, d, *_ in history if (d > border if direction > 0 else d <= border)]
    first_cross = crossed[0]
    assert step == first_cross
    assert duration == pytest.approx(first_cross * DT - t_decision, abs=1e-9)
    assert 3.0 <= duration <= 6.0
    # lanes reported by the world: old lane before the crossing, new lane from it on
    for res, _d, lane_now, lane_of in history:
        assert lane_of >= 0  # never off the road
        assert lane_now == (target if res.step >= first_cross else lane)
        assert lane_of == lane_now
        assert not res.off_road
    assert w.lane_change_count[0] == 1
    assert w.last_lane_change_duration_s[0] == pytest.approx(duration)
    assert w.lane_change[0] == 0 and w.target_lane[0] == target
    # overshoot past the target centre line < half a lane; settles on it
    ds = np.array([d for _, d, *_ in history])
    overshoot = direction * (ds - CENTRE[target])
    assert overshoot.max() < 1.75
    assert abs(ds[-1] - CENTRE[target]) < 0.05
    assert np.all(np.abs(ds[-50:] - CENTRE[target]) < 0.05)


def test_lane_change_request_into_missing_lane(road: RoadModel) -> None:
    # lane 4 is the leftmost: +1 does not exist; at s = 300 the merge lane (0) does not exist
    w = make_world(road, [300.0, 300.0, 650.0], [4, 1, 1], [30.0, 30.0, 25.0])
    res = w.step(np.zeros(3), np.array([1, -1, -1]))
    np.testing.assert_array_equal(res.executed_lane_change, [0, 0, -1])  # 650: lane 0 exists
    np.testing.assert_array_equal(w.target_lane, [4, 1, 0])
    np.testing.assert_array_equal(w.lane_change, [0, 0, -1])
    for _ in range(80):
        res = w.step(np.zeros(3), np.array([1, -1, 0]))
        assert res.executed_lane_change[0] == 0 and res.executed_lane_change[1] == 0
    np.testing.assert_array_equal(w.lane[:2], [4, 1])
    np.testing.assert_array_equal(w.lane_change_count, [0, 0, 1])
    np.testing.assert_allclose(w.d[:2], [CENTRE[4], CENTRE[1]], atol=1e-12)


def test_lane_change_request_ignored_while_changing(road: RoadModel) -> None:
    w = make_world(road, [200.0], [2], [30.0])
    res = w.step(np.zeros(1), np.array([1]))
    assert res.executed_lane_change[0] == 1
    for _ in range(5):  # both directions ignored while the change is in progress
        for req in (1, -1):
            res = w.step(np.zeros(1), np.array([req]))
            assert res.executed_lane_change[0] == 0
            assert w.target_lane[0] == 3 and w.lane_change[0] == 1
    while w.lane_change[0] != 0:
        res = w.step(*keep())
        assert res.step < 100
    assert w.lane[0] == 3 and w.lane_change_count[0] == 1
    # once complete, a new request is executed
    res = w.step(np.zeros(1), np.array([1]))
    assert res.executed_lane_change[0] == 1 and w.target_lane[0] == 4


def test_time_is_step_times_dt(road: RoadModel) -> None:
    w = make_world(road, [100.0], [2], [30.0])
    for _ in range(1000):
        res = w.step(*keep())
    assert res.step == 1000 and w.step_index == 1000
    assert res.time_s == 1000 * DT
    assert w.time_ns == 1000 * 100_000_000


def test_lane_change_into_ending_lane_is_not_left_pending(road: RoadModel) -> None:
    w = make_world(road, [950.0], [1], [30.0])
    res = w.step(np.zeros(1), np.array([-1]))
    assert res.executed_lane_change[0] == -1  # lane 0 exists at s = 950
    aborted = []
    for _ in range(60):  # 180 m: well past the end of the merge lane
        aborted += [(r, w.s[0]) for r in w.step(*keep()).lane_changes_aborted]
    # reported once, as (vehicle, from lane, target lane), when lane 0 ends at s = 960
    assert [r for r, _ in aborted] == [(0, 1, 0)]
    assert 960.0 <= aborted[0][1] < 960.0 + 30.0 * 0.1 + 1e-9
    assert w.s[0] > 1100.0 and w.lane[0] == 1
    # the impossible change is over: the vehicle is back on its lane and can act again
    assert w.lane_change[0] == 0 and w.target_lane[0] == 1
    assert abs(w.d[0] - CENTRE[1]) < 0.05
    res = w.step(np.zeros(1), np.array([1]))
    assert res.executed_lane_change[0] == 1


def test_heading_reference_is_capped_at_low_speed_only() -> None:
    """psi_ref = asin(w / v) capped at max_heading_ref_rad (evoscen_sim.physics.control): by hand, one step, P gains only."""
    import math

    p = ControlParams()  # kp_d 0.8, kp_psi 3.0, w cap 0.6 m/s, heading cap 0.2 rad
    L = 2.9
    # 2 m off the target line -> w = min(0.8 * 2, 0.6) = 0.6 m/s
    for v, psi_ref in ((1.0, 0.2),                       # asin(0.6) = 0.6435 > 0.2: capped
                       (2.0, 0.2),                       # asin(0.3) = 0.3047: capped
                       (30.0, math.asin(0.6 / 30.0))):   # 0.0200: unchanged
        c = DualPidController(1, p, L, 0.1)
        steer = c.steering(np.array([0.0]), np.array([0.0]), np.array([v]), np.array([2.0]), np.array([0.0]))
        assert steer[0] == pytest.approx(math.atan(L * (3.0 * psi_ref / v)), rel=1e-12)
