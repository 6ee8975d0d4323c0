"""Nilsson's lane-utility lane changes (docs/method.md §4) with SUMO-Krauss car following.

Source: J. Nilsson, J. Silvlin, M. Brännström, E. Coelingh, J. Fredriksson, "If, when, and
how to perform lane change maneuvers on highways", IEEE ITS Magazine 8(4), 2016, as restated
in docs/method.md §4.1 from a public re-implementation. Every lane ``l``
that exists at the ego's position gets the utility::

    U_l = w_v · U_v/N_v + w_tg · U_tg/N_tg + w_ld · U_ld/N_ld

* travel time: with the lane's mean speed ``v̄_l`` and the look-ahead ``d_max = v_des β``,
  ``U_v = −|d_max/v_des − d_max/max(v_min, v̄_l)|``, ``N_v = |d_max/v_des − d_max/v_min|``,
  ``w_v = 5`` if ``v̄_l ≤ v_des`` else 12;
* time gap: ``t_g = (x_front − x_rear − L)/v_rear``, ``U_tg = min(α t_des, t_g)``,
  ``N_tg = α t_des``, ``w_tg = 0.5``;
* remaining distance (docs/method.md §4.1's reading, needed on the ramp):
  ``U_ld = −max(0, d_max − d_end,l)/v_des``, ``N_ld = d_max/v_des``.

The best lane over *all* lanes is the target ("all lanes are considered, one step at a
time"); the vehicle requests ±1 towards it when the adjacent lane passes the safety check,
and re-decides at every step (so a two-lane move is two checked steps).

Readings (all configurable through :class:`NilssonParams`):

* **Neighbours.** For every lane, the own lane included, the nearest other vehicle ahead
  of and behind the ego's ``s`` within ``view_range_m`` (centre distance) [choice: sensor
  range], a vehicle's lane being the lane holding its centre (``view.lane``).
* **Mean speed** ``v̄_l = (v_front + v_rear)/2``; without a rear vehicle ``v_front``; without
  a front vehicle within view the lane is free and ``v̄_l = v_des`` [reading; the
  re-implementation uses the rear vehicle's speed, or the ego's in an empty lane, which
  makes a free lane look no faster than the ego is driving].
* **Time gap** [reading]: ``t_g`` is the tighter of the two time gaps the ego has in (or
  would have after moving to) lane ``l`` at its current ``s``: its headway to the front
  vehicle ``g_front/v_ego`` and the rear vehicle's headway to it ``g_rear/v_rear`` (bumper
  gaps; speeds floored at ``v_min``); a missing neighbour drops its term, none gives
  ``α t_des``. With the ego as the rear vehicle this is docs/method.md §4.1's ``(x_front − x_rear −
  L)/v_rear``. The re-implementation uses the ego as the rear vehicle of its *own* lane only
  and the whole front–rear gap of the *other* lanes; that makes the lane just left always
  look roomier than the lane just entered, and in closed loop the ego ping-ponged between
  two lanes every few tenths of a second (default scenario), so every lane is measured the
  same way here.
* **Desired speed** ``v_des = min(desired_speed_mps, the lane's speed limit at s)``.
* **Remaining distance.** ``d_end,l`` = :meth:`RoadModel.distance_to_lane_end` (``inf`` on
  the mainline, so ``U_ld = 0`` there; on the merge lane ``d_end`` ≪ ``d_max`` and
  ``U_ld/N_ld ≈ −1``). docs/method.md §4.1 gives no ``w_ld``: ``lane_end_weight`` = 5 [choice] makes
  the merge lane lose against any mainline lane that is not nearly jammed. Mandatory rule
  [choice]: a lane whose stop point (``merge_stop_margin_m`` before its end) is closer than
  ``merge_mandatory_distance_m`` is never a target, and the ego leaves it for the best
  other lane whatever the utilities.
* **Keep-right bias and hysteresis.** The re-implementation scores a change as
  ``U_l ± b_r − (1+θ)|U_ego|`` against ``U_ego``, i.e. changes when
  ``U_l − U_ego > (1+θ)|U_ego| ∓ b_r``; for ``U_ego < 0`` that makes a *worse* own lane
  *harder* to leave. We use ``U_l − U_ego > θ|U_ego| + b_r·(l − lane)`` [reading]: the same
  ``(1+θ)·U_ego`` threshold when ``U_ego ≥ 0``, monotone in ``U_ego`` when it is negative; the
  bias is ``b_r`` per lane step, in favour of the right (``b_r`` = 0.05, θ = 0.9).
* **Safety.** The step is rejected if a vehicle in the adjacent lane is within ``2.5·L``
  longitudinally (centre distance, ``L`` the ego's length; docs/method.md §4.1). Extensions
  [choice]: the distance grows by ``safety_closing_headway_s`` × the closing speed (a
  faster vehicle behind, a slower one ahead; 0 gives the plain rule), and a vehicle that
  is changing into the adjacent lane (``view.target_lane``) counts as being in it (two
  vehicles must not move into the same gap from both sides).
* A vehicle already changing lanes (``view.lane_change != 0``) requests 0, and so does one
  whose centre is not yet within ``settle_tolerance_m`` of its lane's centre line after a
  change [choice] (except when it must leave an ending lane).
* Among the vehicles one driver drives (the BV role), two steps into the same lane at the
  same step that fail the safety distance for each other are resolved in favour of the
  vehicle ahead (:mod:`evoscen_sut.conflicts`) [choice].

Parameter sources: docs/method.md §4.1 (β = 300 s, v_min = 2 m/s, weights 5/12 and 0.5, α = 2,
b_r = 0.05, θ = 0.9, 2.5·L); ``t_des = 2 s`` is the desired headway of the public
re-implementation's example [choice: docs/method.md §4.1 gives no value].

Longitudinal control: SUMO's Krauss via :class:`evoscen_sut.krauss_lane_change.KraussLaneChangeDriver`
(shared with MOBIL: Krauss behind the own-lane leader, also the target-lane leader during a
change, and a stop before the end of the merge lane).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from evoscen_sim.config.scenario_config import number
from evoscen_sim.jit import kernel, plain
from evoscen_sim.model_registry import ModelSpec
from evoscen_sim.road.road_kernels import RoadTables, lane_end_distance, segment_index

from .conflicts import ConflictRule, resolve_conflicts
from .kernel_math import argmax, maximum, minimum
from .krauss_lane_change import by_identity, kernel_params, kernel_params_type, lane_change_factory, settled


@dataclass(frozen=True)
class NilssonParams:
    """Nilsson lane-utility parameters (``models.nilsson`` in the scenario YAML)."""

    desired_speed_mps: float = number(120.0 / 3.6, 0.0, 40.0, lo_open=True)
    """Desired speed v_des (m/s), capped by each lane's speed limit. Default 120 km/h (the road's limit)."""
    look_ahead_time_s: float = number(300.0, 0.0, 3600.0, lo_open=True)
    """β: the look-ahead distance is d_max = v_des·β (s). Default 300, docs/method.md §4.1."""
    min_speed_mps: float = number(2.0, 0.0, 40.0, lo_open=True)
    """v_min of the travel-time utility and its normaliser (m/s). Default 2, docs/method.md §4.1."""
    speed_weight_slow: float = number(5.0, 0.0, 100.0)
    """Travel-time weight when v̄_l ≤ v_des (-). Default 5, docs/method.md §4.1."""
    speed_weight_fast: float = number(12.0, 0.0, 100.0)
    """Travel-time weight when v̄_l > v_des (-). Default 12, docs/method.md §4.1."""
    time_gap_weight: float = number(0.5, 0.0, 100.0)
    """Time-gap weight (-). Default 0.5, docs/method.md §4.1."""
    desired_time_gap_s: float = number(2.0, 0.0, 20.0, lo_open=True)
    """Desired time gap t_des (s). Default 2, the public re-implementation's example [choice]."""
    time_gap_factor: float = number(2.0, 0.0, 20.0, lo_open=True)
    """α: the time-gap utility saturates at α·t_des (-). Default 2, docs/method.md §4.1."""
    lane_end_weight: float = number(5.0, 0.0, 1000.0)
    """Weight of the remaining-distance utility U_ld (-). Default 5 [choice: not in docs/method.md §4.1]."""
    keep_right_bias: float = number(0.05, 0.0, 10.0)
    """Keep-right bias b_r per lane step (utility units). Default 0.05, docs/method.md §4.1."""
    hysteresis: float = number(0.9, 0.0, 10.0)
    """θ: a change needs U_l − U_ego > θ·|U_ego| + bias (-). Default 0.9, docs/method.md §4.1."""
    safety_length_factor: float = number(2.5, 0.0, 20.0)
    """Reject a step with a target-lane vehicle within this many ego lengths (centre distance). Default 2.5, docs/method.md §4.1."""
    safety_closing_headway_s: float = number(3.0, 0.0, 10.0)
    """Extra safety distance per m/s of closing speed (s) [choice extension; 0: docs/method.md §4.1's rule].
    Default 3 s ≈ the time the centre needs to cross into the target lane (half a 3.5 m lane
    at the lateral controller's 0.6 m/s cap), during which the gap closes unseen by the
    target lane's follower."""
    view_range_m: float = number(150.0, 0.0, 2500.0, lo_open=True)
    """Neighbours farther than this (centre distance) are not seen (m) [choice]."""
    merge_stop_margin_m: float = number(15.0, 0.0, 200.0)
    """A lane end acts as a stop point this far before it (m): the Krauss stop and the
    mandatory rule. Default 15, as the level-0 driver."""
    merge_mandatory_distance_m: float = number(100.0, 0.0, 1000.0)
    """Within this distance of an ending lane's stop point the lane is never a target and
    the ego must leave it (m) [choice]."""
    settle_tolerance_m: float = number(0.5, 0.0, 10.0)
    """A new change is requested only with the centre within this distance of the lane's
    centre line (m) [choice]; not applied when the ego must leave an ending lane."""


@dataclass(frozen=True)
class NilssonEvaluation:
    """Lane utilities and the decision for ``k`` vehicles over all ``num_lanes`` lanes."""

    utility: np.ndarray
    """(k, num_lanes) U_l (−inf where the lane does not exist at the vehicle's s)."""
    speed: np.ndarray
    """(k, num_lanes) v̄_l (m/s)."""
    time_gap: np.ndarray
    """(k, num_lanes) t_g (s), saturated at α·t_des."""
    score: np.ndarray
    """(k, num_lanes) U_l − θ|U_ego| + b_r (lane − l) for other lanes, U_ego for the own lane;
    −inf for lanes that are not candidates."""
    target: np.ndarray
    """(k,) best lane (the own lane when no other lane beats it)."""
    step_safe: np.ndarray
    """(k,) the adjacent lane towards ``target`` passes the safety check (True when target = lane)."""
    own_candidate: np.ndarray
    """(k,) the own lane may be kept (False: an ending lane within the mandatory distance)."""


NilssonKernelParams = kernel_params_type(NilssonParams)
""":class:`NilssonParams` as the compiled kernels read them (:func:`evoscen_sut.krauss_lane_change.kernel_params`)."""


@by_identity
@lru_cache(maxsize=64)
def conflict_rule(p: NilssonParams) -> ConflictRule:
    """Nilsson's pair test of :func:`evoscen_sut.conflicts.resolve_conflicts`: the safety distance
    ``safety_length_factor · L + safety_closing_headway_s · max(closing speed, 0)``."""
    return ConflictRule(safety_distance=True, desired_speed_mps=np.nan, safe_decel_mps2=np.nan,
                        time_headway_s=np.nan, min_gap_m=np.nan, accel_mps2=np.nan, comfort_decel_mps2=np.nan,
                        delta=np.nan, max_decel_mps2=np.nan, length_factor=float(p.safety_length_factor),
                        closing_headway_s=float(p.safety_closing_headway_s))


@kernel
def _nearest_in_lanes(i, s, lane, view_range, front, rear, d_front, d_rear):
    """The nearest vehicle ahead and behind vehicle ``i`` in every lane within ``view_range``, written
    into ``front`` / ``rear`` (-1: none) and their arc distances ``d_front`` / ``d_rear`` (inf: none):
    ahead means a larger ``s``, or the same ``s`` in the same lane and a larger index; the lowest index
    wins a tie ahead, the highest behind."""
    n = s.shape[0]
    nl = front.shape[0]
    si = s[i]
    li = lane[i]
    for ln in range(nl):
        front[ln] = -1
        rear[ln] = -1
        d_front[ln] = np.inf
        d_rear[ln] = np.inf
    for j in range(n):
        if j == i:
            continue
        ds = s[j] - si
        if not (abs(ds) <= view_range):
            continue
        lj = lane[j]
        if lj < 0 or lj >= nl:
            continue
        if ds > 0.0 or (ds == 0.0 and lj == li and j > i):
            if ds < d_front[lj]:  # strict: the lowest index wins a tie
                d_front[lj] = ds
                front[lj] = j
        elif -ds <= d_rear[lj]:  # non-strict: the highest index wins a tie
            d_rear[lj] = -ds
            rear[lj] = j


@kernel
def _step_blocked(i, next_lane, s, v, length, lane, target_lane, prm):
    """Whether a vehicle in (or changing into) ``next_lane`` is within Nilsson's safety distance of
    vehicle ``i``: ``safety_length_factor · L_i + safety_closing_headway_s · max(closing speed, 0)``."""
    si = s[i]
    vi = v[i]
    for j in range(s.shape[0]):
        if j == i or not (lane[j] == next_lane or target_lane[j] == next_lane):
            continue
        ds = s[j] - si
        dv_closing = v[j] - vi if ds < 0.0 else vi - v[j]
        need = prm.safety_length_factor * length[i] + prm.safety_closing_headway_s * maximum(dv_closing, 0.0)
        if abs(ds) < need:
            return True
    return False


@kernel
def _nilsson_kernel(idx, s, v, length, lane, target_lane, road, prm):
    """:func:`evaluate` over the vehicles ``idx`` (module docstring); arrays as :class:`NilssonEvaluation`.

    The nearest vehicle ahead / behind in every lane (within ``view_range_m``): ahead means a
    larger ``s``, or the same ``s`` in the same lane and a larger index (as
    :mod:`evoscen_sim.physics.neighbors`); the lowest index wins a tie ahead, the highest behind.
    """
    k = idx.shape[0]
    nl = road.present.shape[1]
    utility = np.empty((k, nl))
    speed = np.empty((k, nl))
    time_gap = np.empty((k, nl))
    score = np.empty((k, nl))
    target = np.empty(k, dtype=np.int64)
    step_safe = np.empty(k, dtype=np.bool_)
    own_candidate = np.empty(k, dtype=np.bool_)
    front = np.empty(nl, dtype=np.int64)
    rear = np.empty(nl, dtype=np.int64)
    d_front = np.empty(nl)
    d_rear = np.empty(nl)
    candidate = np.empty(nl, dtype=np.bool_)
    others = np.empty(nl)
    v_des_max = prm.desired_speed_mps
    beta = prm.look_ahead_time_s
    v_min = prm.min_speed_mps
    sat = prm.time_gap_factor * prm.desired_time_gap_s
    view_range = prm.view_range_m
    for r in range(k):
        i = idx[r]
        si = s[i]
        vi = v[i]
        li = lane[i]
        half = 0.5 * length[i]
        seg = segment_index(road, si)
        _nearest_in_lanes(i, s, lane, view_range, front, rear, d_front, d_rear)
        # lane utilities
        for ln in range(nl):
            exists = road.present[seg, ln]
            limit = road.max_speed_mps[seg, ln]
            v_des = minimum(v_des_max, limit if np.isfinite(limit) else v_des_max)
            fj = front[ln]
            bj = rear[ln]
            if fj >= 0:
                v_bar = 0.5 * (v[fj] + v[bj]) if bj >= 0 else v[fj]
                gap_f = s[fj] - si - 0.5 * (length[fj] + length[i])
                t_front = gap_f / maximum(vi, v_min)
            else:
                v_bar = v_des
                t_front = np.inf
            if bj >= 0:
                gap_r = si - s[bj] - 0.5 * (length[bj] + length[i])
                t_rear = gap_r / maximum(v[bj], v_min)
            else:
                t_rear = np.inf
            t_gap = minimum(minimum(t_front, t_rear), sat)
            u_v = -beta * abs(1.0 - v_des / maximum(v_min, v_bar))
            n_v = beta * abs(1.0 - v_des / v_min)
            w_v = prm.speed_weight_slow if v_bar <= v_des else prm.speed_weight_fast
            u_tg = minimum(sat, t_gap) / sat
            d_max = v_des * beta
            d_end = lane_end_distance(road, ln, si)
            u_ld = -maximum(0.0, d_max - d_end) / d_max
            u = w_v * u_v / n_v + prm.time_gap_weight * u_tg + prm.lane_end_weight * u_ld
            utility[r, ln] = u if exists else -np.inf
            speed[r, ln] = v_bar
            time_gap[r, ln] = t_gap
            # candidates: existing lanes whose stop point is not within the mandatory distance
            stop_gap = d_end - prm.merge_stop_margin_m - half
            candidate[ln] = exists and not (np.isfinite(stop_gap) and stop_gap < prm.merge_mandatory_distance_m)
        u_ego = utility[r, li]
        for ln in range(nl):
            if ln == li:
                sc = u_ego
            else:
                sc = utility[r, ln] - prm.hysteresis * abs(u_ego) + prm.keep_right_bias * float(li - ln)
            sc = sc if candidate[ln] else -np.inf
            score[r, ln] = sc
            others[ln] = -np.inf if ln == li else sc
        best_other = argmax(others)
        best_score = others[best_other]
        own_ok = candidate[li]
        change = np.isfinite(best_score) and ((not own_ok) or best_score > u_ego)
        tgt = best_other if change else li
        target[r] = tgt
        own_candidate[r] = own_ok
        step = 1 if tgt > li else (-1 if tgt < li else 0)
        step_safe[r] = step == 0 or not _step_blocked(i, li + step, s, v, length, lane, target_lane, prm)
    return utility, speed, time_gap, score, target, step_safe, own_candidate


@kernel
def _decision_kernel(idx, s, d, v, length, lane, target_lane, lane_change, road_t, prm_t, rule_t):
    """:func:`lane_change_decision` (evaluation, safety, settling and conflicts) in one pass. The road's
    tables, the parameters and the conflict rule come as plain tuples (:func:`evoscen_sim.jit.plain`)."""
    road, prm, rule = RoadTables(*road_t), NilssonKernelParams(*prm_t), ConflictRule(*rule_t)
    _utility, _speed, _time_gap, _score, target, step_safe, own_candidate = _nilsson_kernel(
        idx, s, v, length, lane, target_lane, road, prm)
    k = idx.shape[0]
    request = np.zeros(k, dtype=np.int64)
    for r in range(k):
        i = idx[r]
        diff = target[r] - lane[i]
        req = (1 if diff > 0 else (-1 if diff < 0 else 0)) if step_safe[r] else 0
        if lane_change[i] != 0:
            req = 0
        # not leaving an ending lane: only once settled
        if req != 0 and own_candidate[r] and not settled(road, s[i], d[i], lane[i], prm.settle_tolerance_m):
            req = 0
        request[r] = req
    return resolve_conflicts(idx, request, lane, s, v, length, rule)


def evaluate(view: Any, vehicles: np.ndarray, params: NilssonParams) -> NilssonEvaluation:
    """Lane utilities, scores, target lane and safety of the step (module docstring)."""
    idx = np.asarray(vehicles, dtype=np.int64)
    utility, speed, time_gap, score, target, step_safe, own_candidate = _nilsson_kernel(
        idx, view.s, view.v, view.length, view.lane, view.target_lane, view.road.kernel_tables(),
        kernel_params(NilssonKernelParams, params))
    return NilssonEvaluation(utility=utility, speed=speed, time_gap=time_gap, score=score, target=target,
                             step_safe=step_safe, own_candidate=own_candidate)


def lane_change_decision(view: Any, vehicles: np.ndarray, params: NilssonParams) -> np.ndarray:
    """Nilsson's lane-change request (+1 left, −1 right, 0 keep) for each of ``vehicles``.

    One step towards :func:`evaluate`'s target lane if that step is safe; 0 while a change is in
    progress or the vehicle has not settled (:func:`evoscen_sut.krauss_lane_change.settled`, except when it
    must leave an ending lane); two conflicting requests of the given vehicles resolved by
    :func:`evoscen_sut.conflicts.resolve_conflicts` with the safety distance as the pair test
    (:func:`conflict_rule`).
    """
    idx = np.asarray(vehicles, dtype=np.int64)
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64)
    return _decision_kernel(idx, view.s, view.d, view.v, view.length, view.lane, view.target_lane,
                            view.lane_change, plain(view.road.kernel_tables()),
                            plain(kernel_params(NilssonKernelParams, params)), plain(conflict_rule(params)))


make_driver = lane_change_factory(lane_change_decision, NilssonParams)
"""Factory of the ``nilsson`` model (:class:`evoscen_sim.model_registry.ModelSpec`)."""


SPEC = ModelSpec(name="nilsson", roles=("sut", "bv"), factory=make_driver, params_type=NilssonParams,
                 description="Nilsson lane utilities (travel time, time gap, remaining distance) + Krauss car following (docs/method.md §4)")
