"""Neighbourhood queries every driver and the evaluator need, vectorized over vehicles.

For every vehicle ``i`` and lane offset ``o`` in ``-2..+2`` (column ``o + 2``; +1 is the
lane to the left) we find the nearest vehicle ahead (leader) and behind (follower) whose
centre is in lane ``lane[i] + o``, the bumper-to-bumper gaps to them, and their speeds and
accelerations. In the own lane a vehicle is *ahead* of ``i`` when its arc position ``s`` is larger, or
equal with a larger index (so of two vehicles at the same ``s`` exactly one is the other's
leader); in another lane a vehicle exactly level with ``i`` counts as behind it). Gaps are ``|Δs| - (L_i + L_j) / 2`` and are negative when the two bodies overlap
longitudinally — which a lane-change safety check must see.

Method: one compiled pass over all vehicle pairs (:mod:`evoscen_sim.jit`); for the tens
of vehicles of a scenario that is a couple of microseconds, and no Python loop.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from evoscen_sim.jit import kernel

LANE_OFFSETS = np.arange(-2, 3)
"""Lane offsets of the neighbourhood columns: column ``j`` is offset ``j - 2``."""
OWN = 2
LEFT = 3
RIGHT = 1


@kernel
def lane_column(lane_i, lane_j):
    """The neighbourhood column of a vehicle in lane ``lane_j`` seen from one in ``lane_i``: its lane
    offset + 2 (0..4), or -1 when it is more than two lanes away (not in the neighbourhood)."""
    c = lane_j - lane_i + 2
    return c if 0 <= c <= 4 else -1


@dataclass(frozen=True)
class Neighborhood:
    """Leaders and followers of every vehicle in its own lane and the lanes ±1, ±2.

    Arrays have shape ``(N, 5)``; column ``j`` is lane offset ``j - 2`` (``OWN`` = 2,
    ``LEFT`` = 3, ``RIGHT`` = 1). Missing neighbours: index -1, gap ``inf``, speed and
    acceleration ``nan``.
    """

    leader: np.ndarray
    follower: np.ndarray
    gap_front_m: np.ndarray
    gap_rear_m: np.ndarray
    leader_speed_mps: np.ndarray
    follower_speed_mps: np.ndarray
    leader_accel_mps2: np.ndarray
    follower_accel_mps2: np.ndarray

    @property
    def own_gap_m(self) -> np.ndarray:
        """Distance headway (bumper to bumper) to the leader in the own lane, ``inf`` if none."""
        return self.gap_front_m[:, OWN]


_FIELDS = tuple(f.name for f in fields(Neighborhood))
""":class:`Neighborhood`'s fields in order: the kernel's two integer then six float arrays."""


def compute_neighborhood(
    s: np.ndarray, lane: np.ndarray, v: np.ndarray, a: np.ndarray, length: np.ndarray
) -> Neighborhood:
    """Leaders and followers of every vehicle (see :class:`Neighborhood`)."""
    ints, floats = _neighborhood_kernel(s, lane.astype(np.int64), v, a, length)
    # the frozen dataclass's fields set at once (its __init__ sets them one by one through object.__setattr__:
    # ~1.8 µs against ~0.4; docs/performance.md "Per-step work of the world and of the BV drivers")
    nb = object.__new__(Neighborhood)
    nb.__dict__.update(zip(_FIELDS, (*ints, *floats)))
    return nb


@kernel
def _neighborhood_kernel(s, lane, v, a, length):
    """The fields of :class:`Neighborhood` as two arrays (a compiled call pays about half a microsecond
    for every array it hands back: docs/performance.md "Per-step work of the world and of the BV
    drivers"): ``(2, N, 5)`` integers (leader, follower) and ``(6, N, 5)`` floats (the gaps, speeds and
    accelerations in the dataclass's order)."""
    n = s.shape[0]
    ints = np.full((2, n, 5), -1, dtype=np.int64)
    floats = np.empty((6, n, 5))
    floats[0:2] = np.inf
    floats[2:6] = np.nan
    lead, foll = ints[0], ints[1]
    gap_f, gap_r, v_f, v_r, a_f, a_r = floats[0], floats[1], floats[2], floats[3], floats[4], floats[5]
    best_f = np.empty(5)
    best_r = np.empty(5)
    for i in range(n):
        best_f[:] = np.inf
        best_r[:] = np.inf
        for j in range(n):
            c = lane_column(lane[i], lane[j])
            if j == i or c < 0:
                continue
            ds = s[j] - s[i]
            if ds > 0.0 or (ds == 0.0 and c == 2 and j > i):
                if ds < best_f[c]:  # strict: the lowest index wins a tie
                    best_f[c] = ds
                    lead[i, c] = j
            elif -ds <= best_r[c]:  # non-strict: the highest index wins a tie
                best_r[c] = -ds
                foll[i, c] = j
        for c in range(5):
            j = lead[i, c]
            if j >= 0:
                gap_f[i, c] = best_f[c] - 0.5 * (length[i] + length[j])
                v_f[i, c] = v[j]
                a_f[i, c] = a[j]
            j = foll[i, c]
            if j >= 0:
                gap_r[i, c] = best_r[c] - 0.5 * (length[i] + length[j])
                v_r[i, c] = v[j]
                a_r[i, c] = a[j]
    return ints, floats


def time_to_collision(gap_m: np.ndarray, speed_mps: np.ndarray, leader_speed_mps: np.ndarray) -> np.ndarray:
    """TTC = gap / (v - v_leader) while closing, else ``inf`` (docs/method.md §5.1, safety surrogates).

    A gap ≤ 0 while closing gives 0; no leader (``nan`` speed or ``inf`` gap) gives ``inf``.
    """
    closing = speed_mps - leader_speed_mps
    with np.errstate(divide="ignore", invalid="ignore"):
        ttc = np.where(closing > 0.0, np.maximum(gap_m, 0.0) / closing, np.inf)
    return np.where(np.isfinite(gap_m), ttc, np.inf)


def time_headway(gap_m: np.ndarray, speed_mps: np.ndarray) -> np.ndarray:
    """THW = DHW / v (s); ``inf`` without a leader or at standstill."""
    with np.errstate(divide="ignore", invalid="ignore"):
        thw = np.where(speed_mps > 0.0, gap_m / speed_mps, np.inf)
    return np.where(np.isfinite(gap_m), thw, np.inf)
