"""Standard car-following models shared by drivers: the Intelligent Driver Model (IDM).

IDM (Treiber, Hennecke, Helbing 2000; docs/method.md §4.2)::

    a = a_max [1 - (v / v0)^δ - (s* / s)²],   s* = s0 + v T + v Δv / (2 √(a_max b))

with ``s`` the bumper-to-bumper gap and ``Δv = v - v_leader`` (positive when closing).
Without a leader the interaction term is 0 (free road). Gaps ≤ 0 (bodies overlapping)
give the maximum braking the caller allows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evoscen_sim.jit import elementwise, kernel


@dataclass(frozen=True)
class IdmParams:
    """IDM parameters; highway values from docs/method.md §4.2."""

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
    """IDM acceleration (m/s²), clipped below at ``-max_decel_mps2``; broadcasts like numpy.

    ``gap_m = inf`` (and any ``leader_speed_mps``, e.g. ``nan``) means no leader.
    """
    p = params
    return _idm_ufunc(speed_mps, desired_speed_mps, gap_m, leader_speed_mps, p.time_headway_s,
                      p.min_gap_m, p.accel_mps2, p.comfort_decel_mps2, p.delta, max_decel_mps2)


@kernel
def idm_scalar(v, v0, gap, v_leader, time_headway, min_gap, accel, comfort_decel, delta, max_decel):
    """IDM for one vehicle (compiled; callable from other kernels). See the module docstring."""
    free = 1.0 - (v / v0) ** delta
    if gap == np.inf or np.isnan(v_leader):
        interaction = 0.0
    else:
        s_star = min_gap + max(0.0, v * time_headway + v * (v - v_leader) / (2.0 * np.sqrt(accel * comfort_decel)))
        interaction = (s_star / max(gap, 1e-3)) ** 2
    return max(accel * (free - interaction), -max_decel)


@elementwise
def _idm_ufunc(v, v0, gap, v_leader, time_headway, min_gap, accel, comfort_decel, delta, max_decel):
    return idm_scalar(v, v0, gap, v_leader, time_headway, min_gap, accel, comfort_decel, delta, max_decel)
