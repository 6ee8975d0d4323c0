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

import numpy as np

from evoscen_sim.config.config_schema import VehicleParams
from evoscen_sim.jit import kernel


def throttle_to_accel(throttle: np.ndarray, params: VehicleParams) -> np.ndarray:
    """Map a throttle/brake command in [-1, 1] to acceleration (m/s²).

    ``+1`` is full throttle (``max_accel_mps2``), ``-1`` full brake (``-max_brake_mps2``),
    linear in between; commands outside [-1, 1] are clipped.
    """
    u = np.minimum(np.maximum(throttle, -1.0), 1.0)
    return np.maximum(u, 0.0) * params.max_accel_mps2 + np.minimum(u, 0.0) * params.max_brake_mps2


def accel_to_throttle(accel_mps2: np.ndarray, params: VehicleParams) -> np.ndarray:
    """Inverse of :func:`throttle_to_accel`: the command that asks for ``accel_mps2`` (clipped)."""
    a = np.asarray(accel_mps2, dtype=float)
    u = np.maximum(a, 0.0) * (1.0 / params.max_accel_mps2) + np.minimum(a, 0.0) * (1.0 / params.max_brake_mps2)
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
    """Advance the kinematic bicycle one step (inputs are not modified).

    Returns ``(s, d, psi, v, accel)`` after the step, where ``accel`` is the acceleration
    actually realised (differs from the request when the speed hits 0 or ``v_max``).
    """
    arrays = [np.array(x, dtype=float, ndmin=1) for x in (s, d, psi, v)]
    shape = np.broadcast_shapes(*(a.shape for a in arrays), np.shape(accel_mps2), np.shape(steer_rad), np.shape(kappa))
    s1, d1, psi1, v1 = (np.ascontiguousarray(np.broadcast_to(a, shape), dtype=float).copy().ravel() for a in arrays)
    acc = np.ascontiguousarray(np.broadcast_to(np.asarray(accel_mps2, dtype=float), shape)).ravel()
    steer = np.ascontiguousarray(np.broadcast_to(np.asarray(steer_rad, dtype=float), shape)).ravel()
    kap = np.ascontiguousarray(np.broadcast_to(np.asarray(kappa, dtype=float), shape)).ravel()
    a_real = np.empty_like(s1)
    bicycle_step_inplace(s1, d1, psi1, v1, a_real, acc, steer, kap, params.wheelbase_m, params.max_speed_mps, dt_s)
    return tuple(x.reshape(shape) for x in (s1, d1, psi1, v1, a_real))  # type: ignore[return-value]


@kernel
def bicycle_step_inplace(s, d, psi, v, accel_out, accel_cmd, steer, kappa, wheelbase, max_speed, dt):
    """Compiled :func:`bicycle_step` updating ``s, d, psi, v`` and writing ``accel_out`` in place."""
    for i in range(s.shape[0]):
        bicycle_one(i, s, d, psi, v, accel_out, accel_cmd[i], steer[i], kappa[i], wheelbase, max_speed, dt)


@kernel
def bicycle_one(i, s, d, psi, v, accel_out, accel_cmd, steer, kappa, wheelbase, max_speed, dt):
    """Advance vehicle ``i`` of the state arrays one step in place (see the module docstring)."""
    v_new = min(max(v[i] + accel_cmd * dt, 0.0), max_speed)
    accel_out[i] = (v_new - v[i]) / dt
    v_mean = 0.5 * (v[i] + v_new)
    tan_delta = np.tan(steer)
    beta = np.arctan(0.5 * tan_delta)  # l_r / L = 1/2
    course = psi[i] + beta
    s_dot = v_mean * np.cos(course) / (1.0 - kappa * d[i])
    d[i] = d[i] + v_mean * np.sin(course) * dt
    psi[i] = psi[i] + (v_mean * np.cos(beta) * tan_delta / wheelbase - kappa * s_dot) * dt
    s[i] = s[i] + s_dot * dt
    v[i] = v_new
