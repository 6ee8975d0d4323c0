"""Truck drivers of the ``highd`` traffic make-up (docs/bv-profiles.md, "Traffic make-up").

A truck follows the IDM (:func:`evoscen_sim.physics.idm.idm_scalar`) with its own desired speed (drawn
from highD's per-truck speeds, :mod:`evoscen_sim.traffic.makeup`) and truck parameters
(:class:`TruckParams`, ``models.truck``), behind the nearer-braking of the leaders a learned BV
follows (:func:`evoscen_bv.car_following.leaders`: vehicles *occupying* its lane — in it, changing
into it or reaching into it — and its target lane's while it changes lanes; the merge lane's end
as a standing leader), braking at most ``max_decel_mps2``. It changes lanes by MOBIL's asymmetric
keep-right rules (:func:`evoscen_sut.mobil.lane_change_decision`'s kernel) with truck IDM parameters, a
larger keep-right bias and politeness, and never into the leftmost ``keep_off_left_lanes`` lanes.

:class:`MakeupDriver` drives the BVs under ``bvs.makeup: highd``: the cars with ``bvs.driver`` (its
desired speeds replaced by the drawn ones, not capped at the lane's limit), the trucks with
:class:`TruckDriver`. Both keep per-slot state only, so a BV node's share (``restrict``) drives exactly
as in the driver of all BVs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from evoscen_sim.config.scenario_config import integer, number
from evoscen_sim.jit import kernel, plain
from evoscen_sim.physics.idm import idm_scalar
from evoscen_sut.krauss_lane_change import kernel_params
from evoscen_sut.mobil import MobilKernelParams, MobilParams, _mobil_decision_kernel, conflict_rule

from .car_following import _ALL_SEEN, _nearest_leaders, _occupancy, leaders


@dataclass(frozen=True)
class TruckParams:
    """The truck driver (scenario YAML ``models.truck``). IDM values: Treiber & Kesting, *Traffic Flow
    Dynamics* (2013), trucks: a longer headway and standstill gap, lower acceleration than cars."""

    time_headway_s: float = number(1.8, 0.1, 5.0)
    """IDM time headway T (s). [choice] 1.8, within the truck range 1.5–2 s."""
    min_gap_m: float = number(3.0, 0.0, 20.0)
    """IDM standstill gap s0 (m). [choice] 3, within the truck range 2–4 m."""
    accel_mps2: float = number(1.0, 0.1, 5.0)
    """IDM maximum acceleration a (m/s²): 1.0 (Treiber & Kesting's truck value); also the truck's
    acceleration limit (the IDM never exceeds a)."""
    comfort_decel_mps2: float = number(2.0, 0.1, 10.0)
    """IDM comfortable deceleration b (m/s²): 2.0."""
    delta: float = number(4.0, 0.1, 10.0)
    """IDM acceleration exponent δ: 4."""
    max_decel_mps2: float = number(5.0, 0.5, 8.0)
    """Hardest braking of a truck (m/s²). [choice] 5: a loaded truck tractor must stop from 60 mph within
    250 ft (FMVSS 121, 49 CFR 571.121), a mean of 4.7 m/s² including the brakes' build-up."""
    politeness: float = number(0.5, 0.0, 5.0)
    """MOBIL politeness p. [choice] 0.5, the top of docs/method.md §4.2's 0–0.5: highD's trucks change
    lanes half as often per km as its cars (0.151 vs 0.328)."""
    threshold_mps2: float = number(0.5, 0.0, 5.0)
    """MOBIL threshold Δa_th (m/s²). [choice] 0.5, above docs/method.md §4.2's 0.1–0.2 for cars: calibrated
    to highD's truck lane-change rate (0.151 per km; with 0.2 trucks changed 0.56 per km, with 0.6 0.09)."""
    bias_mps2: float = number(0.3, 0.0, 5.0)
    """MOBIL keep-right bias Δa_bias (m/s²). [choice] 0.3, the top of docs/method.md §4.2's range (trucks keep right)."""
    safe_decel_mps2: float = number(4.0, 0.1, 20.0)
    """MOBIL b_safe (m/s²): 4, docs/method.md §4.2."""
    mobil_desired_speed_mps: float = number(24.13, 1.0, 40.0)
    """The desired speed MOBIL's accelerations use for every vehicle it compares (m/s; capped by the
    lane's limit). [choice] 24.13, the median of highD's per-truck mean speeds: MOBIL takes one v0."""
    overtake_deficit_mps: float = number(3.0, 0.0, 40.0)
    """A truck changes to the left (overtakes) only while at least this much below its own desired speed
    (m/s). [choice] 3: MOBIL takes one desired speed for every vehicle (``mobil_desired_speed_mps``), so
    without this a truck content at its own lower speed saw a gain in passing; with it, trucks changed
    lanes about three times as often per km as highD's (traffic_makeup.py, docs/bv-profiles.md)."""
    merge_stop_margin_m: float = number(50.0, 0.0, 200.0)
    """The merge lane's end is a standing leader this far before it (m), in the IDM and in MOBIL. [choice] 50:
    the map's merge lane narrows over its last 50 m, and a 2.5-m-wide truck standing there reaches into
    lane II (cars: 15 m, ``level0.merge_stop_margin_m``)."""
    decision_interval_steps: int = integer(5, 1, 1000)
    """A truck decides on lane changes every this many simulation steps (at steps that are multiples of it).
    [choice] 5 (0.5 s at dt = 0.1 s): a driver's reaction time; and the decision is the driver's costliest
    part (docs/performance.md)."""
    keep_off_left_lanes: int = integer(1, 0, 8)
    """A truck never changes into the leftmost this-many lanes. [choice] 1: German rules bar trucks over
    3.5 t from the left lane of a carriageway with three lanes or more (StVO §7(3c))."""


@dataclass(frozen=True)
class ApproachParams:
    """The cars' approach braking under ``bvs.makeup: highd`` (``models.truck`` holds the trucks'; these
    are module constants, docs/bv-profiles.md, "Traffic make-up": approach braking)."""

    trigger_mps2: float = 1.5
    """A car closing in on a perceived leader brakes once the constant deceleration that matches the
    leader's speed ``margin_m`` behind it reaches this (m/s²)."""
    margin_m: float = 5.0
    """Bumper gap at which the approach braking matches the leader's speed (m)."""


APPROACH = ApproachParams()


@dataclass(frozen=True)
class _Margin:
    merge_stop_margin_m: float
    """The merge lane's end is a standing leader this far before it (m): :attr:`TruckParams.merge_stop_margin_m`."""


def _mobil_params(p: TruckParams) -> MobilParams:
    return MobilParams(politeness=p.politeness, threshold_mps2=p.threshold_mps2, bias_mps2=p.bias_mps2,
                       safe_decel_mps2=p.safe_decel_mps2, desired_speed_mps=p.mobil_desired_speed_mps,
                       accel_mps2=p.accel_mps2, comfort_decel_mps2=p.comfort_decel_mps2,
                       time_headway_s=p.time_headway_s, min_gap_m=p.min_gap_m, delta=p.delta,
                       merge_stop_margin_m=p.merge_stop_margin_m)


class TruckDriver:
    """Truck drivers for world indices ``vehicles`` with desired speeds ``desired_speed_mps`` (module docstring)."""

    def __init__(self, vehicles, params: TruckParams, desired_speed_mps: np.ndarray, vehicle_params) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.params = params
        self.desired_speed_mps = np.asarray(desired_speed_mps, dtype=float).copy()
        self.vehicle_params = vehicle_params
        self.mobil = _mobil_params(params)
        self._mobil_kernel_args = (tuple(kernel_params(MobilKernelParams, self.mobil)),
                                   tuple(conflict_rule(self.mobil)))
        """What :func:`evoscen_sut.mobil.lane_change_decision` makes of the parameters each call, made once (plain
        tuples, as the kernel takes them: :func:`evoscen_sim.jit.plain`)."""
        self._margin = _Margin(float(params.merge_stop_margin_m))
        self._no_late: np.ndarray | None = None

    def restrict(self, positions: np.ndarray) -> None:
        """Host only the vehicles at ``positions`` of :attr:`vehicles`."""
        self.vehicles = self.vehicles[positions]
        self.desired_speed_mps = self.desired_speed_mps[positions]

    def accel(self, view, occ: np.ndarray | None = None) -> np.ndarray:
        """IDM acceleration of every hosted truck (m/s², at least ``-max_decel_mps2``); ``occ``: the view's
        :func:`evoscen_bv.car_following._occupancy`, if the caller has it."""
        if occ is None:
            gap, vl, _ = leaders(view, self.vehicles, self._margin)
        else:  # leaders() from the occupancy given
            if self._no_late is None or self._no_late.size != self.vehicles.size:
                self._no_late = np.zeros(self.vehicles.size, dtype=np.bool_)
            stop = float(view.road.lane_end_s[0]) - self._margin.merge_stop_margin_m
            gap, vl, _ = _nearest_leaders(self.vehicles, view.s, view.v, view.accel, view.lane, view.lane_change,
                                          view.target_lane, view.length, view.lane_lookup().present, stop, occ,
                                          _ALL_SEEN, 0, occ, self._no_late)
        p = self.params
        return _truck_accel(self.vehicles, np.asarray(view.v, dtype=float), self.desired_speed_mps, gap, vl,
                            p.time_headway_s, p.min_gap_m, p.accel_mps2, p.comfort_decel_mps2, p.delta,
                            p.max_decel_mps2)

    def step_args(self, view) -> tuple:
        """The trucks' part of :func:`_makeup_kernel`'s arguments: what :meth:`act` passes its kernels, the MOBIL
        request made here on a decision step (zeros otherwise, as :meth:`act` has them)."""
        if self._no_late is None or self._no_late.size != self.vehicles.size:
            self._no_late = np.zeros(self.vehicles.size, dtype=np.bool_)
        p = self.params
        vp = self.vehicle_params
        decide = int(view.step_index) % int(p.decision_interval_steps) == 0
        if decide and self.vehicles.size:
            nb = view.neighborhood()
            request = np.asarray(_mobil_decision_kernel(
                self.vehicles, view.s, view.d, view.v, view.length, view.lane, view.target_lane, view.lane_change,
                view.speed_limit_mps, nb.gap_front_m, nb.leader_speed_mps, nb.gap_rear_m, nb.follower,
                nb.follower_speed_mps, plain(view.road.kernel_tables()), *self._mobil_kernel_args), dtype=np.int64)
        else:
            request = np.zeros(self.vehicles.size, dtype=np.int64)
        return (self.vehicles, float(view.road.lane_end_s[0]) - self._margin.merge_stop_margin_m, self._no_late,
                _ALL_SEEN, self.desired_speed_mps, p.time_headway_s, p.min_gap_m, p.accel_mps2, p.comfort_decel_mps2,
                p.delta, p.max_decel_mps2, request, decide, float(p.overtake_deficit_mps),
                int(view.road.num_lanes) - int(p.keep_off_left_lanes), float(vp.max_accel_mps2), float(vp.max_brake_mps2))

    def act(self, view, occ: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} for each hosted truck (``occ`` as
        :meth:`accel`'s)."""
        if self.vehicles.size == 0:
            return np.zeros(0), np.zeros(0, dtype=np.int64)
        acc = self.accel(view, occ)
        *_, request, decide, deficit, top, max_accel, max_brake = self.step_args(view)  # the MOBIL request, once
        return _truck_commands(self.vehicles, acc, request, decide, np.asarray(view.v, dtype=float),
                               np.asarray(view.lane, dtype=np.int64), self.desired_speed_mps, deficit, top, max_accel,
                               max_brake)


@kernel
def _truck_commands(idx, acc, request, decide, v, lane, desired, deficit, top, max_accel, max_brake):
    """Throttle (the acceleration as a command, as :func:`evoscen_sim.physics.vehicle.accel_to_throttle`) and
    the lane-change request of each truck: MOBIL's, less a left change into the lanes from ``top`` on or
    while the truck is within ``deficit`` of its desired speed (off the merge lane)."""
    m = idx.shape[0]
    throttle = np.empty(m)
    out = np.zeros(m, dtype=np.int64)
    for k in range(m):
        a = acc[k]
        u = a / max_accel if a >= 0.0 else a / max_brake
        throttle[k] = min(max(u, -1.0), 1.0)
        if decide:
            r = request[k]
            i = idx[k]
            if r > 0 and (lane[i] + 1 >= top or (v[i] > desired[k] - deficit and lane[i] > 0)):
                r = 0
            out[k] = r
    return throttle, out


@kernel
def _truck_accel(idx, v, desired, gap, vl, time_headway, min_gap, accel, comfort_decel, delta, max_decel):
    """IDM behind each of the two leaders of :func:`leaders` (no leader: NaN speed), the lower one."""
    m = idx.shape[0]
    out = np.empty(m)
    for k in range(m):
        vi = v[idx[k]]
        a = idm_scalar(vi, desired[k], np.inf, np.nan, time_headway, min_gap, accel, comfort_decel, delta, max_decel)
        for c in range(2):
            if not np.isnan(vl[k, c]):
                a = min(a, idm_scalar(vi, desired[k], gap[k, c], vl[k, c], time_headway, min_gap, accel,
                                      comfort_decel, delta, max_decel))
        out[k] = a
    return out


class MakeupDriver:
    """The BVs of ``bvs.makeup: highd``: cars by ``car_driver``, trucks by a :class:`TruckDriver` (module docstring)."""

    def __init__(self, vehicles, truck: np.ndarray, car_driver, truck_driver: TruckDriver) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.truck = np.asarray(truck, dtype=bool).copy()
        self.car_driver = car_driver
        self.truck_driver = truck_driver
        self._car_pos: np.ndarray | None = None
        self._truck_pos: np.ndarray | None = None
        self._approach: tuple | None = None

    def restrict(self, positions: np.ndarray) -> None:
        """Host only the vehicles at ``positions`` of :attr:`vehicles` (before the first :meth:`act`)."""
        positions = np.asarray(positions, dtype=np.int64)
        car_rank = np.cumsum(~self.truck) - 1
        truck_rank = np.cumsum(self.truck) - 1
        keep = self.truck[positions]
        self.car_driver.restrict(car_rank[positions[~keep]])
        self.truck_driver.restrict(truck_rank[positions[keep]])
        self.vehicles = self.vehicles[positions]
        self.truck = keep
        self._car_pos = None

    def _layout(self) -> None:
        """Where the cars and the trucks sit in the answer (made once per restrict)."""
        self._car_pos = np.flatnonzero(~self.truck)
        self._truck_pos = np.flatnonzero(self.truck)
        self._approach = None

    def act(self, view) -> tuple[np.ndarray, np.ndarray]:
        """Throttle and lane-change request of every hosted vehicle: the cars' driver asked, then the cars' approach
        bound and the trucks' commands in one compiled call (:func:`_makeup_kernel`; the same kernels as
        :meth:`approach_bound` and :meth:`TruckDriver.act`, so the same bits; docs/performance.md "Per-step work
        of the world and of the BV drivers")."""
        if self._car_pos is None:
            self._layout()
        if self._car_pos.size:
            thr, lc = self.car_driver.act(view)
            car_thr, car_lc = np.asarray(thr, dtype=float), np.asarray(lc, dtype=np.int64)
        else:
            car_thr, car_lc = _NO_FLOATS, _NO_INTS
        idx, max_decel, brake, no_seen = self._approach_args()
        reaction = getattr(self.car_driver, "reaction", None)
        seen = reaction.seen if reaction is not None else None
        truck = self.truck_driver
        lk = view.lane_lookup()
        return _makeup_kernel(
            self.vehicles.size, self._car_pos, self._truck_pos, car_thr, car_lc, idx, view.s, view.d, view.psi, view.v,
            view.accel, view.lane, view.lane_change, view.target_lane, view.length, view.width, lk.d_right, lk.d_left,
            lk.present, seen if seen is not None else no_seen, seen is not None,
            reaction.n_react + 1 if seen is not None else 0, APPROACH.trigger_mps2, APPROACH.margin_m, max_decel, brake,
            *truck.step_args(view))

    def act_unfused(self, view) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`act` call by call (the cars' approach bound, the trucks' :meth:`TruckDriver.act`): what the fused
        call must equal (a test compares them)."""
        if self._car_pos is None:
            self._layout()
        throttle = np.zeros(self.vehicles.size)
        request = np.zeros(self.vehicles.size, dtype=np.int64)
        lk = view.lane_lookup()
        occ = _occupancy(view.s, view.d, view.psi, view.lane, view.lane_change, view.target_lane, view.length,
                         view.width, lk.d_right, lk.d_left, lk.present, -1)
        if self._car_pos.size:
            thr, lc = self.car_driver.act(view)
            throttle[self._car_pos] = self.approach_bound(view, np.asarray(thr, dtype=float), occ)
            request[self._car_pos] = lc
        if self._truck_pos.size:
            thr, lc = self.truck_driver.act(view, occ)
            throttle[self._truck_pos], request[self._truck_pos] = thr, lc
        return throttle, request

    def approach_bound(self, view, throttle: np.ndarray, occ: np.ndarray | None = None) -> np.ndarray:
        """The cars' ``throttle`` bounded by the approach braking (docs/bv-profiles.md, "Traffic make-up"):
        closing in at Δv on a leader it perceives (occupying its lane or its target lane ahead of it; under
        the ``driver`` profile once perceived, :class:`evoscen_bv.car_following.ReactionState`), a car brakes
        at least at b = Δv² / (2 (gap − margin)) once b reaches the trigger, at most ``max_decel_mps2`` of
        its profile (the full brake where the gap is already below the margin)."""
        car = self.car_driver
        idx, max_decel, brake, no_seen = self._approach_args()
        if occ is None:
            lk = view.lane_lookup()
            occ = _occupancy(view.s, view.d, view.psi, view.lane, view.lane_change, view.target_lane, view.length,
                             view.width, lk.d_right, lk.d_left, lk.present, -1)
        reaction = getattr(car, "reaction", None)
        seen = reaction.seen if reaction is not None else None
        full = reaction.n_react + 1 if seen is not None else 0
        return _approach_kernel(idx, view.s, view.v, view.lane, view.target_lane, view.length, occ,
                                seen if seen is not None else no_seen, seen is not None,
                                full, APPROACH.trigger_mps2, APPROACH.margin_m, max_decel, brake,
                                np.array(throttle, dtype=float))


    def _approach_args(self) -> tuple:
        """The approach bound's (cars, their profile's largest deceleration, the full brake, the ``seen`` of no
        profile), made once per :meth:`restrict`."""
        if self._approach is None:
            car = self.car_driver
            brake = float(car.vehicle_params.max_brake_mps2)
            profile = getattr(car, "profile", None)
            max_decel = brake if profile is None or profile.max_decel_mps2 is None else float(profile.max_decel_mps2)
            self._approach = (np.asarray(car.vehicles, dtype=np.int64), max_decel, brake,
                              np.zeros((1, 1, 1), dtype=np.int64))
        return self._approach


_NO_FLOATS = np.zeros(0)
_NO_INTS = np.zeros(0, dtype=np.int64)


@kernel
def _makeup_kernel(n_hosted, car_pos, truck_pos, car_thr, car_lc, car_idx, s, d, psi, v, a, lane, lane_change,
                   target_lane, length, width, d_right, d_left, present, seen, has_seen, full, trigger, margin, max_decel,
                   brake, truck_idx, stop, no_late, all_seen, desired, time_headway, min_gap, accel, comfort_decel, delta,
                   truck_max_decel, request, decide, deficit, top, max_accel, max_brake):
    """:meth:`MakeupDriver.act` after the cars' driver answered: the occupancy, the cars' approach bound
    (:func:`_approach_kernel`) and the trucks' leaders, IDM and commands (:meth:`TruckDriver.act`: ``request`` its
    MOBIL request, made by the caller on a decision step), each answer put at its vehicles' positions."""
    occ = _occupancy(s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left, present, -1)
    throttle = np.zeros(n_hosted)
    out = np.zeros(n_hosted, dtype=np.int64)
    if car_pos.shape[0] > 0:
        thr = _approach_kernel(car_idx, s, v, lane, target_lane, length, occ, seen, has_seen, full, trigger, margin,
                               max_decel, brake, car_thr.copy())
        for k in range(car_pos.shape[0]):
            throttle[car_pos[k]] = thr[k]
            out[car_pos[k]] = car_lc[k]
    if truck_pos.shape[0] > 0:
        gap, vl, _al = _nearest_leaders(truck_idx, s, v, a, lane, lane_change, target_lane, length, present, stop, occ,
                                        all_seen, 0, occ, no_late)
        acc = _truck_accel(truck_idx, v, desired, gap, vl, time_headway, min_gap, accel, comfort_decel, delta,
                           truck_max_decel)
        thr_t, req_t = _truck_commands(truck_idx, acc, request, decide, v, lane, desired, deficit, top, max_accel,
                                       max_brake)
        for k in range(truck_pos.shape[0]):
            throttle[truck_pos[k]] = thr_t[k]
            out[truck_pos[k]] = req_t[k]
    return throttle, out


@kernel
def _approach_kernel(idx, s, v, lane, target_lane, length, occ, seen, has_seen, full, trigger, margin, max_decel,
                     brake, throttle):
    """:meth:`MakeupDriver.approach_bound` over the cars ``idx`` (``throttle`` changed in place and returned)."""
    n = s.shape[0]
    for k in range(idx.shape[0]):
        i = idx[k]
        need = 0.0
        for j in range(n):
            if j == i or not (s[j] > s[i] or (s[j] == s[i] and j > i)):
                continue
            dv = v[i] - v[j]
            if dv <= 0.0:
                continue
            for c in range(2):
                q = lane[i] if c == 0 else target_lane[i]
                if c == 1 and q == lane[i]:
                    break
                if q < 0 or q >= occ.shape[1] or not occ[j, q]:
                    continue
                if has_seen and seen[k, j, q] < full:
                    continue
                room = s[j] - s[i] - 0.5 * (length[i] + length[j]) - margin
                b = dv * dv / (2.0 * room) if room > 0.0 else max_decel
                need = max(need, b)
        if need >= trigger:
            throttle[k] = min(throttle[k], -min(need, max_decel) / brake)
    return throttle


class CutShare:
    """A driver of all the make-up's cars whose answer is cut to a BV node's share of them (``restrict``):
    for a car driver whose random draws depend on how many vehicles it drives (the rule-based drivers'
    Krauss dawdling), so that the world does not depend on ``bvs.nodes``. Its other attributes are the
    driver's."""

    def __init__(self, driver) -> None:
        self.driver = driver
        self.positions: np.ndarray | None = None
        self.vehicles = np.asarray(driver.vehicles, dtype=np.int64)

    def restrict(self, positions: np.ndarray) -> None:
        positions = np.asarray(positions, dtype=np.int64)
        self.positions = positions if self.positions is None else self.positions[positions]
        self.vehicles = np.asarray(self.driver.vehicles, dtype=np.int64)[self.positions]

    def act(self, view) -> tuple[np.ndarray, np.ndarray]:
        throttle, request = self.driver.act(view)
        if self.positions is None:
            return throttle, request
        return np.asarray(throttle)[self.positions], np.asarray(request)[self.positions]

    def __getattr__(self, name: str):
        # only for attributes not found on the share itself; never while it is being unpickled or copied
        # (no ``driver`` yet: asking the driver for it would recurse)
        if name.startswith("__") or name == "driver":
            raise AttributeError(name)
        return getattr(self.driver, name)


def makeup_driver(vehicles, makeup, config, car_driver) -> MakeupDriver:
    """The ``highd`` make-up's driver of all BVs ``vehicles`` (registered for ``bvs.makeup: highd``):
    ``car_driver`` (``bvs.driver``, built for all BVs) takes the drawn desired speeds, uncapped, and
    keeps the cars; the trucks get a :class:`TruckDriver` (``models.truck``). A car driver with per-slot
    state (learned, level0) keeps a BV node's share by ``restrict``; a rule-based one (nilsson, mobil:
    ``drive_only``) drives all the cars in every BV node, its answer cut to the share (:class:`CutShare`)."""
    params = config.models.get("truck") or TruckParams()
    truck = np.asarray(makeup.truck, dtype=bool)
    car_driver.desired_speed_mps = np.asarray(makeup.desired_speed_mps, dtype=float).copy()
    car_driver.speed_cap = False
    if hasattr(car_driver, "restrict"):
        car_driver.restrict(np.flatnonzero(~truck))
    else:
        car_driver.drive_only(np.flatnonzero(~truck))
        car_driver = CutShare(car_driver)
    vehicles = np.asarray(vehicles, dtype=np.int64)
    trucks = TruckDriver(vehicles[truck], params, makeup.desired_speed_mps[truck], config.vehicle)
    return MakeupDriver(vehicles, truck, car_driver, trucks)
