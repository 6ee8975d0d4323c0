"""MOBIL lane changes (docs/method.md §4) with SUMO-Krauss car following.

MOBIL — "Minimizing Overall Braking Induced by Lane changes" (Kesting, Treiber, Helbing,
TRR 1999, 2007; docs/method.md §4.2). A vehicle ``c`` looks at the two *adjacent* lanes
only. With ``a`` the IDM acceleration (:func:`evoscen_sim.car_following.idm_acceleration`)
now and ``ã`` after the change, ``n`` the new follower (behind ``c`` in the target lane) and
``o`` the old follower (behind ``c`` in its lane), a change is

* **safe** when the new follower need not brake harder than ``b_safe``: ``ã_n ≥ −b_safe``;
* **advantageous** when (symmetric MOBIL, ``asymmetric = False``)
  ``ã_c − a_c + p·[(ã_n − a_n) + (ã_o − a_o)] > Δa_th``, or with the asymmetric
  keep-right / overtake-left rules (``asymmetric = True``, the default: traffic keeps right)
  to the right ``ã_c − a_c + p·(ã_o − a_o) > Δa_th − Δa_bias`` and to the left
  ``ã_c − a_c + p·(ã_n − a_n) > Δa_th + Δa_bias``, where "no overtaking on the right"
  caps the ego's acceleration in the right lane by its current-lane acceleration,
  ``ã_c ← min(ã_c, a_c)``, above the critical speed ``v_crit`` (Kesting et al. 2007, European
  rules).

The vehicle requests the lane (+1 left, −1 right) that passes both criteria with the larger
margin of the incentive over its threshold, else 0.

Readings and choices (all configurable through :class:`MobilParams`):

* **Accelerations.** Every vehicle's IDM acceleration uses this model's IDM parameters and
  desired speed (capped by the lane's speed limit at the ego's position): other drivers'
  own parameters are unknown to the deciding driver. Gaps are bumper to bumper
  (:mod:`evoscen_sim.neighbors`); a follower's gap to the vehicle ahead of the ego is its gap
  to the ego plus the ego's length plus the ego's gap to that vehicle. A missing follower
  contributes nothing (its terms are 0 and the safety criterion holds).
* **Own safety** [choice]: the ego also rejects a change where it would itself have to
  brake harder than ``b_safe`` behind the new leader (``ã_c ≥ −b_safe``); this also rejects
  a target lane whose leader overlaps the ego longitudinally (gap ≤ 0 gives IDM's maximum
  braking). MOBIL proper checks the new follower only.
* **Vehicles changing into the candidate lane** [choice] count as being in it for the
  safety criteria (the neighbourhood places a vehicle by its centre, so two vehicles
  could otherwise move into the same gap from both sides).
* **Target lanes.** Only adjacent lanes that exist at the ego's ``s``
  (``road.lane_exists``). A lane that ends ahead (the merge lane I, index 0) is never
  entered unless ``enter_ending_lane`` [choice: it is an acceleration lane, not a passing
  lane].
* **Merge-lane end** (mandatory change). A lane end is a standing obstacle
  ``merge_stop_margin_m`` before the lane ends, in the IDM acceleration of a vehicle in
  that lane (as :mod:`evoscen_bv.level0` does): as the end approaches ``a_c`` falls to
  maximum braking and the incentive to leave grows (MOBIL's own treatment of lane ends,
  Kesting et al. 2007). In addition, leaving an ending lane towards the through lanes
  gets the bias *towards* the target (threshold ``Δa_th − Δa_bias``: the bias models a
  mandatory change), and within ``merge_mandatory_distance_m`` of the stop point the
  incentive criterion is dropped (only the safety criteria count).
* A vehicle already changing lanes (``view.lane_change != 0``) requests 0, and one that has
  not yet settled near its lane's centre line after a change (``settle_tolerance_m``)
  requests 0 too [choice], except for a mandatory change.
* Among the vehicles one driver drives (the BV role), two requests into the same lane at
  the same step that would be unsafe for each other are resolved in favour of the vehicle
  ahead (:func:`resolve_conflicts`) [choice].

Parameter sources: docs/method.md §4.2: p = 0–0.5, Δa_th = 0.1–0.2 m/s²,
Δa_bias = 0.2–0.3 m/s², b_safe = 4 m/s²; IDM highway values v0 = 120 km/h, T = 1.0–1.5 s,
s0 = 2 m, a = 1.0 m/s², b = 1.5 m/s², δ = 4 (Treiber & Kesting, *Traffic Flow Dynamics*,
2013, Table 11.2).

Longitudinal control: SUMO's Krauss (:mod:`evoscen_sut.krauss`, docs/method.md §4: car following is
the same for every SUT), see :class:`KraussLaneChangeDriver`, which this module's and
:mod:`evoscen_sut.nilsson`'s drivers share.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from evoscen_sim.car_following import IdmParams, idm_acceleration, idm_scalar
from evoscen_sim.config import flag, number
from evoscen_sim.jit import kernel
from evoscen_sim.models import ModelSpec
from evoscen_sim.neighbors import LEFT, OWN, RIGHT
from evoscen_sim.scenario_params import vehicle_params_from_config
from evoscen_sim.vehicle import VehicleParams, accel_to_throttle

from .krauss import follow_speed_scalar, next_speed_scalar

IDM_MAX_DECEL_MPS2 = 9.0
"""Lower clip of the IDM accelerations MOBIL compares (m/s²; the IDM helper's default)."""


@dataclass(frozen=True)
class MobilParams:
    """MOBIL parameters (``models.mobil`` in the scenario YAML)."""

    politeness: float = number(0.25, 0.0, 5.0)
    """Politeness factor p (-). Default 0.25, mid-range of docs/method.md §4.2's p = 0–0.5."""
    threshold_mps2: float = number(0.1, 0.0, 5.0)
    """Changing threshold Δa_th (m/s²). Default 0.1, docs/method.md §4.2 (0.1–0.2)."""
    bias_mps2: float = number(0.2, 0.0, 5.0)
    """Keep-right bias Δa_bias of the asymmetric variant (m/s²). Default 0.2, docs/method.md §4.2 (0.2–0.3)."""
    safe_decel_mps2: float = number(4.0, 0.0, 20.0, lo_open=True)
    """Safe deceleration b_safe (m/s²): the new follower's ã_n ≥ −b_safe. Default 4, docs/method.md §4.2."""
    asymmetric: bool = flag(True)
    """Use the asymmetric keep-right / overtake-left criteria (docs/method.md §4.2); False: symmetric MOBIL."""
    critical_speed_mps: float = number(60.0 / 3.6, 0.0, 40.0)
    """Above this speed the ego may not overtake on the right: ã_c ← min(ã_c, a_c) for a change
    to the right (m/s). Default 60 km/h (Kesting, Treiber, Helbing 2007, European rules)."""
    desired_speed_mps: float = number(120.0 / 3.6, 0.0, 40.0, lo_open=True)
    """IDM desired speed v0 (m/s), capped by the lane's speed limit. Default 120 km/h, docs/method.md §4.2."""
    accel_mps2: float = number(1.0, 0.0, 10.0, lo_open=True)
    """IDM maximum acceleration a (m/s²). Default 1.0, docs/method.md §4.2 highway value."""
    comfort_decel_mps2: float = number(1.5, 0.0, 10.0, lo_open=True)
    """IDM comfortable deceleration b (m/s²). Default 1.5, docs/method.md §4.2 highway value."""
    time_headway_s: float = number(1.0, 0.0, 5.0, lo_open=True)
    """IDM safe time headway T (s). Default 1.0, docs/method.md §4.2 highway range 1.0–1.5 (Treiber &
    Kesting 2013, Table 11.2), equal to Krauss' τ = 1 s."""
    min_gap_m: float = number(2.0, 0.0, 20.0)
    """IDM standstill gap s0 (m). Default 2, docs/method.md §4.2."""
    delta: float = number(4.0, 0.0, 10.0, lo_open=True)
    """IDM acceleration exponent δ (-). Default 4, docs/method.md §4.2."""
    merge_stop_margin_m: float = number(15.0, 0.0, 200.0)
    """A lane end acts as a standing obstacle this far before it (m), in the MOBIL
    accelerations and in the Krauss command. Default 15, as the level-0 driver
    (``level0.merge_stop_margin_m``)."""
    merge_mandatory_distance_m: float = number(100.0, 0.0, 1000.0)
    """Within this distance of an ending lane's stop point, leaving it needs only the safety
    criteria (m) [choice]. Default 100 m (4 s at 25 m/s)."""
    enter_ending_lane: bool = flag(False)
    """Allow changes into a lane that ends ahead (the merge lane) [choice: no]."""
    settle_tolerance_m: float = number(0.5, 0.0, 10.0)
    """A new change is requested only with the centre within this distance of the lane's
    centre line (m) [choice]; not applied to a mandatory change."""

    @property
    def idm(self) -> IdmParams:
        """The IDM parameters of the MOBIL accelerations."""
        return IdmParams(time_headway_s=self.time_headway_s, min_gap_m=self.min_gap_m, accel_mps2=self.accel_mps2,
                         comfort_decel_mps2=self.comfort_decel_mps2, delta=self.delta)


@dataclass(frozen=True)
class MobilEvaluation:
    """MOBIL's terms for ``k`` vehicles and the candidate offsets ``-1, 0, +1`` (columns 0, 1, 2).

    Column 1 (own lane) holds the current values (``a_c`` in ``acc_ego``); the change columns
    hold the values after a change. Missing followers give 0 in their terms.
    """

    exists: np.ndarray
    """(k, 3) bool: the candidate lane exists at the vehicle's s (and may be entered)."""
    acc_ego: np.ndarray
    """(k, 3) ego acceleration in the candidate lane (a_c in column 1, ã_c in the others)."""
    gain_new_follower: np.ndarray
    """(k, 3) ã_n − a_n of the candidate lane's follower."""
    gain_old_follower: np.ndarray
    """(k, 1) ã_o − a_o of the own lane's follower (same for both directions)."""
    acc_new_follower: np.ndarray
    """(k, 3) ã_n (0 without follower)."""
    incentive: np.ndarray
    """(k, 3) incentive minus its threshold (> 0: advantageous); column 1 is 0."""
    safe: np.ndarray
    """(k, 3) safety criteria hold."""
    mandatory: np.ndarray
    """(k,) the vehicle must leave an ending lane (incentive waived)."""


_OFFSETS = np.array([-1, 0, 1], dtype=np.int64)
_COLS = np.array([RIGHT, OWN, LEFT], dtype=np.int64)


def _idm(params: MobilParams, v: np.ndarray, v0: np.ndarray, gap: np.ndarray, v_lead: np.ndarray) -> np.ndarray:
    v, v0, gap, v_lead = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (v, v0, gap, v_lead)))
    return idm_acceleration(np.ascontiguousarray(v), np.ascontiguousarray(v0), np.ascontiguousarray(gap),
                            np.ascontiguousarray(v_lead), params.idm, IDM_MAX_DECEL_MPS2)


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


# ------------------------------------------------------------------------------------ compiled
# The decision runs as one compiled kernel over the view's arrays (:mod:`evoscen_sim.jit`): for
# one or twenty vehicles numpy's per-call overhead, not arithmetic, dominated the vectorised
# form. The kernels compute exactly the expressions of the vectorised form (same operations in
# the same order, fastmath off), so the results are bit-identical. Road look-ups use the road
# model's tables as :class:`evoscen_sim.road.RoadModel` does (``_seg``: the last breakpoint
# ``<= clip(s, 0, length)``).

def _road_tables(road: Any) -> tuple:
    """The road model's lane tables the kernels read (cached on the road object)."""
    tables = getattr(road, "_evoscen_sut_tables", None)
    if tables is None:
        tables = (np.ascontiguousarray(road._breaks), np.ascontiguousarray(road._present),
                  np.ascontiguousarray(road._vmax), np.ascontiguousarray(road.lane_end_s, dtype=float),
                  np.ascontiguousarray(road._reaches_end), float(road.length_m),
                  np.ascontiguousarray(road._w_coef), np.ascontiguousarray(road._w_origin),
                  np.ascontiguousarray(road._off_coef), np.ascontiguousarray(road._off_origin))
        try:
            road._evoscen_sut_tables = tables
        except AttributeError:  # pragma: no cover - a road object without a __dict__
            pass
    return tables


@lru_cache(maxsize=64)
def _mobil_param_array(p: MobilParams) -> np.ndarray:
    """MOBIL parameters as one float array (the kernels' ``prm``; indices ``_P_*``)."""
    return np.array([p.politeness, p.threshold_mps2, p.bias_mps2, p.safe_decel_mps2, float(p.asymmetric),
                     p.critical_speed_mps, p.desired_speed_mps, p.accel_mps2, p.comfort_decel_mps2,
                     p.time_headway_s, p.min_gap_m, p.delta, p.merge_stop_margin_m,
                     p.merge_mandatory_distance_m, float(p.enter_ending_lane), p.settle_tolerance_m], dtype=float)


(_P_POL, _P_THR, _P_BIAS, _P_BSAFE, _P_ASYM, _P_VCRIT, _P_V0, _P_ACC, _P_DEC, _P_T, _P_S0, _P_DELTA, _P_MARGIN,
 _P_MAND, _P_ENTER, _P_SETTLE) = range(16)

_FLOAT_MAX = float(np.finfo(np.float64).max)
assert (RIGHT, OWN, LEFT) == (1, 2, 3)  # the kernels use neighbourhood column 2 + offset


@kernel
def _np_min(a, b):  # noqa: ANN001, ANN202
    """``np.minimum`` of two floats (NaN propagates, the first NaN wins)."""
    if np.isnan(a):
        return a
    if np.isnan(b):
        return b
    return min(a, b)


@kernel
def _np_max(a, b):  # noqa: ANN001, ANN202
    """``np.maximum`` of two floats (NaN propagates, the first NaN wins)."""
    if np.isnan(a):
        return a
    if np.isnan(b):
        return b
    return max(a, b)


@kernel
def _nan_to_num(x):  # noqa: ANN001, ANN202
    """``np.nan_to_num(x, nan=0.0)`` of one float."""
    if np.isnan(x):
        return 0.0
    if x == np.inf:
        return _FLOAT_MAX
    if x == -np.inf:
        return -_FLOAT_MAX
    return x


@kernel
def _road_seg(s, breaks, road_length):  # noqa: ANN001, ANN202
    """``RoadModel._seg(clip(s, 0, length))``: index of the lane-table row at ``s``."""
    sc = min(max(s, 0.0), road_length)
    return np.searchsorted(breaks, sc, side="right") - 1


@kernel
def _lane_end_dist(lane, s, lane_end_s, reaches_end):  # noqa: ANN001, ANN202
    """``RoadModel.distance_to_lane_end`` with NaN (invalid lane) mapped to ``inf``."""
    if lane < 0 or lane >= lane_end_s.shape[0]:
        return np.inf
    if reaches_end[lane]:
        return np.inf
    return lane_end_s[lane] - s


@kernel
def _settled_scalar(s, d, lane, tol, breaks, road_length, w_coef, w_origin, off_coef, off_origin):  # noqa: ANN001, ANN202, PLR0913
    """:func:`settled` for one vehicle: ``RoadModel.lane_center_d`` (``_bounds_all``) at ``max(s, 0)``."""
    nl = w_coef.shape[1]
    if lane < 0 or lane >= nl:
        return False  # NaN centre
    sc = min(max(max(s, 0.0), 0.0), road_length)
    j = np.searchsorted(breaks, sc, side="right") - 1
    do = sc - off_origin[j]
    oc = off_coef[j]
    off = oc[0] + do * (oc[1] + do * (oc[2] + do * oc[3]))
    cs = 0.0
    w_lane = 0.0
    for q in range(nl - 1, lane - 1, -1):  # cs[lane] = cumsum of the widths from the last lane
        c = w_coef[j, q]
        x = sc - w_origin[j, q]
        w = max(c[0] + x * (c[1] + x * (c[2] + x * c[3])), 0.0)
        cs = w if q == nl - 1 else cs + w
        w_lane = w
    d_right = off - cs
    d_left = d_right + w_lane
    centre = 0.5 * (d_right + d_left)
    return abs(d - centre) <= tol


@kernel
def _idm_p(v, v0, gap, v_lead, prm):  # noqa: ANN001, ANN202
    """MOBIL's IDM (:func:`_idm`) for one vehicle."""
    return idm_scalar(v, v0, gap, v_lead, prm[_P_T], prm[_P_S0], prm[_P_ACC], prm[_P_DEC], prm[_P_DELTA],
                      IDM_MAX_DECEL_MPS2)


@kernel
def _argmax_first(x):  # noqa: ANN001, ANN202
    """``np.argmax`` of a 1-d float array (the first maximum; the first NaN if any)."""
    best = 0
    bv = x[0]
    if np.isnan(bv):
        return 0
    for q in range(1, x.shape[0]):
        if np.isnan(x[q]):
            return q
        if x[q] > bv:
            best = q
            bv = x[q]
    return best


@kernel
def _mobil_kernel(idx, s, v, length, lane, target_lane, speed_limit, gap_front, leader_speed, gap_rear,  # noqa: ANN001, ANN202, PLR0913, PLR0915
                  follower, follower_speed, breaks, present, vmax, lane_end_s, reaches_end, road_length, prm):
    """:func:`evaluate` over the vehicles ``idx`` (module docstring); arrays as :class:`MobilEvaluation`."""
    k = idx.shape[0]
    n = s.shape[0]
    nl = present.shape[1]
    exists = np.zeros((k, 3), dtype=np.bool_)
    acc_ego = np.empty((k, 3))
    gain_n = np.empty((k, 3))
    gain_o = np.empty((k, 1))
    at_n = np.empty((k, 3))
    inc = np.zeros((k, 3))
    safe = np.empty((k, 3), dtype=np.bool_)
    mandatory = np.empty(k, dtype=np.bool_)
    moving = np.empty(n, dtype=np.int64)  # vehicles changing into another lane
    m = 0
    for j in range(n):
        if target_lane[j] != lane[j]:
            moving[m] = j
            m += 1
    end_gap = np.empty(3)
    ending = np.empty(3, dtype=np.bool_)
    v0 = np.empty(3)
    gap_f = np.empty(3)
    v_f = np.empty(3)
    gap_r = np.empty(3)
    has_r = np.empty(3, dtype=np.bool_)
    v_r = np.empty(3)
    margin = prm[_P_MARGIN]
    b_safe = prm[_P_BSAFE]
    for r in range(k):
        i = idx[r]
        si = s[i]
        vi = v[i]
        li = lane[i]
        half = 0.5 * length[i]
        seg = _road_seg(si, breaks, road_length)
        # candidate lanes: exist at s; lane-end gaps (inf where not existing)
        for c in range(3):
            ln = li + c - 1
            ex = ln >= 0 and ln < nl and present[seg, ln]
            exists[r, c] = ex
            lq = ln if ex else li
            eg = _lane_end_dist(lq, si, lane_end_s, reaches_end) - margin - half
            end_gap[c] = eg if ex else np.inf
            ending[c] = np.isfinite(end_gap[c])
        if prm[_P_ENTER] == 0.0:
            exists[r, 0] = exists[r, 0] and not ending[0]
            exists[r, 2] = exists[r, 2] and not ending[2]
        for c in range(3):
            ln = li + c - 1
            lq = ln if exists[r, c] else li
            limit = vmax[seg, lq] if (lq >= 0 and lq < nl) else np.nan
            if not np.isfinite(limit):
                limit = speed_limit[i]
            v0[c] = _np_min(prm[_P_V0], limit)
            col = 1 + c
            gap_f[c] = gap_front[i, col]
            v_f[c] = _nan_to_num(leader_speed[i, col])
            gap_r[c] = gap_rear[i, col]
            has_r[c] = follower[i, col] >= 0
            v_r[c] = _nan_to_num(follower_speed[i, col]) if has_r[c] else 0.0
        # ego: a_c and ã_c, each with the lane end as an obstacle
        for c in range(3):
            a = _idm_p(vi, v0[c], gap_f[c], v_f[c], prm)
            if ending[c]:
                a = _np_min(a, _idm_p(vi, v0[c], end_gap[c], 0.0, prm))
            acc_ego[r, c] = a
        a_c = acc_ego[r, 1]
        # new follower n
        for c in range(3):
            gap_through = gap_r[c] + length[i] + gap_f[c]
            if has_r[c]:
                a_n = _idm_p(v_r[c], v0[c], gap_through, v_f[c], prm)
                atn = _idm_p(v_r[c], v0[c], gap_r[c], vi, prm)
            else:
                a_n = 0.0
                atn = 0.0
            at_n[r, c] = atn
            gain_n[r, c] = atn - a_n
        # old follower o
        if has_r[1]:
            a_o = _idm_p(v_r[1], v0[1], gap_r[1], vi, prm)
            at_o = _idm_p(v_r[1], v0[1], gap_r[1] + length[i] + gap_f[1], v_f[1], prm)
            g_o = at_o - a_o
        else:
            g_o = 0.0
        gain_o[r, 0] = g_o
        pol = prm[_P_POL]
        thr = prm[_P_THR]
        bias = prm[_P_BIAS]
        if prm[_P_ASYM] != 0.0:
            at_c0 = acc_ego[r, 0]
            if vi > prm[_P_VCRIT]:
                at_c0 = _np_min(at_c0, a_c)
            inc[r, 0] = at_c0 - a_c + pol * g_o - (thr - bias)
            left_thr = thr - bias if ending[1] else thr + bias
            inc[r, 2] = acc_ego[r, 2] - a_c + pol * gain_n[r, 2] - left_thr
        else:
            for c in (0, 2):
                inc[r, c] = acc_ego[r, c] - a_c + pol * (gain_n[r, c] + g_o) - thr
        # safety criteria, also against the vehicles changing into each candidate lane
        for c in range(3):
            ok = at_n[r, c] >= -b_safe and acc_ego[r, c] >= -b_safe
            if ok:
                ln = li + c - 1
                for q in range(m):
                    j = moving[q]
                    if j == i or target_lane[j] != ln:
                        continue
                    ds = s[j] - si
                    gap = abs(ds) - 0.5 * (length[j] + length[i])
                    if ds > 0.0:
                        acc = _idm_p(vi, v0[c], gap, v[j], prm)
                    else:
                        acc = _idm_p(v[j], v0[c], gap, vi, prm)
                    if acc < -b_safe:
                        ok = False
                        break
            safe[r, c] = ok
        safe[r, 1] = True
        mandatory[r] = ending[1] and end_gap[1] < prm[_P_MAND]
    return exists, acc_ego, gain_n, gain_o, at_n, inc, safe, mandatory


@kernel
def _mobil_unsafe_pair(s, v, length, a, b, prm):  # noqa: ANN001, ANN202
    """MOBIL's conflict test of the row vehicle ``a`` and the column vehicle ``b`` (world indices)."""
    ds = s[b] - s[a]
    gap = abs(ds) - 0.5 * (length[b] + length[a])
    if ds > 0.0:
        acc = _idm_p(v[a], prm[_P_V0], gap, v[b], prm)
    else:
        acc = _idm_p(v[b], prm[_P_V0], gap, v[a], prm)
    return acc < -prm[_P_BSAFE]


@kernel
def _nilsson_unsafe_pair(s, v, length, a, b, prm):  # noqa: ANN001, ANN202
    """Nilsson's conflict test (``prm = (safety_length_factor, safety_closing_headway_s)``)."""
    ds = s[b] - s[a]
    closing = v[a] - v[b] if ds > 0.0 else v[b] - v[a]
    need = prm[0] * length[a] + prm[1] * max(closing, 0.0)
    return abs(ds) < need


@kernel
def _resolve_kernel(idx, request, lane, s, v, length, nilsson_rule, prm):  # noqa: ANN001, ANN202, PLR0913
    """:func:`resolve_conflicts` with MOBIL's (or, ``nilsson_rule``, Nilsson's) pair test."""
    k = idx.shape[0]
    out = request.copy()
    cnt = 0
    for a in range(k):
        if request[a] != 0:
            cnt += 1
    if cnt < 2:
        return out
    for a in range(k):
        if request[a] == 0:
            continue
        ia = idx[a]
        ta = lane[ia] + request[a]
        for b in range(k):
            if b == a or request[b] == 0:
                continue
            ib = idx[b]
            if lane[ib] + request[b] != ta:
                continue
            ds = s[ib] - s[ia]
            if not (ds > 0.0 or (ds == 0.0 and ib < ia)):
                continue
            if nilsson_rule:
                unsafe = _nilsson_unsafe_pair(s, v, length, ia, ib, prm)
            else:
                unsafe = _mobil_unsafe_pair(s, v, length, ia, ib, prm)
            if unsafe:
                out[a] = 0
                break
    return out


@kernel
def _mobil_decision_kernel(idx, s, d, v, length, lane, target_lane, lane_change, speed_limit, gap_front,  # noqa: ANN001, ANN202, PLR0913
                           leader_speed, gap_rear, follower, follower_speed, breaks, present, vmax, lane_end_s,
                           reaches_end, road_length, w_coef, w_origin, off_coef, off_origin, prm):
    """:func:`lane_change_decision` (evaluation, choice, settling and conflicts) in one pass."""
    exists, _acc_ego, _gain_n, _gain_o, _at_n, inc, safe, mandatory = _mobil_kernel(
        idx, s, v, length, lane, target_lane, speed_limit, gap_front, leader_speed, gap_rear, follower,
        follower_speed, breaks, present, vmax, lane_end_s, reaches_end, road_length, prm)
    k = idx.shape[0]
    request = np.zeros(k, dtype=np.int64)
    score = np.empty(3)
    for r in range(k):
        for c in range(3):
            ok = c != 1 and exists[r, c] and safe[r, c] and (inc[r, c] > 0.0 or mandatory[r])
            sc = inc[r, c] if ok else -np.inf
            if ok and mandatory[r]:
                sc = _np_max(sc, 0.0) + 1e6
            score[c] = sc
        best = _argmax_first(score)
        req = best - 1 if np.isfinite(score[best]) else 0
        i = idx[r]
        if lane_change[i] != 0:
            req = 0
        if req != 0 and not mandatory[r] and not _settled_scalar(
                s[i], d[i], lane[i], prm[_P_SETTLE], breaks, road_length, w_coef, w_origin, off_coef, off_origin):
            req = 0
        request[r] = req
    return _resolve_kernel(idx, request, lane, s, v, length, False, prm)


def _view_args(view: Any) -> tuple:
    """The view's arrays the MOBIL kernels read, in their argument order (``s`` .. ``follower_speed``)."""
    nb = view.neighborhood()
    return (view.s, view.v, view.length, view.lane, view.target_lane, view.speed_limit_mps, nb.gap_front_m,
            nb.leader_speed_mps, nb.gap_rear_m, nb.follower, nb.follower_speed_mps)


def evaluate(view: Any, vehicles: np.ndarray, params: MobilParams) -> MobilEvaluation:
    """MOBIL's accelerations, incentives and safety criteria (see the module docstring)."""
    idx = np.asarray(vehicles, dtype=np.int64)
    breaks, present, vmax, lane_end_s, reaches_end, road_length = _road_tables(view.road)[:6]
    exists, acc_ego, gain_n, gain_o, at_n, inc, safe, mandatory = _mobil_kernel(
        idx, *_view_args(view), breaks, present, vmax, lane_end_s, reaches_end, road_length,
        _mobil_param_array(params))
    return MobilEvaluation(exists=exists, acc_ego=acc_ego, gain_new_follower=gain_n, gain_old_follower=gain_o,
                           acc_new_follower=at_n, incentive=inc, safe=safe, mandatory=mandatory)


def lane_change_decision(view: Any, vehicles: np.ndarray, params: MobilParams) -> np.ndarray:
    """MOBIL's lane-change request (+1 left, −1 right, 0 keep) for each of ``vehicles``.

    The lane offering the larger margin of incentive over threshold among those passing the
    criteria (:func:`evaluate`), a mandatory change preferred; 0 while a change is in progress or
    the vehicle has not settled (:func:`settled`, except for a mandatory change); two
    conflicting requests of the given vehicles resolved by :func:`resolve_conflicts` with the
    pair test "the rear vehicle's IDM deceleration (desired speed ``v0``) exceeds ``b_safe``".
    """
    idx = np.asarray(vehicles, dtype=np.int64)
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64)
    nb = view.neighborhood()
    return _mobil_decision_kernel(idx, view.s, view.d, view.v, view.length, view.lane, view.target_lane,
                                  view.lane_change, view.speed_limit_mps, nb.gap_front_m, nb.leader_speed_mps,
                                  nb.gap_rear_m, nb.follower, nb.follower_speed_mps, *_road_tables(view.road),
                                  _mobil_param_array(params))


def settled(view: Any, vehicles: np.ndarray, tolerance_m: float) -> np.ndarray:
    """True where a vehicle's centre is within ``tolerance_m`` of its lane's centre line: a new
    change is requested only once the previous one has settled [choice] (the world completes a
    change when the centre crosses into the target lane, while the vehicle is still moving
    across; reversing there produced ping-pong changes and side-by-side conflicts)."""
    centre = view.road.lane_center_d(view.lane[vehicles], np.maximum(view.s[vehicles], 0.0))
    return np.abs(view.d[vehicles] - centre) <= tolerance_m


def resolve_conflicts(view: Any, vehicles: np.ndarray, request: np.ndarray,
                      unsafe_pair: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Requests of one driver's vehicles into the same lane at the same step, resolved [choice].

    Decisions of one step are taken from the same state, so two vehicles can each find a gap
    safe and move into it together from both sides. Of two requesting vehicles with the same
    target lane whose pair is unsafe (``unsafe_pair(world indices) -> (m, m) bool``), the one
    ahead keeps its request (the lower index when level) and the other keeps its lane.
    """
    moving = np.flatnonzero(request != 0)
    if moving.size < 2:
        return request
    i = vehicles[moving]
    target = view.lane[i] + request[moving]
    conflict = (target[:, None] == target[None, :]) & np.asarray(unsafe_pair(i), dtype=bool)
    np.fill_diagonal(conflict, False)
    ds = view.s[i][None, :] - view.s[i][:, None]  # > 0: the column vehicle is ahead of the row vehicle
    yields = np.any(conflict & ((ds > 0.0) | ((ds == 0.0) & (i[None, :] < i[:, None]))), axis=1)
    out = request.copy()
    out[moving[yields]] = 0
    return out


# ------------------------------------------------------------------------------------ driver
class KraussLaneChangeDriver:
    """A lane-change decision model on top of SUMO-Krauss car following (every SUT's longitudinal control).

    Longitudinal command, for each driven vehicle: the Krauss acceleration behind the leader
    in its lane; while a lane change is in progress also behind the leader in the target
    lane (the smaller of the two); on a lane that ends (merge lane) and not changing,
    capped by Krauss' safe speed behind a standing obstacle ``stop_margin_m`` before the
    lane end (:func:`evoscen_sut.krauss.sumo_follow_speed` with leader speed 0, acceleration
    ``(v_safe − v) / dt``), so a vehicle that finds no gap waits there. The acceleration is
    mapped to throttle/brake by :func:`evoscen_sim.vehicle.accel_to_throttle`.

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

    def acceleration(self, view: Any) -> np.ndarray:
        """Desired acceleration (m/s²) of every driven vehicle (see the class docstring)."""
        if self._compiled_krauss():
            return self._acceleration_throttle(view)[0]
        return self._acceleration_generic(view)

    def _acceleration_generic(self, view: Any) -> np.ndarray:
        """:meth:`acceleration` for any car follower with ``KraussCarFollowing``'s interface."""
        from .krauss import sumo_follow_speed

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
        from .krauss import KraussCarFollowing

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
        road = _road_tables(view.road)
        return _krauss_lc_kernel(idx, u, u_target, view.s, view.v, view.length, lane, target_lane,
                                 view.speed_limit_mps, nb.gap_front_m, nb.leader_speed_mps, road[3], road[4],
                                 _krauss_param_array(kr.params, self.vehicle_params, self.stop_margin_m,
                                                     float(kr.dt_s), float(view.dt_s)))

    def act(self, view: Any) -> tuple[np.ndarray, np.ndarray]:
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} for each driven vehicle."""
        request = self.decide(view, self.vehicles, self.params)
        if self._compiled_krauss():
            throttle = self._acceleration_throttle(view)[1]
        else:
            throttle = accel_to_throttle(self._acceleration_generic(view), self.vehicle_params)
        return throttle, request


_NO_DRAWS = np.zeros(0)


@lru_cache(maxsize=64)
def _krauss_param_array(kp: Any, vp: VehicleParams, stop_margin_m: float, dt_s: float, view_dt_s: float) -> np.ndarray:
    """Parameters of :func:`_krauss_lc_kernel` as one float array."""
    return np.array([kp.min_gap_m, kp.accel_mps2, kp.decel_mps2, kp.emergency_decel_mps2, kp.sigma, kp.tau_s,
                     kp.desired_speed_mps, dt_s, view_dt_s, stop_margin_m, vp.max_accel_mps2, vp.max_brake_mps2],
                    dtype=float)


@kernel
def _count_changing(idx, lane, target_lane):  # noqa: ANN001, ANN202
    """How many of the vehicles ``idx`` are changing lanes (``target_lane != lane``)."""
    cnt = 0
    for q in range(idx.shape[0]):
        i = idx[q]
        if target_lane[i] != lane[i]:
            cnt += 1
    return cnt


@kernel
def _krauss_lc_kernel(idx, u, u_target, s, v, length, lane, target_lane, speed_limit, gap_front,  # noqa: ANN001, ANN202, PLR0913
                      leader_speed, lane_end_s, reaches_end, prm):
    """:class:`KraussLaneChangeDriver`'s acceleration and throttle (class docstring)."""
    min_gap, accel, decel, emergency, sigma, tau = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5]
    desired, dt, view_dt, margin, max_accel, max_brake = prm[6], prm[7], prm[8], prm[9], prm[10], prm[11]
    m = idx.shape[0]
    acc = np.empty(m)
    throttle = np.empty(m)
    q = 0
    for k in range(m):
        i = idx[k]
        vi = v[i]
        lim = speed_limit[i]
        v_max = desired if np.isnan(lim) else (lim if np.isnan(desired) else min(lim, desired))  # np.fmin
        v_next = next_speed_scalar(vi, v_max, gap_front[i, 2] - min_gap, leader_speed[i, 2], u[k], accel, decel,
                                   emergency, sigma, tau, dt)
        a = (v_next - vi) / dt
        offset = min(max(target_lane[i] - lane[i], -1), 1)
        if offset != 0:
            col = 2 + offset
            v_next = next_speed_scalar(vi, v_max, gap_front[i, col] - min_gap, leader_speed[i, col], u_target[q],
                                       accel, decel, emergency, sigma, tau, dt)
            q += 1
            a = _np_min(a, (v_next - vi) / dt)
        else:
            end_gap = _lane_end_dist(lane[i], s[i], lane_end_s, reaches_end) - margin - 0.5 * length[i]
            if np.isfinite(end_gap):
                v_safe = follow_speed_scalar(end_gap - min_gap, vi, 0.0, decel, emergency, tau, view_dt)
                a = _np_min(a, (_np_max(v_safe, 0.0) - vi) / view_dt)
        acc[k] = a
        cmd = _np_max(a, 0.0) * (1.0 / max_accel) + _np_min(a, 0.0) * (1.0 / max_brake)  # accel_to_throttle
        throttle[k] = _np_min(_np_max(cmd, -1.0), 1.0)
    return acc, throttle


def krauss_for(config: Any, rng: np.random.Generator) -> Any:
    """The Krauss car follower of a scenario (parameters from ``models.krauss`` if present)."""
    from . import krauss

    kp = None
    if hasattr(config, "models"):
        kp = config.models.get("krauss")
    if kp is None:
        from_config = getattr(krauss, "krauss_params_from_config", None)
        kp = from_config(config) if from_config is not None else krauss.KraussParams()
    return krauss.KraussCarFollowing(kp, rng, config.dt_s)


def lane_change_factory(decision: Any, params_type: type) -> Any:
    """A :class:`evoscen_sim.models.ModelSpec` factory: ``decision`` plus Krauss car following.

    Shared by the rule-based models (MOBIL, Nilsson), which differ only in their decision.
    """
    def make_driver(vehicles: np.ndarray, params: Any, config: Any,
                    rng: np.random.Generator) -> KraussLaneChangeDriver:
        params = params_type() if params is None else params
        return KraussLaneChangeDriver(vehicles, decision, params, krauss_for(config, rng),
                                      vehicle_params_from_config(config), params.merge_stop_margin_m)

    make_driver.__module__ = decision.__module__  # the factory belongs to its model's module
    make_driver.__qualname__ = "make_driver"
    return make_driver


make_driver = lane_change_factory(lane_change_decision, MobilParams)
"""Factory of the ``mobil`` model (:class:`evoscen_sim.models.ModelSpec`)."""


SPEC = ModelSpec(
    name="mobil",
    roles=("sut", "bv"),
    factory=make_driver,
    params_type=MobilParams,
    description="MOBIL lane changes (IDM accelerations, keep-right variant) + Krauss car following (docs/method.md §4)",
)
