"""What the rule-based lane-change models (MOBIL, Nilsson) share (docs/method.md §4).

* :class:`KraussLaneChangeDriver`: a lane-change decision on top of SUMO-Krauss car following
  (:mod:`evoscen_sut.krauss`; docs/method.md §4: car following is the same for every SUT),
  with the stop before the end of the merge lane; :func:`lane_change_factory` makes a model's
  :class:`evoscen_sim.model_registry.ModelSpec` factory from its decision function (the car follower's
  parameters: the scenario's ``models.krauss``, :func:`evoscen_sut.krauss.krauss_for`).
* :func:`settled`: a new change is requested only once the previous one has settled [choice].
* :func:`kernel_params`: a model's frozen parameter dataclass as the named tuple its compiled
  kernels read (the tuple type derived from the dataclass by :func:`kernel_params_type`).

The conflict resolution of one driver's vehicles is :mod:`evoscen_sut.conflicts`; the road
queries of the kernels are :mod:`evoscen_sim.road.road_kernels`.
"""

from __future__ import annotations

from collections import namedtuple
from collections.abc import Callable
from dataclasses import fields
from functools import lru_cache
from typing import Any, NamedTuple

import numpy as np
from evoscen_sim.jit import by_identity, kernel, plain  # noqa: F401 - by_identity: the models take it from here
from evoscen_sim.physics.vehicle import VehicleParams, accel_to_throttle
from evoscen_sim.road.road_kernels import RoadTables, lane_center_d, lane_end_distance

from .kernel_math import maximum, minimum
from .krauss import KraussCarFollowing, follow_speed_scalar, krauss_for, next_speed_scalar


@lru_cache(maxsize=128)
def kernel_params_type(params_class: type) -> type:
    """The named tuple the compiled kernels read a parameter dataclass as (:func:`kernel_params`):
    ``params_class``'s fields in their order, so each parameter is declared once, in the dataclass.
    Named as the dataclass with ``Kernel`` before ``Params`` (``MobilParams`` ->
    ``MobilKernelParams``), in the dataclass's module."""
    name = params_class.__name__.removesuffix("Params") + "KernelParams"
    return namedtuple(name, [f.name for f in fields(params_class)], module=params_class.__module__)


_KERNEL_PARAMS: dict[tuple[int, int], tuple[type, Any, tuple]] = {}
""":func:`kernel_params`'s tuples by the identity of (tuple type, parameter set); each entry holds
both objects, so an id is not reused while its entry lives."""
_KERNEL_PARAMS_MAX = 256


def kernel_params(tuple_type: type, params: Any) -> tuple:
    """``params`` (a frozen parameter dataclass) as ``tuple_type``, a named tuple with (some of)
    its field names, for compiled kernels: numbers as float, flags as bool (cached: one tuple per
    parameter set, as the models call it every decision; looked up by identity, a parameter set
    being frozen — docs/performance.md "Per-step work of the SUT drivers")."""
    key = (id(tuple_type), id(params))
    hit = _KERNEL_PARAMS.get(key)
    if hit is not None and hit[0] is tuple_type and hit[1] is params:
        return hit[2]
    values = (getattr(params, name) for name in tuple_type._fields)
    out = tuple_type(*(v if isinstance(v, bool) else float(v) for v in values))
    if len(_KERNEL_PARAMS) >= _KERNEL_PARAMS_MAX:
        _KERNEL_PARAMS.clear()
    _KERNEL_PARAMS[key] = (tuple_type, params, out)
    return out


@kernel
def settled(road, s, d, lane, tolerance_m):
    """True where the vehicle's centre ``d`` is within ``tolerance_m`` of its lane's centre line at
    ``max(s, 0)`` (False for an invalid lane; ``road``: :class:`evoscen_sim.road.road_kernels.RoadTables`).

    A new change is requested only once the previous one has settled [choice]: the world
    completes a change when the centre crosses into the target lane, while the vehicle is still
    moving across; reversing there produced ping-pong changes and side-by-side conflicts.
    """
    return abs(d - lane_center_d(road, lane, max(s, 0.0))) <= tolerance_m


def lane_end_gap_m(view: Any, vehicles: np.ndarray, lanes: np.ndarray, margin_m: float) -> np.ndarray:
    """Bumper gap from each vehicle's front to the stop point ``margin_m`` before the end of
    ``lanes`` (broadcast against ``vehicles[:, None]``); ``inf`` for lanes running to the road end."""
    s = view.s[vehicles]
    half = 0.5 * view.length[vehicles]
    if lanes.ndim == 2:
        s, half = s[:, None], half[:, None]
    dist = np.asarray(view.road.distance_to_lane_end(lanes, s), dtype=float)
    dist = np.where(np.isnan(dist), np.inf, dist)
    return dist - margin_m - half


class KraussLaneChangeDriver:
    """A lane-change decision model on top of SUMO-Krauss car following (every SUT's longitudinal control).

    Longitudinal command, for each driven vehicle: the Krauss acceleration behind the leader
    in its lane; while a lane change is in progress also behind the leader in the target
    lane (the smaller of the two); on a lane that ends (merge lane) and not changing,
    capped by Krauss' safe speed behind a standing obstacle ``stop_margin_m`` before the
    lane end (:func:`evoscen_sut.krauss.sumo_follow_speed` with leader speed 0, acceleration
    ``(v_safe − v) / dt``), so a vehicle that finds no gap waits there. The acceleration is
    mapped to throttle/brake by :func:`evoscen_sim.physics.vehicle.accel_to_throttle`.

    Args:
        vehicles: world indices of the driven vehicles.
        decide: ``decide(view, vehicles, params) -> lane_change`` (in {-1, 0, +1}).
        params: the decision model's parameters.
        krauss: a :class:`evoscen_sut.krauss.KraussCarFollowing`.
        vehicle_params: the scenario's vehicle limits.
        stop_margin_m: the lane-end stop margin (m).
    """

    def __init__(self, vehicles: np.ndarray, decide: Callable[..., np.ndarray], params: Any, krauss: Any,
                 vehicle_params: VehicleParams, stop_margin_m: float) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.decide = decide
        self.params = params
        self.krauss = krauss
        self.vehicle_params = vehicle_params
        self.stop_margin_m = float(stop_margin_m)
        self._params_memo: tuple | None = None
        self._factors_memo: tuple | None = None
        self.desired_speed_mps: np.ndarray | None = None
        """Per driven vehicle, its own desired speed (m/s), set by ``bvs.makeup: highd``'s driver
        (:func:`evoscen_bv.truck.makeup_driver`): it replaces ``models.krauss.desired_speed_mps`` × the
        vehicle's speed factor in the car following. None (default): the Krauss parameters' speed."""
        self.speed_cap = True
        """Whether the car following's speed is capped by the lane's limit (False under ``bvs.makeup:
        highd``: highD's desired speeds are not capped). The lane-change decision keeps its own
        parameters' desired speed either way (docs/bv-profiles.md, "Rule-based cars in the highD make-up")."""

    def acceleration(self, view: Any) -> np.ndarray:
        """Desired acceleration (m/s²) of every driven vehicle (see the class docstring)."""
        if self._compiled_krauss():
            return self._acceleration_throttle(view)[0]
        return self._acceleration_generic(view)

    def _acceleration_generic(self, view: Any) -> np.ndarray:
        """:meth:`acceleration` for any car follower with ``KraussCarFollowing``'s interface."""
        from evoscen_sim.errors import InputError

        from .krauss import sumo_follow_speed

        if self.desired_speed_mps is not None or not self.speed_cap:
            raise InputError(f"bvs.makeup: highd: the cars' car follower {type(self.krauss).__name__} takes no "
                             "desired speed per vehicle (expected evoscen_sut.krauss.KraussCarFollowing)")
        idx = self.vehicles
        acc = np.asarray(self.krauss.acceleration(view, idx), dtype=float).copy()
        offset = np.clip(view.target_lane[idx] - view.lane[idx], -1, 1).astype(np.int64)
        changing = offset != 0
        if changing.any():
            acc_t = np.asarray(self.krauss.acceleration(view, idx[changing], offset[changing]), dtype=float)
            acc[changing] = np.minimum(acc[changing], acc_t)
        end_gap = lane_end_gap_m(view, idx, view.lane[idx], self.stop_margin_m)
        stop = np.isfinite(end_gap) & ~changing
        if stop.any():
            v = view.v[idx[stop]]
            v_safe = sumo_follow_speed(end_gap[stop], v, np.zeros(v.size), self.krauss.params, view.dt_s)
            acc[stop] = np.minimum(acc[stop], (np.maximum(v_safe, 0.0) - v) / view.dt_s)
        return acc

    def _compiled_krauss(self) -> bool:
        """The car follower is exactly :class:`evoscen_sut.krauss.KraussCarFollowing` (compiled path)."""
        return type(self.krauss) is KraussCarFollowing

    def _acceleration_throttle(self, view: Any) -> tuple[np.ndarray, np.ndarray]:
        """(acceleration, throttle) in one compiled pass; the same numbers and random draws as
        :meth:`_acceleration_generic` with ``KraussCarFollowing`` (one ``rng.random(m)`` for the
        own lane, then one for the vehicles changing lanes, if any)."""
        idx = self.vehicles
        kr = self.krauss
        m = idx.shape[0]
        u = kr.rng.random(m)
        if m == 0:
            return np.zeros(0), np.zeros(0)
        lane = view.lane
        target_lane = view.target_lane
        n_changing = _count_changing(idx, lane, target_lane)
        u_target = kr.rng.random(n_changing) if n_changing else _NO_DRAWS
        nb = view.neighborhood()
        prm = self._kernel_params(kr, float(view.dt_s))
        limit = view.speed_limit_mps if self.speed_cap else self._no_limit(view.s.shape[0])
        return _krauss_kernel(idx, self._factors(kr, idx, prm.desired_speed_mps), u, u_target, view.s, view.v,
                              view.length, lane, target_lane, limit, nb.gap_front_m, nb.leader_speed_mps,
                              plain(view.road.kernel_tables()), plain(prm))

    def _kernel_params(self, kr: KraussCarFollowing, view_dt_s: float) -> KraussDriverParams:
        """:func:`_krauss_params` of this driver, kept while the car follower's parameters and the
        vehicle limits are the same objects and the margin and steps the same values (no hashing of
        the frozen parameter sets every step; docs/performance.md "Per-step work of the SUT drivers")."""
        c = self._params_memo
        if (c is not None and c[0] is kr.params and c[1] is self.vehicle_params and c[2] == self.stop_margin_m
                and c[3] == kr.dt_s and c[4] == view_dt_s):
            return c[5]
        out = _krauss_params(kr.params, self.vehicle_params, self.stop_margin_m, float(kr.dt_s), view_dt_s)
        self._params_memo = (kr.params, self.vehicle_params, self.stop_margin_m, kr.dt_s, view_dt_s, out)
        return out

    def _factors(self, kr: KraussCarFollowing, idx: np.ndarray, desired_mps: float) -> np.ndarray:
        """``kr.factors(idx)``, kept while the car follower, its speed factors (drawn once, when it was
        built) and the driven vehicles are the same objects; with :attr:`desired_speed_mps` set, the factors
        that make ``desired_mps`` × factor each vehicle's own desired speed."""
        c = self._factors_memo
        own = self.desired_speed_mps
        if c is not None and c[0] is kr and c[1] is kr.speed_factors and c[2] is idx and c[3] is own:
            return c[4]
        out = kr.factors(idx) if own is None else np.asarray(own, dtype=float) / desired_mps
        self._factors_memo = (kr, kr.speed_factors, idx, own, out)
        return out

    def _no_limit(self, n: int) -> np.ndarray:
        """The speed limits of an uncapped car follower: ``nan`` for all ``n`` vehicles (kept, not made per step)."""
        c = getattr(self, "_nan_limits", None)
        if c is None or c.shape[0] != n:
            c = self._nan_limits = np.full(n, np.nan)
        return c

    def drive_only(self, positions: np.ndarray) -> None:
        """Drive only the vehicles at ``positions`` of :attr:`vehicles` (with their own desired speeds, if
        set); before the first :meth:`act`. Not a BV node's ``restrict``: the dawdling draws are one per
        driven vehicle and step, so a driver of a share would draw otherwise than the driver of all.
        :func:`evoscen_bv.truck.makeup_driver` keeps it to the make-up's cars once, when it is built; a BV
        node's share of them is its answer cut (:class:`evoscen_bv.truck.CutShare`)."""
        positions = np.asarray(positions, dtype=np.int64)
        self.vehicles = self.vehicles[positions]
        if self.desired_speed_mps is not None:
            self.desired_speed_mps = np.asarray(self.desired_speed_mps, dtype=float)[positions]
        self._factors_memo = None

    def lane_change(self, view: Any) -> np.ndarray:
        """The lane-change request of :meth:`act` alone (the decision draws no random numbers)."""
        return self.decide(view, self.vehicles, self.params)

    def throttle(self, view: Any) -> np.ndarray:
        """The throttle of :meth:`act` alone, with the same random draws."""
        if self._compiled_krauss():
            return self._acceleration_throttle(view)[1]
        return accel_to_throttle(self._acceleration_generic(view), self.vehicle_params)

    def act(self, view: Any) -> tuple[np.ndarray, np.ndarray]:
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} for each driven vehicle."""
        request = self.lane_change(view)
        return self.throttle(view), request


_NO_DRAWS = np.zeros(0)


class KraussDriverParams(NamedTuple):
    """The parameters of :class:`KraussLaneChangeDriver`'s compiled command (:func:`_krauss_kernel`)."""

    min_gap_m: float
    """Krauss ``minGap`` (m)."""
    accel_mps2: float
    """Krauss ``accel`` (m/s²)."""
    decel_mps2: float
    """Krauss ``decel`` (m/s²)."""
    emergency_decel_mps2: float
    """Krauss ``emergencyDecel`` (m/s²)."""
    sigma: float
    """Krauss dawdling ``σ`` (-)."""
    tau_s: float
    """Krauss ``τ`` (s)."""
    desired_speed_mps: float
    """The desired speed, capped by the lane's speed limit (m/s)."""
    dt_s: float
    """The car follower's step (s)."""
    view_dt_s: float
    """The view's step (s): the lane-end stop's acceleration is ``(v_safe − v) / view_dt_s``."""
    stop_margin_m: float
    """The lane-end stop margin (m)."""
    max_accel_mps2: float
    """The vehicle's maximum acceleration (m/s²): throttle 1."""
    max_brake_mps2: float
    """The vehicle's maximum braking (m/s²): throttle −1."""


@lru_cache(maxsize=64)
def _krauss_params(kp: Any, vp: VehicleParams, stop_margin_m: float, dt_s: float,
                   view_dt_s: float) -> KraussDriverParams:
    """The :class:`KraussDriverParams` of a car follower's parameters and the vehicle limits."""
    return KraussDriverParams(
        min_gap_m=float(kp.min_gap_m), accel_mps2=float(kp.accel_mps2), decel_mps2=float(kp.decel_mps2),
        emergency_decel_mps2=float(kp.emergency_decel_mps2), sigma=float(kp.sigma), tau_s=float(kp.tau_s),
        desired_speed_mps=float(kp.desired_speed_mps), dt_s=float(dt_s), view_dt_s=float(view_dt_s),
        stop_margin_m=float(stop_margin_m), max_accel_mps2=float(vp.max_accel_mps2),
        max_brake_mps2=float(vp.max_brake_mps2))


@kernel
def _count_changing(idx, lane, target_lane):
    """How many of the vehicles ``idx`` are changing lanes (``target_lane != lane``)."""
    cnt = 0
    for q in range(idx.shape[0]):
        i = idx[q]
        if target_lane[i] != lane[i]:
            cnt += 1
    return cnt


@kernel
def _krauss_kernel(idx, factor, u, u_target, s, v, length, lane, target_lane, speed_limit, gap_front,
                   leader_speed, road_t, prm_t):
    """:class:`KraussLaneChangeDriver`'s acceleration and throttle (class docstring); the road's tables and the
    parameters as plain tuples (:func:`evoscen_sim.jit.plain`)."""
    road, prm = RoadTables(*road_t), KraussDriverParams(*prm_t)
    min_gap, accel, decel, emergency, sigma, tau = (prm.min_gap_m, prm.accel_mps2, prm.decel_mps2,
                                                    prm.emergency_decel_mps2, prm.sigma, prm.tau_s)
    desired, dt, view_dt, margin = prm.desired_speed_mps, prm.dt_s, prm.view_dt_s, prm.stop_margin_m
    max_accel, max_brake = prm.max_accel_mps2, prm.max_brake_mps2
    m = idx.shape[0]
    acc = np.empty(m)
    throttle = np.empty(m)
    q = 0
    for k in range(m):
        i = idx[k]
        vi = v[i]
        lim = speed_limit[i]
        want = desired * factor[k]
        v_max = want if np.isnan(lim) else (lim if np.isnan(want) else min(lim, want))  # np.fmin
        v_next = next_speed_scalar(vi, v_max, gap_front[i, 2] - min_gap, leader_speed[i, 2], u[k], accel, decel,
                                   emergency, sigma, tau, dt)
        a = (v_next - vi) / dt
        offset = min(max(target_lane[i] - lane[i], -1), 1)
        if offset != 0:
            col = 2 + offset
            v_next = next_speed_scalar(vi, v_max, gap_front[i, col] - min_gap, leader_speed[i, col], u_target[q],
                                       accel, decel, emergency, sigma, tau, dt)
            q += 1
            a = minimum(a, (v_next - vi) / dt)
        else:
            end_gap = lane_end_distance(road, lane[i], s[i]) - margin - 0.5 * length[i]
            if np.isfinite(end_gap):
                v_safe = follow_speed_scalar(end_gap - min_gap, vi, 0.0, decel, emergency, tau, view_dt)
                a = minimum(a, (maximum(v_safe, 0.0) - vi) / view_dt)
        acc[k] = a
        cmd = maximum(a, 0.0) * (1.0 / max_accel) + minimum(a, 0.0) * (1.0 / max_brake)  # accel_to_throttle
        throttle[k] = minimum(maximum(cmd, -1.0), 1.0)
    return acc, throttle


def lane_change_factory(decision: Any, params_type: type) -> Any:
    """A :class:`evoscen_sim.model_registry.ModelSpec` factory: ``decision`` plus Krauss car following.

    Shared by the rule-based models (MOBIL, Nilsson), which differ only in their decision.
    """
    def make_driver(vehicles: np.ndarray, params: Any, config: Any,
                    rng: np.random.Generator) -> KraussLaneChangeDriver:
        params = params_type() if params is None else params
        return KraussLaneChangeDriver(vehicles, decision, params, krauss_for(config, rng, vehicles),
                                      config.vehicle, params.merge_stop_margin_m)

    make_driver.__module__ = decision.__module__  # the factory belongs to its model's module
    make_driver.__qualname__ = "make_driver"
    return make_driver
