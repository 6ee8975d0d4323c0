"""Vehicle model: a kinematic single-track (bicycle) model in road (Frenet) coordinates.

State per vehicle (all numpy arrays over vehicles, SI units):

* ``s`` arc length along the reference line (m), ``d`` lateral offset, positive to the
  left (m), ``psi`` heading relative to the road's tangent (rad), ``v`` speed (m/s).

Inputs: longitudinal acceleration (from the throttle command, see
:func:`throttle_to_accel`) and the steering angle of the front wheel.

Kinematic bicycle with the reference point at the centre of mass, half-way between the
axles (``l_r = wheelbase / 2``), slip angle ``beta = atan(l_r / L * tan(delta))``::

    ds/dt   = v cos(psi + beta) / (1 - kappa(s) d)
    dd/dt   = v sin(psi + beta)
    dpsi/dt = v cos(beta) tan(delta) / L  -  kappa(s) ds/dt
    dv/dt   = a,  0 <= v <= v_max

integrated with a fixed step (default 0.1 s): speed exactly (constant acceleration
within the step, clipped at 0 and ``v_max``), position with the step's mean speed,
heading with forward Euler. Limits: acceleration ``[-max_brake, max_accel]``, steering
``[-max_steer, max_steer]`` reached at most at ``max_steer_rate``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class VehicleParams:
    """Physical limits of a vehicle (the same for every vehicle of a scenario)."""

    length_m: float = 4.8
    width_m: float = 1.9
    wheelbase_m: float = 2.9
    max_accel_mps2: float = 3.0
    max_brake_mps2: float = 8.0
    max_speed_mps: float = 40.0
    max_steer_rad: float = 0.5
    max_steer_rate_radps: float = 0.5


def throttle_to_accel(throttle: np.ndarray, params: VehicleParams) -> np.ndarray:
    """Map a throttle/brake command in [-1, 1] to acceleration (m/s²).

    ``+1`` is full throttle (``max_accel_mps2``), ``-1`` full brake (``-max_brake_mps2``),
    linear in between; commands outside [-1, 1] are clipped.
    """
    u = np.minimum(np.maximum(throttle, -1.0), 1.0)
    return np.where(u >= 0.0, u * params.max_accel_mps2, u * params.max_brake_mps2)


def accel_to_throttle(accel_mps2: np.ndarray, params: VehicleParams) -> np.ndarray:
    """Inverse of :func:`throttle_to_accel`: the command that asks for ``accel_mps2`` (clipped)."""
    a = np.asarray(accel_mps2, dtype=float)
    u = np.where(a >= 0.0, a / params.max_accel_mps2, a / params.max_brake_mps2)
    return np.minimum(np.maximum(u, -1.0), 1.0)


def bicycle_step(
    s: np.ndarray,
    d: np.ndarray,
    psi: np.ndarray,
    v: np.ndarray,
    accel_mps2: np.ndarray,
    steer_rad: np.ndarray,
    kappa: np.ndarray,
    params: VehicleParams,
    dt_s: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Advance the kinematic bicycle one step.

    Returns ``(s, d, psi, v, accel)`` after the step, where ``accel`` is the acceleration
    actually realised (differs from the request when the speed hits 0 or ``v_max``).
    """
    v_new = np.minimum(np.maximum(v + accel_mps2 * dt_s, 0.0), params.max_speed_mps)
    accel = (v_new - v) / dt_s
    v_mean = 0.5 * (v + v_new)
    wheelbase = params.wheelbase_m
    tan_delta = np.tan(steer_rad)
    beta = np.arctan(0.5 * tan_delta)  # l_r / L = 1/2
    course = psi + beta
    s_dot = v_mean * np.cos(course) / (1.0 - kappa * d)
    d_new = d + v_mean * np.sin(course) * dt_s
    psi_new = psi + (v_mean * np.cos(beta) * tan_delta / wheelbase - kappa * s_dot) * dt_s
    return s + s_dot * dt_s, d_new, psi_new, v_new, accel
