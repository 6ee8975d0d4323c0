"""Neighbourhood queries every driver and the evaluator need, vectorized over vehicles.

For every vehicle ``i`` and lane offset ``o`` in ``-2..+2`` (column ``o + 2``; +1 is the
lane to the left) we find the nearest vehicle ahead (leader) and behind (follower) whose
centre is in lane ``lane[i] + o``, the bumper-to-bumper gaps to them, and their speeds and
accelerations. In the own lane a vehicle is *ahead* of ``i`` when its arc position ``s`` is larger, or
equal with a larger index (so of two vehicles at the same ``s`` exactly one is the other's
leader); in another lane a vehicle exactly level with ``i`` counts as behind it). Gaps are ``|Δs| - (L_i + L_j) / 2`` and are negative when the two bodies overlap
longitudinally — which a lane-change safety check must see.

Method: one stable sort of all vehicles by (lane, s) and one ``searchsorted`` of the 5·N
queries (lane + o, s_i, i) into it — a fixed, small number of numpy operations per step
whatever the number of vehicles, and no Python loop over vehicles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LANE_OFFSETS = np.arange(-2, 3)
"""Lane offsets of the neighbourhood columns: column ``j`` is offset ``j - 2``."""
OWN = 2
LEFT = 3
RIGHT = 1

_LANE_KEY = 1.0e5  # lane stride of the sort key (> any arc position, m)


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


def compute_neighborhood(
    s: np.ndarray, lane: np.ndarray, v: np.ndarray, a: np.ndarray, length: np.ndarray
) -> Neighborhood:
    """Leaders and followers of every vehicle (see :class:`Neighborhood`)."""
    n = s.shape[0]
    # sort by lane, then s; the stable sort keeps equal keys in index order
    key_all = lane * _LANE_KEY + s
    order = np.argsort(key_all, kind="stable")
    key = key_all[order]
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    q_lane = lane[:, None] + LANE_OFFSETS[None, :]  # (N, 5)
    # other lanes: everything with s <= s_i is behind; own lane: i sits at its rank
    split = np.searchsorted(key, q_lane * _LANE_KEY + s[:, None], side="right")
    split[:, OWN] = rank
    # own lane: i itself sits at split (= rank[i]); its leader is the next one
    own_col = LANE_OFFSETS[None, :] == 0
    lead_pos = np.where(own_col, split + 1, split)
    foll_pos = split - 1
    lead_ok = lead_pos < n
    lead_idx = order[np.minimum(lead_pos, n - 1)]
    lead_ok &= lane[lead_idx] == q_lane
    foll_ok = foll_pos >= 0
    foll_idx = order[np.maximum(foll_pos, 0)]
    foll_ok &= lane[foll_idx] == q_lane
    half_i = 0.5 * length[:, None]
    gap_front = np.where(lead_ok, s[lead_idx] - s[:, None] - half_i - 0.5 * length[lead_idx], np.inf)
    gap_rear = np.where(foll_ok, s[:, None] - s[foll_idx] - half_i - 0.5 * length[foll_idx], np.inf)
    return Neighborhood(
        leader=np.where(lead_ok, lead_idx, -1),
        follower=np.where(foll_ok, foll_idx, -1),
        gap_front_m=gap_front,
        gap_rear_m=gap_rear,
        leader_speed_mps=np.where(lead_ok, v[lead_idx], np.nan),
        follower_speed_mps=np.where(foll_ok, v[foll_idx], np.nan),
        leader_accel_mps2=np.where(lead_ok, a[lead_idx], np.nan),
        follower_accel_mps2=np.where(foll_ok, a[foll_idx], np.nan),
    )


def time_to_collision(gap_m: np.ndarray, speed_mps: np.ndarray, leader_speed_mps: np.ndarray) -> np.ndarray:
    """TTC = gap / (v - v_leader) while closing, else ``inf`` (MODELS.md, safety surrogates).

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
