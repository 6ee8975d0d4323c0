"""Collision detection: oriented-box overlap (hand geometry, a polygon-clipping reference) and
the world's collision reports (first overlapping step, once per contact)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_sim.physics.collision import boxes_overlap, overlapping_pairs
from evoscen_sim.loop.hand_built import hand_built_world
from evoscen_sim.physics.world import World
from evoscen_sim.road.road_model import RoadModel, load_road

DT = 0.1
L, W = 4.8, 1.9


@pytest.fixture(scope="module")
def road() -> RoadModel:
    return load_road()


def make_world(road: RoadModel, s, lane, speed) -> World:
    return hand_built_world(road, s, lane, speed, dt_s=DT)


def overlap1(b1, b2) -> bool:
    """boxes_overlap for one pair of boxes given as (s, d, psi, length, width)."""
    args = [np.array([x], dtype=float) for x in (*b1, *b2)]
    return bool(boxes_overlap(*args)[0])


# ---------------------------------------------------------------- boxes_overlap, by hand
def test_axis_aligned_boxes() -> None:
    # lengths 4 (binary exact): centres 4 m apart touch -> no collision; 3.75 m apart overlap
    assert not overlap1((0.0, 0.0, 0.0, 4.0, 2.0), (4.0, 0.0, 0.0, 4.0, 2.0))
    assert overlap1((0.0, 0.0, 0.0, 4.0, 2.0), (3.75, 0.0, 0.0, 4.0, 2.0))
    assert not overlap1((0.0, 0.0, 0.0, 4.0, 2.0), (4.25, 0.0, 0.0, 4.0, 2.0))
    # side by side: widths 2, centres 2 m apart touch; 1.5 m apart overlap
    assert not overlap1((0.0, 0.0, 0.0, 4.0, 2.0), (0.0, 2.0, 0.0, 4.0, 2.0))
    assert overlap1((0.0, 0.0, 0.0, 4.0, 2.0), (0.0, -1.5, 0.0, 4.0, 2.0))
    # two lanes' centres (3.5 m) with 1.9 m wide cars: no contact even when level
    assert not overlap1((100.0, -8.75, 0.0, L, W), (100.0, -5.25, 0.0, L, W))
    # corner to corner: s overlaps, d overlaps -> overlap; identical boxes overlap
    assert overlap1((0.0, 0.0, 0.0, 4.0, 2.0), (3.5, 1.5, 0.0, 4.0, 2.0))
    assert overlap1((5.0, 1.0, 0.3, L, W), (5.0, 1.0, 0.3, L, W))


def test_rotated_box_aabb_overlap_only() -> None:
    """Box A rotated by psi = 0.5 points up-right; the lower-right corner of its axis-aligned
    extent is empty. A small box B placed there overlaps A's AABB but not A."""
    psi = 0.5
    c, sn = math.cos(psi), math.sin(psi)
    half_s = 0.5 * (L * c + W * sn)  # 2.5616...
    half_d = 0.5 * (L * sn + W * c)  # 1.9843...
    b = (2.3, -1.7, 0.0, 0.4, 0.4)
    # B overlaps A's AABB (|Δs| < half_s + 0.2, |Δd| < half_d + 0.2) ...
    assert abs(b[0]) < half_s + 0.2 and abs(b[1]) < half_d + 0.2
    # ... but on A's width axis (-sin psi, cos psi) B's centre is 2.59 m away while the half
    # extents only add up to 0.95 + 0.2 (|sin psi| + |cos psi|) = 1.22 m: a separating axis
    dist = abs(-sn * b[0] + c * b[1])
    assert dist > 0.5 * W + 0.2 * (abs(sn) + abs(c))
    a = (0.0, 0.0, psi, L, W)
    assert not overlap1(a, b)
    assert not overlap1(b, a)
    # the whole pipeline (broad phase passes it to the exact test) reports no pair
    pairs = overlapping_pairs(np.array([0.0, 2.3]), np.array([0.0, -1.7]), np.array([psi, 0.0]),
                              np.array([L, 0.4]), np.array([W, 0.4]))
    assert pairs.shape == (0, 2)
    # moved onto A's long axis at the same distance from its centre, B does overlap
    r = math.hypot(2.3, 1.7) * 0.5
    assert overlap1(a, (r * c, r * sn, 0.0, 0.4, 0.4))


def test_rotated_box_real_overlap_and_quarter_turn() -> None:
    # a box turned by 90 degrees: its length runs along d; 4 x 2 box at psi = pi/2 spans
    # s in [-1, 1], d in [-2, 2]; a 4 x 2 axis-aligned box at s = 2.9 spans s in [0.9, 4.9]
    a = (0.0, 0.0, math.pi / 2, 4.0, 2.0)
    assert overlap1(a, (2.9, 0.0, 0.0, 4.0, 2.0))
    assert not overlap1(a, (3.1, 0.0, 0.0, 4.0, 2.0))
    assert overlap1(a, (0.0, 2.9, 0.0, 4.0, 2.0))  # d overlap [1.9, 3.9] vs [-2, 2]
    assert not overlap1(a, (0.0, 3.1, 0.0, 4.0, 2.0))


def _corners(s, d, psi, length, width) -> np.ndarray:
    c, sn = math.cos(psi), math.sin(psi)
    u, v = np.array([c, sn]), np.array([-sn, c])
    centre = np.array([s, d])
    return np.array([centre + 0.5 * (i * length * u + j * width * v) for i, j in ((1, 1), (-1, 1), (-1, -1), (1, -1))])


def _clip_area(p: np.ndarray, q: np.ndarray) -> float:
    """Area of the intersection of two convex polygons (counter-clockwise), Sutherland-Hodgman."""
    out = list(p)
    for k in range(len(q)):
        a, b = q[k], q[(k + 1) % len(q)]
        inp, out = out, []
        if not inp:
            break

        def side(x):
            return (b[0] - a[0]) * (x[1] - a[1]) - (b[1] - a[1]) * (x[0] - a[0])  # noqa: B023 (called within the iteration)

        for m in range(len(inp)):
            cur, prev = inp[m], inp[m - 1]
            sc, sp = side(cur), side(prev)
            if sc >= 0:
                if sp < 0:
                    out.append(prev + (cur - prev) * sp / (sp - sc))
                out.append(cur)
            elif sp >= 0:
                out.append(prev + (cur - prev) * sp / (sp - sc))
    if len(out) < 3:
        return 0.0
    x, y = np.array(out).T
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _point_segment(pt, a, b) -> float:
    ab = b - a
    t = np.clip(np.dot(pt - a, ab) / np.dot(ab, ab), 0.0, 1.0)
    return float(np.linalg.norm(pt - (a + t * ab)))


def _poly_distance(p, q) -> float:
    return min(
        min(_point_segment(x, poly[k], poly[(k + 1) % 4]) for x in other for k in range(4))
        for poly, other in ((p, q), (q, p))
    )


def test_boxes_overlap_against_polygon_clipping() -> None:
    rng = np.random.default_rng(7)
    n = 600
    s1, d1, s2, d2 = (rng.uniform(-4.0, 4.0, n) for _ in range(4))
    psi1, psi2 = rng.uniform(-math.pi, math.pi, n), rng.uniform(-math.pi, math.pi, n)
    l1, l2 = rng.uniform(1.0, 6.0, n), rng.uniform(1.0, 6.0, n)
    w1, w2 = rng.uniform(0.5, 2.5, n), rng.uniform(0.5, 2.5, n)
    got = boxes_overlap(s1, d1, psi1, l1, w1, s2, d2, psi2, l2, w2)
    checked_hit = checked_miss = 0
    for k in range(n):
        p = _corners(s1[k], d1[k], psi1[k], l1[k], w1[k])
        q = _corners(s2[k], d2[k], psi2[k], l2[k], w2[k])
        area = _clip_area(p, q)
        if area > 1e-6:
            assert got[k], k
            checked_hit += 1
        elif area == 0.0 and _poly_distance(p, q) > 1e-6:
            assert not got[k], k
            checked_miss += 1
    assert checked_hit > 100 and checked_miss > 100
    # symmetric in the order of the boxes
    np.testing.assert_array_equal(got, boxes_overlap(s2, d2, psi2, l2, w2, s1, d1, psi1, l1, w1))


def test_overlapping_pairs_sorted_and_complete() -> None:
    # 0-1 overlap longitudinally, 2 alone, 3-4 overlap, 4-5 overlap (chain), 5-0 far apart
    s = np.array([0.0, 4.0, 50.0, 100.0, 103.0, 106.0])
    d = np.array([0.0, 0.5, 0.0, -5.0, -5.0, -5.0])
    z = np.zeros(6)
    pairs = overlapping_pairs(s, d, z, np.full(6, L), np.full(6, W))
    np.testing.assert_array_equal(pairs, [[0, 1], [3, 4], [4, 5]])
    # unordered input indices: pairs are (low, high), sorted
    perm = np.array([5, 3, 1, 4, 0, 2])
    pairs = overlapping_pairs(s[perm], d[perm], z, np.full(6, L), np.full(6, W))
    expected = sorted(tuple(sorted((int(np.flatnonzero(perm == i)[0]), int(np.flatnonzero(perm == j)[0]))))
                      for i, j in [(0, 1), (3, 4), (4, 5)])
    np.testing.assert_array_equal(pairs, expected)
    assert overlapping_pairs(np.array([0.0]), np.zeros(1), np.zeros(1), np.array([L]), np.array([W])).shape == (0, 2)


# ---------------------------------------------------------------- world reports
def test_rear_end_collision_reported_once_at_first_overlap(road: RoadModel) -> None:
    """Leader (0) stopped at s = 320, follower (1) at 300 with 30 m/s, same lane, no throttle.

    After k steps the follower is at 300 + 3k (exact: 3 m per step); the bodies (4.8 m) overlap
    strictly when |20 - 3k| < 4.8, i.e. k = 6, 7, 8 (k = 5 leaves a 0.2 m gap, k = 9 is 2.2 m
    past). The collision is reported at step 6 only.
    """
    w = make_world(road, [320.0, 300.0], [2, 2], [0.0, 30.0])
    steps_overlapping = [k for k in range(1, 20) if abs(20.0 - 3.0 * k) < L]
    assert steps_overlapping == [6, 7, 8]
    reports = []
    for _ in range(9):
        res = w.step(np.zeros(2), np.zeros(2, dtype=np.int64))
        assert w.s[1] == pytest.approx(300.0 + 3.0 * res.step)
        assert w.s[0] == 320.0 and w.v[0] == 0.0
        reports.extend((res.step, c) for c in res.collisions)
    assert reports == [(6, (0, 1))]

    # second contact of the same pair after separating: the follower (now 7 m ahead, at 327)
    # brakes fully (-8 m/s^2), the leader accelerates fully (+3 m/s^2) and runs into it.
    # Follower: 37 steps of -0.8 m/s (30 -> 0.4 m/s), then one step clipped at 0:
    stop = 327.0 + (30.0 * 3.7 - 0.5 * 8.0 * 3.7**2) + 0.5 * 0.4 * DT
    # Leader: s = 320 + 1.5 t^2 (never reaches 40 m/s here); first step with |Δs| < 4.8:
    k_hit = next(k for k in range(1, 200) if stop - (320.0 + 1.5 * (k * DT) ** 2) < L)
    reports = []
    for _ in range(k_hit + 20):
        res = w.step(np.array([1.0, -1.0]), np.zeros(2, dtype=np.int64))
        reports.extend((res.step, c) for c in res.collisions)
    assert w.v[1] == 0.0 and w.s[1] == pytest.approx(stop)
    assert reports == [(9 + k_hit, (0, 1))]


def test_side_by_side_adjacent_lanes_no_collision(road: RoadModel) -> None:
    w = make_world(road, [200.0, 200.0, 200.0, 200.0], [1, 2, 3, 4], [30.0] * 4)
    d0 = w.d.copy()
    np.testing.assert_allclose(np.diff(d0), [3.5, 3.5, 3.5])
    for _ in range(50):
        res = w.step(np.zeros(4), np.zeros(4, dtype=np.int64))
        assert res.collisions == []
    # nor while one of them changes lanes away from the others (lane 4 has no left neighbour)
    w = make_world(road, [200.0, 230.0], [2, 3], [30.0, 30.0])
    res = w.step(np.zeros(2), np.array([0, 1]))
    assert res.executed_lane_change[1] == 1
    for _ in range(100):
        assert w.step(np.zeros(2), np.zeros(2, dtype=np.int64)).collisions == []


def test_lane_change_into_a_level_vehicle_collides(road: RoadModel) -> None:
    """Vehicle 0 changes from lane 2 into lane 3 where vehicle 1 drives level with it: the
    bodies first overlap when the lateral distance of the centres drops below the width 1.9 m
    (both headings are small, so the boxes are nearly axis-aligned)."""
    w = make_world(road, [200.0, 200.0], [2, 3], [30.0, 30.0])
    res = w.step(np.zeros(2), np.array([1, 0]))
    reports = [(res.step, c) for c in res.collisions]
    gap = w.d[1] - w.d[0]
    early = late = None  # first steps with a lateral centre distance below 2.0 m / 1.8 m
    for _ in range(100):
        res = w.step(np.zeros(2), np.zeros(2, dtype=np.int64))
        gap = w.d[1] - w.d[0]
        assert abs(w.psi[0]) < 0.03  # so the rotated extent adds < 2.4 * 0.03 = 0.072 m
        if early is None and gap < W + 0.1:
            early = res.step
        if late is None and gap < W - 0.1:
            late = res.step
        reports.extend((res.step, c) for c in res.collisions)
    assert gap < 0.05  # both on the centre of lane 3 now
    assert len(reports) == 1 and reports[0][1] == (0, 1)
    assert early is not None and late is not None
    assert early <= reports[0][0] <= late
