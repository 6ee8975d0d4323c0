"""MOBIL lane changes (docs/method.md §4) with SUMO-Krauss car following.

MOBIL — "Minimizing Overall Braking Induced by Lane changes" (Kesting, Treiber, Helbing,
TRR 1999, 2007; docs/method.md §4.2). A vehicle ``c`` looks at the two *adjacent* lanes
only. With ``a`` the IDM acceleration (:func:`evoscen_sim.physics.idm.idm_acceleration`)
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
  (:mod:`evoscen_sim.physics.neighbors`); a follower's gap to the vehicle ahead of the ego is its gap
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
  ahead (:mod:`evoscen_sut.conflicts`, pair test :func:`conflict_rule`) [choice].

Parameter sources: docs/method.md §4.2: p = 0–0.5, Δa_th = 0.1–0.2 m/s²,
Δa_bias = 0.2–0.3 m/s², b_safe = 4 m/s²; IDM highway values v0 = 120 km/h, T = 1.0–1.5 s,
s0 = 2 m, a = 1.0 m/s², b = 1.5 m/s², δ = 4 (Treiber & Kesting, *Traffic Flow Dynamics*,
2013, Table 11.2).

Longitudinal control: SUMO's Krauss (:mod:`evoscen_sut.krauss`, docs/method.md §4: car following is
the same for every SUT), see :class:`evoscen_sut.krauss_lane_change.KraussLaneChangeDriver`, which this
module's and :mod:`evoscen_sut.nilsson`'s drivers share.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from evoscen_sim.config.scenario_config import flag, number
from evoscen_sim.jit import kernel, plain
from evoscen_sim.model_registry import ModelSpec
from evoscen_sim.physics.idm import idm_scalar
from evoscen_sim.physics.neighbors import LEFT, OWN, RIGHT
from evoscen_sim.road.road_kernels import RoadTables, lane_end_distance, segment_index

from .conflicts import ConflictRule, resolve_conflicts
from .kernel_math import argmax, maximum, minimum, nan_to_num
from .krauss_lane_change import by_identity, kernel_params, kernel_params_type, lane_change_factory, settled

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


MobilKernelParams = kernel_params_type(MobilParams)
""":class:`MobilParams` as the compiled kernels read them (:func:`evoscen_sut.krauss_lane_change.kernel_params`)."""


@by_identity
@lru_cache(maxsize=64)
def conflict_rule(p: MobilParams) -> ConflictRule:
    """MOBIL's pair test of :func:`evoscen_sut.conflicts.resolve_conflicts`: the rear vehicle's IDM
    acceleration (desired speed ``v0``) behind the front one is below ``−b_safe``."""
    return ConflictRule(safety_distance=False, desired_speed_mps=float(p.desired_speed_mps),
                        safe_decel_mps2=float(p.safe_decel_mps2), time_headway_s=float(p.time_headway_s),
                        min_gap_m=float(p.min_gap_m), accel_mps2=float(p.accel_mps2),
                        comfort_decel_mps2=float(p.comfort_decel_mps2), delta=float(p.delta),
                        max_decel_mps2=IDM_MAX_DECEL_MPS2, length_factor=np.nan, closing_headway_s=np.nan)


# ------------------------------------------------------------------------------------ compiled
# The decision runs as one compiled kernel over the view's arrays (:mod:`evoscen_sim.jit`): for
# one or twenty vehicles numpy's per-call overhead, not arithmetic, dominated the vectorised
# form. The kernels compute exactly the expressions of the vectorised form (same operations in
# the same order, fastmath off), so the results are bit-identical. ``prm`` is a
# :class:`MobilKernelParams`, ``road`` the road's :class:`evoscen_sim.road.road_kernels.RoadTables`.

assert (RIGHT, OWN, LEFT) == (1, 2, 3)  # the kernels use neighbourhood column 2 + offset


@kernel
def _idm(v, v0, gap, v_lead, prm):
    """MOBIL's IDM acceleration of one vehicle (:func:`evoscen_sim.physics.idm.idm_scalar`, clipped
    at −``IDM_MAX_DECEL_MPS2``)."""
    return idm_scalar(v, v0, gap, v_lead, prm.time_headway_s, prm.min_gap_m, prm.accel_mps2,
                      prm.comfort_decel_mps2, prm.delta, IDM_MAX_DECEL_MPS2)


@kernel
def _safe_from_movers(i, ln, v0, moving, m, s, v, length, target_lane, prm):
    """MOBIL's safety criterion against the vehicles changing into lane ``ln`` (``moving[:m]``): neither
    vehicle ``i`` behind one of them nor one of them behind ``i`` would brake harder than
    ``safe_decel_mps2`` (IDM with desired speed ``v0``)."""
    si = s[i]
    vi = v[i]
    b_safe = prm.safe_decel_mps2
    for q in range(m):
        j = moving[q]
        if j == i or target_lane[j] != ln:
            continue
        ds = s[j] - si
        gap = abs(ds) - 0.5 * (length[j] + length[i])
        if ds > 0.0:
            acc = _idm(vi, v0, gap, v[j], prm)
        else:
            acc = _idm(v[j], v0, gap, vi, prm)
        if acc < -b_safe:
            return False
    return True


@kernel
def _mobil_kernel(idx, s, v, length, lane, target_lane, speed_limit, gap_front, leader_speed, gap_rear,
                  follower, follower_speed, road, prm):
    """:func:`evaluate` over the vehicles ``idx`` (module docstring); arrays as :class:`MobilEvaluation`."""
    k = idx.shape[0]
    n = s.shape[0]
    nl = road.present.shape[1]
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
    margin = prm.merge_stop_margin_m
    b_safe = prm.safe_decel_mps2
    for r in range(k):
        i = idx[r]
        si = s[i]
        vi = v[i]
        li = lane[i]
        half = 0.5 * length[i]
        seg = segment_index(road, si)
        # candidate lanes: exist at s; lane-end gaps (inf where not existing)
        for c in range(3):
            ln = li + c - 1
            ex = ln >= 0 and ln < nl and road.present[seg, ln]
            exists[r, c] = ex
            lq = ln if ex else li
            eg = lane_end_distance(road, lq, si) - margin - half
            end_gap[c] = eg if ex else np.inf
            ending[c] = np.isfinite(end_gap[c])
        if not prm.enter_ending_lane:
            exists[r, 0] = exists[r, 0] and not ending[0]
            exists[r, 2] = exists[r, 2] and not ending[2]
        for c in range(3):
            ln = li + c - 1
            lq = ln if exists[r, c] else li
            limit = road.max_speed_mps[seg, lq] if (lq >= 0 and lq < nl) else np.nan
            if not np.isfinite(limit):
                limit = speed_limit[i]
            v0[c] = minimum(prm.desired_speed_mps, limit)
            col = 1 + c
            gap_f[c] = gap_front[i, col]
            v_f[c] = nan_to_num(leader_speed[i, col])
            gap_r[c] = gap_rear[i, col]
            has_r[c] = follower[i, col] >= 0
            v_r[c] = nan_to_num(follower_speed[i, col]) if has_r[c] else 0.0
        # ego: a_c and ã_c, each with the lane end as an obstacle
        for c in range(3):
            a = _idm(vi, v0[c], gap_f[c], v_f[c], prm)
            if ending[c]:
                a = minimum(a, _idm(vi, v0[c], end_gap[c], 0.0, prm))
            acc_ego[r, c] = a
        a_c = acc_ego[r, 1]
        # new follower n
        for c in range(3):
            gap_through = gap_r[c] + length[i] + gap_f[c]
            if has_r[c]:
                a_n = _idm(v_r[c], v0[c], gap_through, v_f[c], prm)
                atn = _idm(v_r[c], v0[c], gap_r[c], vi, prm)
            else:
                a_n = 0.0
                atn = 0.0
            at_n[r, c] = atn
            gain_n[r, c] = atn - a_n
        # old follower o
        if has_r[1]:
            a_o = _idm(v_r[1], v0[1], gap_r[1], vi, prm)
            at_o = _idm(v_r[1], v0[1], gap_r[1] + length[i] + gap_f[1], v_f[1], prm)
            g_o = at_o - a_o
        else:
            g_o = 0.0
        gain_o[r, 0] = g_o
        pol = prm.politeness
        thr = prm.threshold_mps2
        bias = prm.bias_mps2
        if prm.asymmetric:
            at_c0 = acc_ego[r, 0]
            if vi > prm.critical_speed_mps:
                at_c0 = minimum(at_c0, a_c)
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
                ok = _safe_from_movers(i, li + c - 1, v0[c], moving, m, s, v, length, target_lane, prm)
            safe[r, c] = ok
        safe[r, 1] = True
        mandatory[r] = ending[1] and end_gap[1] < prm.merge_mandatory_distance_m
    return exists, acc_ego, gain_n, gain_o, at_n, inc, safe, mandatory


@kernel
def _mobil_decision_kernel(idx, s, d, v, length, lane, target_lane, lane_change, speed_limit, gap_front,
                           leader_speed, gap_rear, follower, follower_speed, road_t, prm_t, rule_t):
    """:func:`lane_change_decision` (evaluation, choice, settling and conflicts) in one pass. The road's
    tables, the parameters and the conflict rule come as plain tuples (:func:`evoscen_sim.jit.plain`)."""
    road, prm, rule = RoadTables(*road_t), MobilKernelParams(*prm_t), ConflictRule(*rule_t)
    exists, _acc_ego, _gain_n, _gain_o, _at_n, inc, safe, mandatory = _mobil_kernel(
        idx, s, v, length, lane, target_lane, speed_limit, gap_front, leader_speed, gap_rear, follower,
        follower_speed, road, prm)
    k = idx.shape[0]
    request = np.zeros(k, dtype=np.int64)
    score = np.empty(3)
    for r in range(k):
        for c in range(3):
            ok = c != 1 and exists[r, c] and safe[r, c] and (inc[r, c] > 0.0 or mandatory[r])
            sc = inc[r, c] if ok else -np.inf
            if ok and mandatory[r]:
                sc = maximum(sc, 0.0) + 1e6
            score[c] = sc
        best = argmax(score)
        req = best - 1 if np.isfinite(score[best]) else 0
        i = idx[r]
        if lane_change[i] != 0:
            req = 0
        if req != 0 and not mandatory[r] and not settled(road, s[i], d[i], lane[i], prm.settle_tolerance_m):
            req = 0
        request[r] = req
    return resolve_conflicts(idx, request, lane, s, v, length, rule)


def _view_args(view: Any) -> tuple:
    """The view's arrays the MOBIL kernels read, in their argument order (``s`` .. ``follower_speed``)."""
    nb = view.neighborhood()
    return (view.s, view.v, view.length, view.lane, view.target_lane, view.speed_limit_mps, nb.gap_front_m,
            nb.leader_speed_mps, nb.gap_rear_m, nb.follower, nb.follower_speed_mps)


def evaluate(view: Any, vehicles: np.ndarray, params: MobilParams) -> MobilEvaluation:
    """MOBIL's accelerations, incentives and safety criteria (see the module docstring)."""
    idx = np.asarray(vehicles, dtype=np.int64)
    exists, acc_ego, gain_n, gain_o, at_n, inc, safe, mandatory = _mobil_kernel(
        idx, *_view_args(view), view.road.kernel_tables(), kernel_params(MobilKernelParams, params))
    return MobilEvaluation(exists=exists, acc_ego=acc_ego, gain_new_follower=gain_n, gain_old_follower=gain_o,
                           acc_new_follower=at_n, incentive=inc, safe=safe, mandatory=mandatory)


def lane_change_decision(view: Any, vehicles: np.ndarray, params: MobilParams) -> np.ndarray:
    """MOBIL's lane-change request (+1 left, −1 right, 0 keep) for each of ``vehicles``.

    The lane offering the larger margin of incentive over threshold among those passing the
    criteria (:func:`evaluate`), a mandatory change preferred; 0 while a change is in progress or
    the vehicle has not settled (:func:`evoscen_sut.krauss_lane_change.settled`, except for a mandatory
    change); two conflicting requests of the given vehicles resolved by
    :func:`evoscen_sut.conflicts.resolve_conflicts` with :func:`conflict_rule`.
    """
    idx = np.asarray(vehicles, dtype=np.int64)
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64)
    nb = view.neighborhood()
    return _mobil_decision_kernel(idx, view.s, view.d, view.v, view.length, view.lane, view.target_lane,
                                  view.lane_change, view.speed_limit_mps, nb.gap_front_m, nb.leader_speed_mps,
                                  nb.gap_rear_m, nb.follower, nb.follower_speed_mps, plain(view.road.kernel_tables()),
                                  plain(kernel_params(MobilKernelParams, params)), plain(conflict_rule(params)))


make_driver = lane_change_factory(lane_change_decision, MobilParams)
"""Factory of the ``mobil`` model (:class:`evoscen_sim.model_registry.ModelSpec`)."""


SPEC = ModelSpec(name="mobil", roles=("sut", "bv"), factory=make_driver, params_type=MobilParams,
                 description="MOBIL lane changes (IDM accelerations, keep-right variant) + Krauss car following (docs/method.md §4)")
