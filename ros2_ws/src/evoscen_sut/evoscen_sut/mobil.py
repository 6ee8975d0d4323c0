"""MOBIL lane changes (SPEC §4) with SUMO-Krauss car following.

MOBIL — "Minimizing Overall Braking Induced by Lane changes" (Kesting, Treiber, Helbing,
TRR 1999, 2007; MODELS.md "IDM and MOBIL"). A vehicle ``c`` looks at the two *adjacent* lanes
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

Parameter sources: MODELS.md ("IDM and MOBIL"): p = 0–0.5, Δa_th = 0.1–0.2 m/s²,
Δa_bias = 0.2–0.3 m/s², b_safe = 4 m/s²; IDM highway values v0 = 120 km/h, T = 1.0–1.5 s,
s0 = 2 m, a = 1.0 m/s², b = 1.5 m/s², δ = 4 (Treiber & Kesting, *Traffic Flow Dynamics*,
2013, Table 11.2).

Longitudinal control: SUMO's Krauss (:mod:`evoscen_sut.krauss`, SPEC §4: car following is
the same for every SUT), see :class:`KraussLaneChangeDriver`, which this module's and
:mod:`evoscen_sut.nilsson`'s drivers share.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from evoscen_sim.car_following import IdmParams, idm_acceleration
from evoscen_sim.config import flag, number
from evoscen_sim.models import ModelSpec
from evoscen_sim.neighbors import LEFT, OWN, RIGHT
from evoscen_sim.scenario_params import vehicle_params_from_config
from evoscen_sim.vehicle import VehicleParams, accel_to_throttle

IDM_MAX_DECEL_MPS2 = 9.0
"""Lower clip of the IDM accelerations MOBIL compares (m/s²; the IDM helper's default)."""


@dataclass(frozen=True)
class MobilParams:
    """MOBIL parameters (``models.mobil`` in the scenario YAML)."""

    politeness: float = number(0.25, 0.0, 5.0)
    """Politeness factor p (-). Default 0.25, mid-range of MODELS.md's p = 0–0.5."""
    threshold_mps2: float = number(0.1, 0.0, 5.0)
    """Changing threshold Δa_th (m/s²). Default 0.1, MODELS.md (0.1–0.2)."""
    bias_mps2: float = number(0.2, 0.0, 5.0)
    """Keep-right bias Δa_bias of the asymmetric variant (m/s²). Default 0.2, MODELS.md (0.2–0.3)."""
    safe_decel_mps2: float = number(4.0, 0.0, 20.0, lo_open=True)
    """Safe deceleration b_safe (m/s²): the new follower's ã_n ≥ −b_safe. Default 4, MODELS.md."""
    asymmetric: bool = flag(True)
    """Use the asymmetric keep-right / overtake-left criteria (MODELS.md); False: symmetric MOBIL."""
    critical_speed_mps: float = number(60.0 / 3.6, 0.0, 40.0)
    """Above this speed the ego may not overtake on the right: ã_c ← min(ã_c, a_c) for a change
    to the right (m/s). Default 60 km/h (Kesting, Treiber, Helbing 2007, European rules)."""
    desired_speed_mps: float = number(120.0 / 3.6, 0.0, 40.0, lo_open=True)
    """IDM desired speed v0 (m/s), capped by the lane's speed limit. Default 120 km/h, MODELS.md."""
    accel_mps2: float = number(1.0, 0.0, 10.0, lo_open=True)
    """IDM maximum acceleration a (m/s²). Default 1.0, MODELS.md highway value."""
    comfort_decel_mps2: float = number(1.5, 0.0, 10.0, lo_open=True)
    """IDM comfortable deceleration b (m/s²). Default 1.5, MODELS.md highway value."""
    time_headway_s: float = number(1.0, 0.0, 5.0, lo_open=True)
    """IDM safe time headway T (s). Default 1.0, MODELS.md highway range 1.0–1.5 (Treiber &
    Kesting 2013, Table 11.2), equal to Krauss' τ = 1 s."""
    min_gap_m: float = number(2.0, 0.0, 20.0)
    """IDM standstill gap s0 (m). Default 2, MODELS.md."""
    delta: float = number(4.0, 0.0, 10.0, lo_open=True)
    """IDM acceleration exponent δ (-). Default 4, MODELS.md."""
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


def _incoming_safe(view: Any, idx: np.ndarray, lanes: np.ndarray, v0: np.ndarray, p: MobilParams) -> np.ndarray:
    """(k, 3): the safety criteria also hold against the vehicles changing *into* each candidate
    lane (``target_lane`` = the lane, ``lane`` ≠ it), which the neighbourhood (by ``lane``)
    does not show: one behind the ego must not need to brake harder than ``b_safe`` behind
    it, nor the ego behind one ahead."""
    moving_in = view.target_lane != view.lane  # (n,)
    if not moving_in.any():
        return np.ones(lanes.shape, dtype=bool)
    j = np.flatnonzero(moving_in)
    j = j[None, :]
    into = (view.target_lane[j][:, :, None] == lanes[:, None, :]) & (j != idx[:, None])[:, :, None]  # (k, m, 3)
    ds = (view.s[j] - view.s[idx][:, None])[:, :, None]  # > 0: the other is ahead
    gap = np.abs(ds) - 0.5 * (view.length[j] + view.length[idx][:, None])[:, :, None]
    v_i = view.v[idx][:, None, None]
    v_j = view.v[j][:, :, None]
    ahead = ds > 0.0
    v_follow = np.where(ahead, v_i, v_j)
    v_lead = np.where(ahead, v_j, v_i)
    acc = _idm(p, v_follow, v0[:, None, :], gap, v_lead)
    return ~np.any(into & (acc < -p.safe_decel_mps2), axis=1)


def evaluate(view: Any, vehicles: np.ndarray, params: MobilParams) -> MobilEvaluation:
    """MOBIL's accelerations, incentives and safety criteria (see the module docstring)."""
    p = params
    idx = np.asarray(vehicles, dtype=np.int64)
    k = idx.size
    nb = view.neighborhood()
    road = view.road
    v = view.v[idx]
    s = view.s[idx]
    length = view.length[idx]
    lane = view.lane[idx]
    lanes = lane[:, None] + _OFFSETS[None, :]  # (k, 3)

    # candidate lanes: exist at s; ending lanes only if allowed (or if already in one)
    exists = np.asarray(road.lane_exists(lanes, s[:, None]), dtype=bool)
    end_gap = lane_end_gap_m(view, idx, np.where(exists, lanes, lane[:, None]), p.merge_stop_margin_m)
    end_gap = np.where(exists, end_gap, np.inf)
    ending = np.isfinite(end_gap)
    if not p.enter_ending_lane:
        exists[:, [0, 2]] &= ~ending[:, [0, 2]]

    limit = np.asarray(road.speed_limit_max_mps(np.where(exists, lanes, lane[:, None]), s[:, None]), dtype=float)
    limit = np.where(np.isfinite(limit), limit, view.speed_limit_mps[idx][:, None])
    v0 = np.minimum(p.desired_speed_mps, limit)  # (k, 3)

    gap_f = nb.gap_front_m[idx][:, _COLS]
    v_f = np.nan_to_num(nb.leader_speed_mps[idx][:, _COLS], nan=0.0)
    gap_r = nb.gap_rear_m[idx][:, _COLS]
    has_r = nb.follower[idx][:, _COLS] >= 0
    v_r = np.where(has_r, np.nan_to_num(nb.follower_speed_mps[idx][:, _COLS], nan=0.0), 0.0)

    # ego: a_c (own lane, column 1) and ã_c (columns 0, 2), each with the lane end as an obstacle
    acc_ego = _idm(p, v[:, None], v0, gap_f, v_f)
    acc_end = _idm(p, v[:, None], v0, np.where(ending, end_gap, np.inf), np.zeros_like(end_gap))
    acc_ego = np.where(ending, np.minimum(acc_ego, acc_end), acc_ego)
    a_c = acc_ego[:, 1:2]

    # new follower n: now behind the target lane's leader, after the change behind the ego
    gap_through = gap_r + length[:, None] + gap_f  # inf without leader
    a_n = _idm(p, v_r, v0, gap_through, v_f)
    at_n = _idm(p, v_r, v0, gap_r, v[:, None])
    a_n = np.where(has_r, a_n, 0.0)
    at_n = np.where(has_r, at_n, 0.0)
    gain_n = at_n - a_n

    # old follower o: now behind the ego, after the change behind the ego's leader
    a_o = _idm(p, v_r[:, 1], v0[:, 1], gap_r[:, 1], v)
    at_o = _idm(p, v_r[:, 1], v0[:, 1], gap_through[:, 1], v_f[:, 1])
    gain_o = np.where(has_r[:, 1], at_o - a_o, 0.0)[:, None]

    at_c = acc_ego.copy()
    inc = np.zeros((k, 3))
    if p.asymmetric:
        # no overtaking on the right above v_crit
        fast = v > p.critical_speed_mps
        at_c[:, 0] = np.where(fast, np.minimum(at_c[:, 0], a_c[:, 0]), at_c[:, 0])
        inc[:, 0] = at_c[:, 0] - a_c[:, 0] + p.politeness * gain_o[:, 0] - (p.threshold_mps2 - p.bias_mps2)
        own_ending = ending[:, 1]
        # leaving an ending lane to the left: the bias points to the target (mandatory change)
        left_thr = np.where(own_ending, p.threshold_mps2 - p.bias_mps2, p.threshold_mps2 + p.bias_mps2)
        inc[:, 2] = at_c[:, 2] - a_c[:, 0] + p.politeness * gain_n[:, 2] - left_thr
    else:
        for c in (0, 2):
            inc[:, c] = at_c[:, c] - a_c[:, 0] + p.politeness * (gain_n[:, c] + gain_o[:, 0]) - p.threshold_mps2

    safe = (at_n >= -p.safe_decel_mps2) & (acc_ego >= -p.safe_decel_mps2) & _incoming_safe(view, idx, lanes, v0, p)
    mandatory = ending[:, 1] & (end_gap[:, 1] < p.merge_mandatory_distance_m)
    safe[:, 1] = True
    return MobilEvaluation(exists=exists, acc_ego=acc_ego, gain_new_follower=gain_n, gain_old_follower=gain_o,
                           acc_new_follower=at_n, incentive=inc, safe=safe, mandatory=mandatory)


def lane_change_decision(view: Any, vehicles: np.ndarray, params: MobilParams) -> np.ndarray:
    """MOBIL's lane-change request (+1 left, −1 right, 0 keep) for each of ``vehicles``."""
    idx = np.asarray(vehicles, dtype=np.int64)
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64)
    ev = evaluate(view, idx, params)
    ok = ev.exists & ev.safe & ((ev.incentive > 0.0) | ev.mandatory[:, None])
    ok[:, 1] = False
    score = np.where(ok, ev.incentive, -np.inf)
    # a mandatory change ignores the incentive: prefer any admissible side (only left exists in practice)
    score = np.where(ok & ev.mandatory[:, None], np.maximum(score, 0.0) + 1e6, score)
    best = np.argmax(score, axis=1)
    request = np.where(np.isfinite(score[np.arange(idx.size), best]), _OFFSETS[best], 0)
    request = np.where(view.lane_change[idx] != 0, 0, request)
    request = np.where(settled(view, idx, params.settle_tolerance_m) | ev.mandatory, request, 0)

    def unsafe_pair(i: np.ndarray) -> np.ndarray:
        # the rear vehicle of each pair behind the front one: IDM deceleration beyond b_safe
        ds = view.s[i][None, :] - view.s[i][:, None]
        gap = np.abs(ds) - 0.5 * (view.length[i][None, :] + view.length[i][:, None])
        v_rear = np.where(ds > 0, view.v[i][:, None], view.v[i][None, :])
        v_front = np.where(ds > 0, view.v[i][None, :], view.v[i][:, None])
        return _idm(params, v_rear, params.desired_speed_mps, gap, v_front) < -params.safe_decel_mps2

    return resolve_conflicts(view, idx, request.astype(np.int64), unsafe_pair)


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

    def act(self, view: Any) -> tuple[np.ndarray, np.ndarray]:
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} for each driven vehicle."""
        request = self.decide(view, self.vehicles, self.params)
        throttle = accel_to_throttle(self.acceleration(view), self.vehicle_params)
        return throttle, request


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


def make_driver(vehicles: np.ndarray, params: MobilParams | None, config: Any,
                rng: np.random.Generator) -> KraussLaneChangeDriver:
    """Factory of the ``mobil`` model (:class:`evoscen_sim.models.ModelSpec`)."""
    params = MobilParams() if params is None else params
    return KraussLaneChangeDriver(vehicles, lane_change_decision, params, krauss_for(config, rng),
                                  vehicle_params_from_config(config), params.merge_stop_margin_m)


SPEC = ModelSpec(
    name="mobil",
    roles=("sut", "bv"),
    factory=make_driver,
    params_type=MobilParams,
    description="MOBIL lane changes (IDM accelerations, keep-right variant) + Krauss car following (SPEC 4)",
)
