"""Low-level lateral control: a cascaded dual PID tracking the target lane's centre line.

docs/method.md §2: "a dual PID (lateral offset and heading error) tracks the target lane's centre
line, producing steering". Our reading, vectorized over vehicles:

1. Lateral-offset PID (outer loop). ``e_d = d_target - d`` gives a lateral-speed demand
   ``w = kp_d e_d + ki_d ∫e_d + kd_d de_d/dt`` (m/s), saturated at
   ``±max_lateral_speed_mps``; the heading reference is ``psi_ref = asin(w / v)``. The
   saturation sets how long a lane change takes: ~0.6 m/s moves the centre of mass the
   1.75 m to the lane boundary in about 3.5 s at any speed above ~3 m/s.
   [choice] ``psi_ref`` is capped at ``±max_heading_ref_rad`` [0.2 rad, 11.5°]: below
   ``max_lateral_speed / sin(0.2)`` ≈ 3 m/s the demanded lateral speed would otherwise
   turn a crawling car 30–90° across its lane, and when it accelerated again it swung over
   the far lane line (a learned BV merging in stop-and-go traffic left the road this way).
   Above ~3 m/s the cap never binds, so highway-speed behaviour is unchanged to the bit.
2. Heading PID (inner loop). ``e_psi = psi_ref - psi`` gives a heading-rate demand
   ``r = kp_psi e_psi + ki_psi ∫e_psi + kd_psi de_psi/dt`` (1/s), turned into steering
   with the bicycle relation ``delta = atan(L (r / v + kappa))`` — the ``kappa`` term is
   the feed-forward that holds the lane on curves.

Gains are per second (the loops are gain-scheduled by speed through ``w / v`` and
``r / v``), so one set of gains behaves the same from 10 to 40 m/s. With the defaults
(kp_d 0.8, kp_psi 3.0) the closed loop is near critically damped (no overshoot).
"""

from __future__ import annotations

import numpy as np

from evoscen_sim.config.config_schema import ControlParams
from evoscen_sim.jit import kernel

_MIN_SPEED_MPS = 1.0  # below this the speed scheduling uses 1 m/s (avoids division by ~0)


class DualPidController:
    """Vectorized dual PID for ``n`` vehicles; keeps the integral and previous errors."""

    def __init__(self, n: int, params: ControlParams, wheelbase_m: float, dt_s: float) -> None:
        self.params = params
        self.wheelbase_m = wheelbase_m
        self.dt_s = dt_s
        self.int_d = np.zeros(n)
        self.int_psi = np.zeros(n)
        self.prev_e_d = np.zeros(n)
        self.prev_e_psi = np.zeros(n)
        self.fresh = np.ones(n, dtype=bool)

    def reset(self, idx: np.ndarray) -> None:
        """Forget the loop memory of vehicles ``idx`` (new lane change, re-entry).

        The first step after a reset has no derivative term (no derivative kick).
        """
        self.int_d[idx] = 0.0
        self.int_psi[idx] = 0.0
        self.fresh[idx] = True

    def steering(
        self, d: np.ndarray, psi: np.ndarray, v: np.ndarray, d_target: np.ndarray, kappa: np.ndarray
    ) -> np.ndarray:
        """Steering angle request (rad) for every vehicle."""
        p = self.params
        return _dual_pid_kernel(
            d, psi, v, d_target, kappa, self.int_d, self.int_psi, self.prev_e_d, self.prev_e_psi, self.fresh,
            p.lat_kp, p.lat_ki, p.lat_kd, p.head_kp, p.head_ki, p.head_kd, p.max_lateral_speed_mps,
            p.max_heading_ref_rad, self.wheelbase_m, self.dt_s,
        )


@kernel
def _dual_pid_kernel(d, psi, v, d_target, kappa, int_d, int_psi, prev_e_d, prev_e_psi, fresh,
                     lat_kp, lat_ki, lat_kd, head_kp, head_ki, head_kd, max_lat_speed, max_heading, wheelbase, dt):
    n = d.shape[0]
    steer = np.empty(n)
    for i in range(n):
        steer[i] = dual_pid_one(i, d[i], psi[i], v[i], d_target[i], kappa[i], int_d, int_psi, prev_e_d,
                                prev_e_psi, fresh, lat_kp, lat_ki, lat_kd, head_kp, head_ki, head_kd,
                                max_lat_speed, max_heading, wheelbase, dt)
    return steer


@kernel
def dual_pid_one(i, d, psi, v, d_target, kappa, int_d, int_psi, prev_e_d, prev_e_psi, fresh,
                 lat_kp, lat_ki, lat_kd, head_kp, head_ki, head_kd, max_lat_speed, max_heading, wheelbase, dt):
    """Steering request of vehicle ``i`` (compiled; updates the loop memory arrays at ``i``)."""
    v_eff = max(v, _MIN_SPEED_MPS)
    # outer loop: lateral offset -> lateral-speed demand -> heading reference
    e_d = d_target - d
    int_d[i] += e_d * dt
    de_d = 0.0 if fresh[i] else (e_d - prev_e_d[i]) / dt
    w = lat_kp * e_d + lat_ki * int_d[i] + lat_kd * de_d
    w = min(max(w, -max_lat_speed), max_lat_speed)
    psi_ref = np.arcsin(min(max(w / v_eff, -1.0), 1.0))
    psi_ref = min(max(psi_ref, -max_heading), max_heading)  # [choice] a car needs forward motion to move sideways
    # inner loop: heading error -> heading-rate demand -> steering (+ curvature feed-forward)
    e_psi = psi_ref - psi
    int_psi[i] += e_psi * dt
    de_psi = 0.0 if fresh[i] else (e_psi - prev_e_psi[i]) / dt
    r = head_kp * e_psi + head_ki * int_psi[i] + head_kd * de_psi
    prev_e_d[i] = e_d
    prev_e_psi[i] = e_psi
    fresh[i] = False
    return np.arctan(wheelbase * (r / v_eff + kappa))
