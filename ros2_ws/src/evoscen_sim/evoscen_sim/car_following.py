"""Standard car-following models shared by drivers: the Intelligent Driver Model (IDM).

IDM (Treiber, Hennecke, Helbing 2000; MODELS.md)::

    a = a_max [1 - (v / v0)^δ - (s* / s)²],   s* = s0 + v T + v Δv / (2 √(a_max b))

with ``s`` the bumper-to-bumper gap and ``Δv = v - v_leader`` (positive when closing).
Without a leader the interaction term is 0 (free road). Gaps ≤ 0 (bodies overlapping)
give the maximum braking the caller allows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class IdmParams:
    """IDM parameters; highway values from MODELS.md."""

    time_headway_s: float = 1.5
    min_gap_m: float = 2.0
    accel_mps2: float = 1.5
    comfort_decel_mps2: float = 2.0
    delta: float = 4.0


def idm_acceleration(
    speed_mps: np.ndarray,
    desired_speed_mps: np.ndarray,
    gap_m: np.ndarray,
    leader_speed_mps: np.ndarray,
    params: IdmParams,
    max_decel_mps2: float = 9.0,
) -> np.ndarray:
    """IDM acceleration (m/s²), clipped below at ``-max_decel_mps2``.

    ``gap_m = inf`` (and any ``leader_speed_mps``, e.g. ``nan``) means no leader.
    """
    p = params
    v = speed_mps
    free = 1.0 - (v / desired_speed_mps) ** p.delta
    # no leader: v_leader is nan, fmax drops the nan dynamic term and gap = inf zeroes the ratio
    closing = v * (v - leader_speed_mps) * (0.5 / np.sqrt(p.accel_mps2 * p.comfort_decel_mps2))
    s_star = p.min_gap_m + np.fmax(0.0, v * p.time_headway_s + closing)
    interaction = (s_star / np.maximum(gap_m, 1e-3)) ** 2
    return np.maximum(p.accel_mps2 * (free - interaction), -max_decel_mps2)
