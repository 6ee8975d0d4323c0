"""Neighbourhood queries: hand-placed vehicles, a brute-force O(N²) reference, TTC and THW.

Rules (neighbors.py docstring): column j = lane offset j - 2; in the own lane j is ahead of
i when s_j > s_i, or s_j == s_i and j > i; in another lane a vehicle exactly level with i
counts as behind. Gaps are bumper to bumper, |Δs| - (L_i + L_j) / 2. Missing: -1, inf, nan.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from evoscen_sim.physics.neighbors import (
    LANE_OFFSETS,
    LEFT,
    OWN,
    RIGHT,
    compute_neighborhood,
    time_headway,
    time_to_collision,
)

L = 4.8
INF = math.inf


def _nb(s, lane, v, a=None, length=None):
    s = np.asarray(s, dtype=float)
    n = s.size
    a = np.zeros(n) if a is None else np.asarray(a, dtype=float)
    length = np.full(n, L) if length is None else np.asarray(length, dtype=float)
    return compute_neighborhood(s, np.asarray(lane, dtype=np.int64), np.asarray(v, dtype=float), a, length)


def test_column_constants() -> None:
    np.testing.assert_array_equal(LANE_OFFSETS, [-2, -1, 0, 1, 2])
    assert (RIGHT, OWN, LEFT) == (1, 2, 3)


# vehicles: index: (s, lane, speed, accel)
HAND = [
    (100.0, 2, 30.0, 0.1),  # 0 ego
    (130.0, 2, 31.0, 0.2),  # 1 own leader of 0
    (80.0, 2, 29.0, 0.3),   # 2 own follower of 0
    (160.0, 2, 32.0, 0.4),  # 3 leader of 1
    (100.0, 3, 33.0, 0.5),  # 4 level with 0 in the left lane: behind 0 (follower)
    (120.0, 3, 34.0, 0.6),  # 5 left leader of 0
    (95.0, 1, 28.0, 0.7),   # 6 right follower of 0
    (200.0, 4, 35.0, 0.8),  # 7 two lanes left, ahead
]


@pytest.fixture(scope="module")
def hand():
    s, lane, v, a = (np.array(c) for c in zip(*HAND))
    return _nb(s, lane, v, a)


def _row(nb, i):
    return (list(nb.leader[i]), list(nb.follower[i]), list(nb.gap_front_m[i]), list(nb.gap_rear_m[i]))


def test_hand_placed_ego(hand) -> None:
    nb = hand
    # columns: offset -2 (lane 0), -1 (lane 1), 0 (lane 2), +1 (lane 3), +2 (lane 4)
    assert list(nb.leader[0]) == [-1, -1, 1, 5, 7]
    assert list(nb.follower[0]) == [-1, 6, 2, 4, -1]
    np.testing.assert_allclose(nb.gap_front_m[0], [INF, INF, 30 - L, 20 - L, 100 - L])
    np.testing.assert_allclose(nb.gap_rear_m[0], [INF, 5 - L, 20 - L, 0 - L, INF])
    np.testing.assert_allclose(nb.leader_speed_mps[0], [np.nan, np.nan, 31.0, 34.0, 35.0])
    np.testing.assert_allclose(nb.follower_speed_mps[0], [np.nan, 28.0, 29.0, 33.0, np.nan])
    np.testing.assert_allclose(nb.leader_accel_mps2[0], [np.nan, np.nan, 0.2, 0.6, 0.8])
    np.testing.assert_allclose(nb.follower_accel_mps2[0], [np.nan, 0.7, 0.3, 0.5, np.nan])
    assert nb.own_gap_m[0] == pytest.approx(25.2)
    assert nb.gap_rear_m[0, LEFT] == pytest.approx(-4.8)  # overlapping alongside: negative
    assert nb.gap_rear_m[0, RIGHT] == pytest.approx(0.2)


def test_hand_placed_others(hand) -> None:
    nb = hand
    # vehicle 4 (lane 3, s = 100): vehicle 0 is level in lane 2 -> behind (follower), gap -4.8
    assert list(nb.leader[4]) == [-1, 1, 5, 7, -1]
    assert list(nb.follower[4]) == [6, 0, -1, -1, -1]
    np.testing.assert_allclose(nb.gap_front_m[4], [INF, 30 - L, 20 - L, 100 - L, INF])
    np.testing.assert_allclose(nb.gap_rear_m[4], [5 - L, 0 - L, INF, INF, INF])
    # vehicle 3: front of lane 2, nobody ahead in any lane except lane 4 (s = 200)
    assert list(nb.leader[3]) == [-1, -1, -1, -1, 7]
    assert list(nb.follower[3]) == [-1, 6, 1, 5, -1]
    np.testing.assert_allclose(nb.gap_rear_m[3], [INF, 65 - L, 30 - L, 40 - L, INF])
    # vehicle 7 in the leftmost lane: offsets +1, +2 do not exist
    assert list(nb.leader[7]) == [-1, -1, -1, -1, -1]
    assert list(nb.follower[7]) == [3, 5, -1, -1, -1]
    assert np.isinf(nb.gap_front_m[7]).all()
    assert np.isnan(nb.leader_speed_mps[7]).all() and np.isnan(nb.leader_accel_mps2[7]).all()
    # vehicle 6 (lane 1): lane -1 does not exist
    assert list(nb.leader[6]) == [-1, -1, -1, 0, 4]
    assert list(nb.follower[6]) == [-1, -1, -1, 2, -1]
    np.testing.assert_allclose(nb.gap_front_m[6], [INF, INF, INF, 5 - L, 5 - L])
    np.testing.assert_allclose(nb.gap_rear_m[6], [INF, INF, INF, 15 - L, INF])


def test_same_s_in_own_lane_breaks_tie_by_index() -> None:
    nb = _nb([50.0, 50.0, 50.0], [1, 1, 1], [10.0, 11.0, 12.0])
    # order along the lane: 0, 1, 2
    assert list(nb.leader[:, OWN]) == [1, 2, -1]
    assert list(nb.follower[:, OWN]) == [-1, 0, 1]
    np.testing.assert_allclose(nb.gap_front_m[:, OWN], [-L, -L, INF])
    np.testing.assert_allclose(nb.leader_speed_mps[:, OWN], [11.0, 12.0, np.nan])


def test_different_lengths() -> None:
    nb = _nb([0.0, 20.0], [2, 3], [1.0, 2.0], length=[4.0, 12.0])
    assert nb.gap_front_m[0, LEFT] == pytest.approx(20.0 - 8.0)
    assert nb.gap_rear_m[1, RIGHT] == pytest.approx(20.0 - 8.0)


def test_single_vehicle_has_no_neighbours() -> None:
    nb = _nb([10.0], [2], [5.0])
    assert (nb.leader == -1).all() and (nb.follower == -1).all()
    assert np.isinf(nb.gap_front_m).all() and np.isinf(nb.gap_rear_m).all()
    assert np.isnan(nb.leader_speed_mps).all() and np.isnan(nb.follower_speed_mps).all()
    assert nb.leader.shape == (1, 5)


def _brute_force(s, lane, v, a, length):
    n = s.size
    out = {k: np.empty((n, 5)) for k in ("lead", "foll", "gf", "gr", "vl", "vf", "al", "af")}
    for i in range(n):
        for col, off in enumerate(range(-2, 3)):
            ahead, behind = [], []
            for j in range(n):
                if j == i or lane[j] != lane[i] + off:
                    continue
                if off == 0:
                    is_ahead = (s[j], j) > (s[i], i)
                else:
                    is_ahead = s[j] > s[i]
                (ahead if is_ahead else behind).append(j)
            lead = min(ahead, key=lambda j: (s[j], j)) if ahead else -1
            foll = max(behind, key=lambda j: (s[j], j)) if behind else -1
            out["lead"][i, col] = lead
            out["foll"][i, col] = foll
            out["gf"][i, col] = s[lead] - s[i] - (length[i] + length[lead]) / 2 if lead >= 0 else INF
            out["gr"][i, col] = s[i] - s[foll] - (length[i] + length[foll]) / 2 if foll >= 0 else INF
            out["vl"][i, col] = v[lead] if lead >= 0 else np.nan
            out["vf"][i, col] = v[foll] if foll >= 0 else np.nan
            out["al"][i, col] = a[lead] if lead >= 0 else np.nan
            out["af"][i, col] = a[foll] if foll >= 0 else np.nan
    return out


@pytest.mark.parametrize("seed", range(40))
def test_against_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    if seed % 2:  # coarse grid: many exact ties in s, within and across lanes
        s = rng.integers(-5, 30, size=n) * 5.0
    else:
        s = rng.uniform(-20.0, 2400.0, size=n)
    lane = rng.integers(0, 5, size=n)
    v = rng.uniform(0.0, 40.0, size=n)
    a = rng.uniform(-8.0, 3.0, size=n)
    length = rng.uniform(3.5, 12.0, size=n) if seed % 3 == 0 else np.full(n, L)
    nb = compute_neighborhood(s, lane, v, a, length)
    ref = _brute_force(s, lane, v, a, length)
    np.testing.assert_array_equal(nb.leader, ref["lead"])
    np.testing.assert_array_equal(nb.follower, ref["foll"])
    np.testing.assert_allclose(nb.gap_front_m, ref["gf"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(nb.gap_rear_m, ref["gr"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(nb.leader_speed_mps, ref["vl"])
    np.testing.assert_array_equal(nb.follower_speed_mps, ref["vf"])
    np.testing.assert_array_equal(nb.leader_accel_mps2, ref["al"])
    np.testing.assert_array_equal(nb.follower_accel_mps2, ref["af"])


# ---------------------------------------------------------------- TTC / THW
def test_time_to_collision() -> None:
    gap = np.array([20.0, 20.0, 20.0, 0.0, -1.0, -1.0, INF, INF, 30.0])
    v = np.array([30.0, 20.0, 10.0, 30.0, 30.0, 10.0, 30.0, 30.0, 25.0])
    vl = np.array([20.0, 20.0, 30.0, 20.0, 20.0, 30.0, np.nan, 0.0, 10.0])
    ttc = time_to_collision(gap, v, vl)
    # closing 10 m/s over 20 m -> 2 s; equal speeds and opening -> inf; zero or negative gap
    # while closing -> 0; overlapping but opening -> inf; no leader -> inf; 30 m at 15 m/s -> 2 s
    np.testing.assert_array_equal(ttc, [2.0, INF, INF, 0.0, 0.0, INF, INF, INF, 2.0])


def test_time_to_collision_with_neighbourhood() -> None:
    nb = _nb([0.0, 44.8], [2, 2], [30.0, 20.0])
    ttc = time_to_collision(nb.own_gap_m, np.array([30.0, 20.0]), nb.leader_speed_mps[:, OWN])
    assert ttc[0] == pytest.approx(4.0)  # (44.8 - 4.8) / (30 - 20)
    assert ttc[1] == INF


def test_time_headway() -> None:
    gap = np.array([30.0, 0.0, 30.0, INF, INF])
    v = np.array([15.0, 20.0, 0.0, 20.0, 0.0])
    # 30 m at 15 m/s -> 2 s; zero gap -> 0; standstill -> inf; no leader -> inf
    np.testing.assert_array_equal(time_headway(gap, v), [2.0, 0.0, INF, INF, INF])
