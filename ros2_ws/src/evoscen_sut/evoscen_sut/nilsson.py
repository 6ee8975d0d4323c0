"""Nilsson's lane-utility lane changes (SPEC §4) with SUMO-Krauss car following.

Source: J. Nilsson, J. Silvlin, M. Brännström, E. Coelingh, J. Fredriksson, "If, when, and
how to perform lane change maneuvers on highways", IEEE ITS Magazine 8(4), 2016, as restated
in MODELS.md ("Nilsson lane-utility model") from a public re-implementation. Every lane ``l``
that exists at the ego's position gets the utility::

    U_l = w_v · U_v/N_v + w_tg · U_tg/N_tg + w_ld · U_ld/N_ld

* travel time: with the lane's mean speed ``v̄_l`` and the look-ahead ``d_max = v_des β``,
  ``U_v = −|d_max/v_des − d_max/max(v_min, v̄_l)|``, ``N_v = |d_max/v_des − d_max/v_min|``,
  ``w_v = 5`` if ``v̄_l ≤ v_des`` else 12;
* time gap: ``t_g = (x_front − x_rear − L)/v_rear``, ``U_tg = min(α t_des, t_g)``,
  ``N_tg = α t_des``, ``w_tg = 0.5``;
* remaining distance (MODELS.md's reading, needed on the ramp):
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
  ``α t_des``. With the ego as the rear vehicle this is MODELS.md's ``(x_front − x_rear −
  L)/v_rear``. The re-implementation uses the ego as the rear vehicle of its *own* lane only
  and the whole front–rear gap of the *other* lanes; that makes the lane just left always
  look roomier than the lane just entered, and in closed loop the ego ping-ponged between
  two lanes every few tenths of a second (default scenario), so every lane is measured the
  same way here.
* **Desired speed** ``v_des = min(desired_speed_mps, the lane's speed limit at s)``.
* **Remaining distance.** ``d_end,l`` = :meth:`RoadModel.distance_to_lane_end` (``inf`` on
  the mainline, so ``U_ld = 0`` there; on the merge lane ``d_end`` ≪ ``d_max`` and
  ``U_ld/N_ld ≈ −1``). MODELS.md gives no ``w_ld``: ``lane_end_weight`` = 5 [choice] makes
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
  longitudinally (centre distance, ``L`` the ego's length; MODELS.md). Extensions
  [choice]: the distance grows by ``safety_closing_headway_s`` × the closing speed (a
  faster vehicle behind, a slower one ahead; 0 gives the plain rule), and a vehicle that
  is changing into the adjacent lane (``view.target_lane``) counts as being in it (two
  vehicles must not move into the same gap from both sides).
* A vehicle already changing lanes (``view.lane_change != 0``) requests 0, and so does one
  whose centre is not yet within ``settle_tolerance_m`` of its lane's centre line after a
  change [choice] (except when it must leave an ending lane).
* Among the vehicles one driver drives (the BV role), two steps into the same lane at the
  same step that fail the safety distance for each other are resolved in favour of the
  vehicle ahead (:func:`evoscen_sut.mobil.resolve_conflicts`) [choice].

Parameter sources: MODELS.md (β = 300 s, v_min = 2 m/s, weights 5/12 and 0.5, α = 2,
b_r = 0.05, θ = 0.9, 2.5·L); ``t_des = 2 s`` is the desired headway of the public
re-implementation's example [choice: MODELS.md gives no value].

Longitudinal control: SUMO's Krauss via :class:`evoscen_sut.mobil.KraussLaneChangeDriver`
(shared with MOBIL: Krauss behind the own-lane leader, also the target-lane leader during a
change, and a stop before the end of the merge lane).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from evoscen_sim.config import number
from evoscen_sim.models import ModelSpec
from evoscen_sim.scenario_params import vehicle_params_from_config

from .mobil import (
    KraussLaneChangeDriver,
    krauss_for,
    lane_end_gap_m,
    resolve_conflicts,
    settled,
)


@dataclass(frozen=True)
class NilssonParams:
    """Nilsson lane-utility parameters (``models.nilsson`` in the scenario YAML)."""

    desired_speed_mps: float = number(120.0 / 3.6, 0.0, 40.0, lo_open=True)
    """Desired speed v_des (m/s), capped by each lane's speed limit. Default 120 km/h (the road's limit)."""
    look_ahead_time_s: float = number(300.0, 0.0, 3600.0, lo_open=True)
    """β: the look-ahead distance is d_max = v_des·β (s). Default 300, MODELS.md."""
    min_speed_mps: float = number(2.0, 0.0, 40.0, lo_open=True)
    """v_min of the travel-time utility and its normaliser (m/s). Default 2, MODELS.md."""
    speed_weight_slow: float = number(5.0, 0.0, 100.0)
    """Travel-time weight when v̄_l ≤ v_des (-). Default 5, MODELS.md."""
    speed_weight_fast: float = number(12.0, 0.0, 100.0)
    """Travel-time weight when v̄_l > v_des (-). Default 12, MODELS.md."""
    time_gap_weight: float = number(0.5, 0.0, 100.0)
    """Time-gap weight (-). Default 0.5, MODELS.md."""
    desired_time_gap_s: float = number(2.0, 0.0, 20.0, lo_open=True)
    """Desired time gap t_des (s). Default 2, the public re-implementation's example [choice]."""
    time_gap_factor: float = number(2.0, 0.0, 20.0, lo_open=True)
    """α: the time-gap utility saturates at α·t_des (-). Default 2, MODELS.md."""
    lane_end_weight: float = number(5.0, 0.0, 1000.0)
    """Weight of the remaining-distance utility U_ld (-). Default 5 [choice: not in MODELS.md]."""
    keep_right_bias: float = number(0.05, 0.0, 10.0)
    """Keep-right bias b_r per lane step (utility units). Default 0.05, MODELS.md."""
    hysteresis: float = number(0.9, 0.0, 10.0)
    """θ: a change needs U_l − U_ego > θ·|U_ego| + bias (-). Default 0.9, MODELS.md."""
    safety_length_factor: float = number(2.5, 0.0, 20.0)
    """Reject a step with a target-lane vehicle within this many ego lengths (centre distance). Default 2.5, MODELS.md."""
    safety_closing_headway_s: float = number(3.0, 0.0, 10.0)
    """Extra safety distance per m/s of closing speed (s) [choice extension; 0: MODELS.md's rule].
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


def _lane_neighbours(view: Any, idx: np.ndarray, num_lanes: int, view_range_m: float) -> tuple[np.ndarray, ...]:
    """Nearest vehicle ahead / behind each ego in every lane: (front, rear) indices (k, L), -1 if none."""
    n = view.n
    s = np.asarray(view.s, dtype=float)
    lane_all = np.asarray(view.lane, dtype=np.int64)
    ds = s[None, :] - s[idx][:, None]  # (k, n)
    j = np.arange(n)
    other = j[None, :] != idx[:, None]
    visible = other & (np.abs(ds) <= view_range_m)
    same = lane_all[None, :] == lane_all[idx][:, None]
    ahead = (ds > 0.0) | ((ds == 0.0) & same & (j[None, :] > idx[:, None]))  # as evoscen_sim.neighbors
    in_lane = lane_all[None, :, None] == np.arange(num_lanes)[None, None, :]  # (1, n, L)
    m_front = (visible & ahead)[:, :, None] & in_lane
    m_rear = (visible & ~ahead)[:, :, None] & in_lane
    d_front = np.where(m_front, ds[:, :, None], np.inf)
    d_rear = np.where(m_rear, -ds[:, :, None], np.inf)
    front = np.argmin(d_front, axis=1)  # lowest index wins a tie
    rear = np.argmin(d_rear[:, ::-1, :], axis=1)
    rear = n - 1 - rear  # highest index wins a tie (as evoscen_sim.neighbors)
    front = np.where(np.isfinite(np.min(d_front, axis=1)), front, -1)
    rear = np.where(np.isfinite(np.min(d_rear, axis=1)), rear, -1)
    return front, rear


def evaluate(view: Any, vehicles: np.ndarray, params: NilssonParams) -> NilssonEvaluation:
    """Lane utilities, scores, target lane and safety of the step (module docstring)."""
    p = params
    idx = np.asarray(vehicles, dtype=np.int64)
    k = idx.size
    road = view.road
    num_lanes = int(road.num_lanes)
    lanes = np.arange(num_lanes)
    s = view.s[idx]
    v = view.v[idx]
    length = view.length[idx]
    lane = view.lane[idx]
    rows = np.arange(k)

    exists = np.asarray(road.lane_exists(lanes[None, :], s[:, None]), dtype=bool)  # (k, L)
    limit = np.asarray(road.speed_limit_max_mps(lanes[None, :], s[:, None]), dtype=float)
    v_des = np.minimum(p.desired_speed_mps, np.where(np.isfinite(limit), limit, p.desired_speed_mps))

    front, rear = _lane_neighbours(view, idx, num_lanes, p.view_range_m)
    has_f = front >= 0
    has_r = rear >= 0
    fi = np.where(has_f, front, 0)
    ri = np.where(has_r, rear, 0)
    v_f, v_r = view.v[fi], view.v[ri]
    # bumper gaps the ego has (own lane) or would have (other lanes) at its s
    gap_f = view.s[fi] - s[:, None] - 0.5 * (view.length[fi] + length[:, None])
    gap_r = s[:, None] - view.s[ri] - 0.5 * (view.length[ri] + length[:, None])

    sat = p.time_gap_factor * p.desired_time_gap_s
    v_bar = np.where(has_f, np.where(has_r, 0.5 * (v_f + v_r), v_f), v_des)
    t_front = np.where(has_f, gap_f / np.maximum(v[:, None], p.min_speed_mps), np.inf)
    t_rear = np.where(has_r, gap_r / np.maximum(v_r, p.min_speed_mps), np.inf)
    t_gap = np.minimum(np.minimum(t_front, t_rear), sat)

    beta = p.look_ahead_time_s
    u_v = -beta * np.abs(1.0 - v_des / np.maximum(p.min_speed_mps, v_bar))  # d_max/v_des = β
    n_v = beta * np.abs(1.0 - v_des / p.min_speed_mps)
    w_v = np.where(v_bar <= v_des, p.speed_weight_slow, p.speed_weight_fast)
    u_tg = np.minimum(sat, t_gap) / sat
    d_max = v_des * beta
    d_end = np.asarray(road.distance_to_lane_end(lanes[None, :], s[:, None]), dtype=float)
    d_end = np.where(np.isnan(d_end), np.inf, d_end)
    u_ld = -np.maximum(0.0, d_max - d_end) / d_max  # (U_ld / N_ld)
    utility = w_v * u_v / n_v + p.time_gap_weight * u_tg + p.lane_end_weight * u_ld
    utility = np.where(exists, utility, -np.inf)

    # candidates: existing lanes whose stop point is not within the mandatory distance
    stop_gap = lane_end_gap_m(view, idx, np.broadcast_to(lanes, (k, num_lanes)), p.merge_stop_margin_m)
    closing_end = np.isfinite(stop_gap) & (stop_gap < p.merge_mandatory_distance_m)
    candidate = exists & ~closing_end
    u_ego = utility[rows, lane]
    score = utility - p.hysteresis * np.abs(u_ego)[:, None] + p.keep_right_bias * (lane[:, None] - lanes[None, :])
    score[rows, lane] = u_ego
    score = np.where(candidate, score, -np.inf)
    others = score.copy()
    others[rows, lane] = -np.inf
    best_other = np.argmax(others, axis=1)
    best_score = others[rows, best_other]
    own_ok = candidate[rows, lane]
    change = np.isfinite(best_score) & (~own_ok | (best_score > u_ego))
    target = np.where(change, best_other, lane)

    # safety of the adjacent step
    step = np.sign(target - lane)
    next_lane = lane + step
    ds = view.s[None, :] - s[:, None]  # (k, n)
    dv_closing = np.where(ds < 0.0, view.v[None, :] - v[:, None], v[:, None] - view.v[None, :])
    need = p.safety_length_factor * length[:, None] + p.safety_closing_headway_s * np.maximum(dv_closing, 0.0)
    # a vehicle counts in the lane it is in and in the lane it is changing into
    occupies = (view.lane[None, :] == next_lane[:, None]) | (view.target_lane[None, :] == next_lane[:, None])
    in_next = occupies & (np.arange(view.n)[None, :] != idx[:, None])
    blocked = np.any(in_next & (np.abs(ds) < need), axis=1)
    step_safe = (step == 0) | ~blocked
    return NilssonEvaluation(utility=utility, speed=v_bar, time_gap=t_gap, score=score, target=target,
                             step_safe=step_safe, own_candidate=own_ok)


def lane_change_decision(view: Any, vehicles: np.ndarray, params: NilssonParams) -> np.ndarray:
    """Nilsson's lane-change request (+1 left, −1 right, 0 keep) for each of ``vehicles``."""
    idx = np.asarray(vehicles, dtype=np.int64)
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64)
    ev = evaluate(view, idx, params)
    lane = view.lane[idx]
    request = np.where(ev.step_safe, np.sign(ev.target - lane), 0)
    request = np.where(view.lane_change[idx] != 0, 0, request)
    leaving_end = ~ev.own_candidate
    request = np.where(settled(view, idx, params.settle_tolerance_m) | leaving_end, request, 0)

    def unsafe_pair(i: np.ndarray) -> np.ndarray:
        ds = view.s[i][None, :] - view.s[i][:, None]
        closing = np.where(ds > 0, view.v[i][:, None] - view.v[i][None, :], view.v[i][None, :] - view.v[i][:, None])
        need = params.safety_length_factor * view.length[i][:, None] + params.safety_closing_headway_s * np.maximum(
            closing, 0.0)
        return np.abs(ds) < need

    return resolve_conflicts(view, idx, request.astype(np.int64), unsafe_pair)


def make_driver(vehicles: np.ndarray, params: NilssonParams | None, config: Any,
                rng: np.random.Generator) -> KraussLaneChangeDriver:
    """Factory of the ``nilsson`` model (:class:`evoscen_sim.models.ModelSpec`)."""
    params = NilssonParams() if params is None else params
    return KraussLaneChangeDriver(vehicles, lane_change_decision, params, krauss_for(config, rng),
                                  vehicle_params_from_config(config), params.merge_stop_margin_m)


SPEC = ModelSpec(
    name="nilsson",
    roles=("sut", "bv"),
    factory=make_driver,
    params_type=NilssonParams,
    description="Nilsson lane utilities (travel time, time gap, remaining distance) + Krauss car following (SPEC 4)",
)
