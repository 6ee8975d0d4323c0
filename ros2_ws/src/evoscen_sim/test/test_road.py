"""RoadModel on the shipped onramp.xodr; expectations derived by hand from the map's numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_sim.road.road_model import DEFAULT_MAP_PATH, RoadModel, load_road

W = 3.5  # lane width
R = 2000.0  # arc radius (curvature 0.0005)
L = 2393.76


@pytest.fixture(scope="module")
def road() -> RoadModel:
    return load_road(DEFAULT_MAP_PATH)


def test_basic_attributes(road: RoadModel) -> None:
    assert DEFAULT_MAP_PATH.name == "onramp.xodr"
    assert road.length_m == pytest.approx(L, abs=1e-12)
    assert road.num_lanes == 5
    assert road.lane_width_m == pytest.approx(W)
    assert list(road.lane_ids) == [-5, -4, -3, -2, -1]
    np.testing.assert_allclose(road.lane_start_s, [600, 0, 0, 0, 0])
    np.testing.assert_allclose(road.lane_end_s, [960, L, L, L, L])
    np.testing.assert_allclose(road.lane_full_width_end_s, [900, L, L, L, L])


def test_lane_centres_at_700(road: RoadModel) -> None:
    # reference line = left edge; lane index i has id i-5, i.e. (4-i) lanes of 3.5 m to its left
    assert road.lane_center_d(4, 700) == pytest.approx(-1.75)
    assert road.lane_center_d(1, 700) == pytest.approx(-12.25)
    assert road.lane_center_d(0, 700) == pytest.approx(-15.75)
    np.testing.assert_allclose(road.lane_center_d(np.arange(5), 700.0), [-15.75, -12.25, -8.75, -5.25, -1.75])
    r, l = road.lane_bounds_d(2, 700)
    assert (float(r), float(l)) == pytest.approx((-10.5, -7.0))


def test_lane_existence(road: RoadModel) -> None:
    assert not road.lane_exists(0, 500)
    assert road.lane_exists(0, 650)
    assert not road.lane_exists(0, 1000)
    assert road.lane_exists(0, 600)  # start inclusive
    assert road.lane_exists(0, 959.9)
    assert not road.lane_exists(0, 960)  # end exclusive
    assert road.lane_exists(4, 0) and road.lane_exists(4, L)  # lane reaching the road end
    assert road.lane_exists(4, -3.0)  # clamped to s = 0
    assert not road.lane_exists(0, -3.0)
    np.testing.assert_array_equal(road.lane_exists([-1, 5, 7], 700), [False, False, False])
    # broadcasting lane x s
    ex = road.lane_exists(np.arange(5)[:, None], np.array([500.0, 700.0])[None, :])
    assert ex.shape == (5, 2)
    np.testing.assert_array_equal(ex[:, 0], [False, True, True, True, True])
    assert ex[:, 1].all()


def test_taper_width_and_centre(road: RoadModel) -> None:
    c, d = -3 * W / 60**2, 2 * W / 60**3
    ds = 930.0 - 900.0
    w_hand = W + c * ds**2 + d * ds**3  # = 3.5 - 2.625 + 0.875 = 1.75
    assert w_hand == pytest.approx(1.75)
    assert road.lane_width(0, 930) == pytest.approx(w_hand, abs=1e-12)
    ds = 915.0 - 900.0
    assert road.lane_width(0, 915) == pytest.approx(W + c * ds**2 + d * ds**3, abs=1e-12)
    assert road.lane_width(0, 900) == pytest.approx(W)
    assert road.lane_width(0, 959.999) == pytest.approx(0.0, abs=1e-6)
    assert road.lane_width(0, 500) == 0.0 and road.lane_width(0, 1000) == 0.0
    assert road.lane_width(9, 700) == 0.0
    # centre of the taper moves with the width: right border of lane II is -14
    assert road.lane_center_d(0, 930) == pytest.approx(-14 - 1.75 / 2)
    r_edge, l_edge = road.road_edges_d(np.array([500.0, 700.0, 930.0]))
    np.testing.assert_allclose(r_edge, [-14.0, -17.5, -15.75])
    np.testing.assert_allclose(l_edge, 0.0)


def test_lane_of(road: RoadModel) -> None:
    s = 700.0
    assert road.lane_of(s, -1.0) == 4
    assert road.lane_of(s, 0.0) == 4  # left road edge is on the road
    assert road.lane_of(s, 0.01) == -1
    assert road.lane_of(s, -3.5) == 3  # a line between lanes belongs to the lane on its right
    assert road.lane_of(s, -3.49) == 4
    assert road.lane_of(s, -14.0) == 0
    assert road.lane_of(s, -17.5) == 0  # right road edge is on the road
    assert road.lane_of(s, -17.51) == -1
    assert road.lane_of(500.0, -14.0) == 1  # no lane I here: -14 is the right road edge
    assert road.lane_of(500.0, -15.0) == -1
    got = road.lane_of(np.array([700.0, 700.0, 930.0, 930.0]), np.array([-16.0, -9.0, -15.7, -15.8]))
    np.testing.assert_array_equal(got, [0, 2, 0, -1])  # taper right edge at 930: -15.75


def test_distance_to_lane_end(road: RoadModel) -> None:
    np.testing.assert_allclose(road.distance_to_lane_end(0, [700.0, 950.0, 1000.0]), [260.0, 10.0, -40.0])
    assert np.isinf(road.distance_to_lane_end(1, 700.0))
    assert np.all(np.isinf(road.distance_to_lane_end(np.arange(1, 5), 2000.0)))
    assert np.isnan(road.distance_to_lane_end(-1, 700.0))


def test_frenet_to_cartesian_on_first_line(road: RoadModel) -> None:
    x, y, h = road.frenet_to_cartesian(np.array([0.0, 250.0, 999.0]), np.array([-3.0, -10.0, 2.0]))
    np.testing.assert_allclose(x, [0.0, 250.0, 999.0], atol=1e-12)
    np.testing.assert_allclose(y, [-3.0, -10.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(h, 0.0, atol=1e-15)


def test_frenet_to_cartesian_on_arc(road: RoadModel) -> None:
    # arc starts at (1000, 0) heading 0, centre (1000, 2000); after 100 m the angle is 100/2000
    phi = 100.0 / R
    for d in (0.0, -5.25, 3.0):
        x, y, h = road.frenet_to_cartesian(1100.0, d)
        assert float(x) == pytest.approx(1000.0 + (R - d) * math.sin(phi), abs=1e-9)
        assert float(y) == pytest.approx(R - (R - d) * math.cos(phi), abs=1e-9)
        assert float(h) == pytest.approx(phi, abs=1e-15)
    assert road.curvature(1100.0) == pytest.approx(0.0005)
    assert road.curvature(500.0) == 0.0 and road.curvature(2000.0) == 0.0


def test_frenet_to_cartesian_after_arc(road: RoadModel) -> None:
    x_end, y_end = 1000.0 + R * math.sin(0.3), R * (1.0 - math.cos(0.3))
    x, y, h = road.frenet_to_cartesian(2000.0, -7.0)
    assert float(h) == pytest.approx(0.3, abs=1e-12)
    assert float(x) == pytest.approx(x_end + 400.0 * math.cos(0.3) + 7.0 * math.sin(0.3), abs=1e-9)
    assert float(y) == pytest.approx(y_end + 400.0 * math.sin(0.3) - 7.0 * math.cos(0.3), abs=1e-9)
    assert road.heading(2393.76) == pytest.approx(0.3)
    assert road.heading(1600.0) == pytest.approx(0.3)
    assert road.heading(1300.0) == pytest.approx(0.15)


def test_round_trip_all_pieces(road: RoadModel) -> None:
    rng = np.random.default_rng(42)
    for lo, hi in ((0.0, 1000.0), (1000.0, 1600.0), (1600.0, L)):
        s = rng.uniform(lo, hi, 500)
        d = rng.uniform(-50.0, 50.0, 500)
        x, y, _ = road.frenet_to_cartesian(s, d)
        s2, d2 = road.cartesian_to_frenet(x, y)
        np.testing.assert_allclose(s2, s, rtol=0, atol=1e-9)
        np.testing.assert_allclose(d2, d, rtol=0, atol=1e-9)
    # piece junctions and beyond the ends (extended end pieces)
    s = np.array([0.0, 1000.0, 1600.0, L, -20.0, L + 30.0])
    d = np.array([-1.0, -17.0, 10.0, -3.0, -5.0, -2.0])
    s2, d2 = road.cartesian_to_frenet(*road.frenet_to_cartesian(s, d)[:2])
    np.testing.assert_allclose(s2, s, atol=1e-9)
    np.testing.assert_allclose(d2, d, atol=1e-9)


def test_cartesian_to_frenet_by_hand(road: RoadModel) -> None:
    s, d = road.cartesian_to_frenet(500.0, -12.0)
    assert (float(s), float(d)) == pytest.approx((500.0, -12.0))
    # the arc centre direction: point at angle phi seen from the centre (1000, 2000), radius R + 10
    phi = 0.1
    s, d = road.cartesian_to_frenet(1000.0 + (R + 10) * math.sin(phi), R - (R + 10) * math.cos(phi))
    assert float(s) == pytest.approx(1000.0 + R * phi, abs=1e-9)
    assert float(d) == pytest.approx(-10.0, abs=1e-9)


def test_speed_limits(road: RoadModel) -> None:
    np.testing.assert_allclose(road.speed_limit_max_mps(np.arange(1, 5), 300.0), 120 / 3.6)
    np.testing.assert_allclose(road.speed_limit_min_mps(np.arange(1, 5), 300.0), 90 / 3.6)
    assert road.speed_limit_max_mps(4, 2000.0) == pytest.approx(33.333, abs=1e-3)
    assert road.speed_limit_min_mps(4, 2000.0) == pytest.approx(25.0)
    assert road.speed_limit_max_mps(0, 700.0) == pytest.approx(33.333, abs=1e-3)
    assert road.speed_limit_min_mps(0, 700.0) == 0.0  # merge lane: no minimum
    assert np.isnan(road.speed_limit_max_mps(0, 300.0))  # lane I does not exist there
    assert np.isnan(road.speed_limit_min_mps(5, 300.0))


def test_shapes_and_scalars(road: RoadModel) -> None:
    assert np.ndim(road.lane_width(1, 10.0)) == 0
    s = np.linspace(0, L, 21).reshape(3, 7)
    assert road.lane_center_d(2, s).shape == (3, 7)
    assert road.lane_of(s, -5.0).shape == (3, 7)
    assert road.frenet_to_cartesian(s, 0.0)[0].shape == (3, 7)
    assert road.cartesian_to_frenet(s, 0.0)[0].shape == (3, 7)
    with pytest.raises(ValueError):
        road.lane_width(1.5, 10.0)


def test_lane_markings(road: RoadModel) -> None:
    marks = road.lane_markings()
    kinds = {m.kind for m in marks}
    assert kinds == {"edge_left", "edge_right", "lane_line"}
    for m in marks:
        assert m.s_m.shape == m.d_m.shape == m.x_m.shape == m.y_m.shape
        assert np.all(np.diff(m.s_m) <= 5.0 + 1e-9)
        assert m.color == "white" and m.width_m == pytest.approx(0.15)
    # the merge-lane edge on [600, 900) is solid at d = -17.5
    lane_i = [m for m in marks if m.lane_id == -5 and m.s_m[0] == 600.0]
    assert len(lane_i) == 1 and lane_i[0].type == "solid" and lane_i[0].kind == "edge_right"
    np.testing.assert_allclose(lane_i[0].d_m, -17.5)
    # between lanes II and I the line is broken; before the ramp lane II's edge is solid at -14
    ii = {m.s_m[0]: m for m in marks if m.lane_id == -4}
    assert ii[600.0].type == "broken" and ii[600.0].kind == "lane_line"
    assert ii[0.0].type == "solid" and ii[0.0].kind == "edge_right"
    # taper edge ends on lane II's border
    taper = [m for m in marks if m.lane_id == -5 and m.s_m[0] == 900.0][0]
    assert taper.d_m[0] == pytest.approx(-17.5) and taper.d_m[-1] == pytest.approx(-14.0, abs=1e-6)
    x, y, _ = road.frenet_to_cartesian(taper.s_m, taper.d_m)
    np.testing.assert_allclose(taper.x_m, x) and np.testing.assert_allclose(taper.y_m, y)


def test_model_is_read_only(road: RoadModel) -> None:
    with pytest.raises(ValueError):
        road.lane_end_s[0] = 1.0


def test_compiled_queries_match_the_model(road: RoadModel) -> None:
    # evoscen_sim.road.road_kernels computes, for one (lane, s), exactly what RoadModel's methods compute
    from evoscen_sim.road.road_kernels import lane_center_d, lane_end_distance, segment_index

    tables = road.kernel_tables()
    rng = np.random.default_rng(5)
    s = np.concatenate([rng.uniform(-20.0, L + 20.0, 300), [0.0, 600.0, 900.0, 930.0, 960.0, L]])
    lane = np.concatenate([rng.integers(-1, road.num_lanes + 1, 300), [0, 0, 0, 0, 0, 4]])
    for k in range(s.size):
        li, sk = int(lane[k]), float(s[k])
        assert bool(road.lane_exists(li, sk)) == (0 <= li < road.num_lanes
                                                  and bool(tables.present[segment_index(tables, sk), li]))
        expected_end = float(road.distance_to_lane_end(li, sk))
        assert lane_end_distance(tables, li, sk) == (math.inf if math.isnan(expected_end) else expected_end)
        np.testing.assert_array_equal(lane_center_d(tables, li, sk), road.lane_center_d(li, sk))
    assert tables.length_m == road.length_m and all(not a.flags.writeable for a in tables if hasattr(a, "flags"))
