"""FISS / FISS+ as an evoscen SUT: the Frenet-frame sampling planners of ``fiss-planner`` (PyPI,
Apache-2.0; Sun et al., RA-L 2022 and IROS 2023) plugged in through the ``evoscen.sut`` entry point.

Each step, for the SUT, the adapter gives the planner (``fiss_planner.Planner.plan``):

* **the reference line**: the centre line of the SUT's lane (its target lane during a lane change),
  from ``road.lane_center_d``, from ``reference_behind_m`` behind the SUT to far enough ahead for the
  longest horizon at the vehicle's top speed;
* **the lane corridor**: that lane and the lanes to its right and left, each a band between its
  borders (``road.lane_bounds_d``) along the reference line, with its speed limit; a lane that does
  not exist somewhere (the merge lane before 600 m and from 960 m) has zero width there. A lane that
  ends (``distance_to_lane_end`` finite: the merge lane) carries ``ending_lane_cost``. A change into a
  neighbouring lane is offered only when evoscen would execute the request now: no change under way,
  the lane exists at the SUT's position, and the SUT has settled within ``settle_tolerance_m`` of its
  lane's centre line (on a lane that ends it need not settle);
* **the other vehicles** within ``look_behind_m`` behind and ``look_ahead_m`` ahead, each predicted
  at constant velocity (speed and heading held, ``fiss_planner.predict_constant_velocity``).

The frame is the road's own: x is the arc length ``s`` along the road's reference line, y the lateral
offset ``d`` (the shipped road's curvature, at most 1/2000 m, is left out; steering is the
simulation's lateral controller's, not the planner's). Of the chosen trajectory the adapter takes

* **the acceleration**: the planned speed's mean change over the first ``preview_s`` (0.5 s),
  ``(s_d(preview_s) - s_d(0)) / preview_s``, turned into throttle with ``accel_to_throttle`` and the
  scenario's vehicle limits;
* **the target lane**: the trajectory's end lane; +1 / -1 (a neighbouring lane) is the lane-change
  request.

When no candidate is valid (``PlanResult.success`` false) it keeps its lane and follows with IDM
(Treiber et al. 2000) behind its leader, stopping ``lane_end_margin_m`` before the end of a lane that
ends (fiss-planner's own ``LocalPlanner`` keeps its previous plan and then brakes; the adapter calls the
planner directly and has none). The planner runs single-threaded without a time budget, so its answer
depends only on what it is given: the same in both runners. It draws no random numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import fiss_planner as fp
import numpy as np
from evoscen import OWN, InputError, ModelSpec, accel_to_throttle, flag, integer, number, number_range, text

PLANNERS = ("fop", "fop_plus", "fiss", "fiss_plus")
"""fiss-planner's planners: FOP (Werling et al. 2010), FOP+, FISS (2022), FISS+ (2023)."""


@dataclass(frozen=True)
class FissSutParams:
    """``models.fiss`` in the scenario YAML. Defaults: fiss-planner 1.0.0's own (``PlannerConfig()``)
    where the field is one of its settings, else this adapter's choice."""

    planner: str = text("fiss_plus", PLANNERS)
    """Which of fiss-planner's planners: fop, fop_plus, fiss, fiss_plus (its default)."""
    desired_speed_mps: float = number(30.0, 0.0, 40.0, lo_open=True)
    """The planner's target speed (m/s), capped by the lane's speed limit; adapter default."""
    horizon_s: tuple[float, float] = number_range((3.0, 5.0), 0.5, 10.0)
    """[min, max] duration of the sampled trajectories (s); fiss-planner's sampling.min_t, max_t."""
    num_speed: int = integer(5, 1, 20)
    """Sampled end speeds; fiss-planner's sampling.num_speed."""
    num_t: int = integer(5, 1, 20)
    """Sampled durations; fiss-planner's sampling.num_t."""
    num_width: int = integer(5, 1, 20)
    """Sampled lateral end offsets per lane; fiss-planner's sampling.num_width."""
    time_headway_s: float = number(1.5, 0.0, 10.0)
    """Desired time headway to the leader (s); fiss-planner's cost.desired_time_headway."""
    lane_change_weight: float = number(5.0, 0.0, 1000.0)
    """Cost of ending in another lane; fiss-planner's cost.w_lane_change."""
    min_gap_m: float = number(2.0, 0.0, 50.0)
    """Hard minimum gap to any vehicle (m); fiss-planner's safety.min_gap."""
    min_ttc_s: float = number(1.5, 0.0, 10.0)
    """Hard minimum time to collision (s); fiss-planner's safety.min_ttc."""
    ignore_rear_in_lane: bool = flag(True)
    """Vehicles behind in the own lane do not reject a trajectory; fiss-planner's
    collision.ignore_rear_in_lane (its default: false). Adapter default true: with false a
    tailgater rejects every candidate and the SUT ends up braking in dense traffic (seed 4 of the
    shipped scenario: 1,423 of 3,000 steps without a valid trajectory, then stopped for good)."""
    ending_lane_cost: float = number(20.0, 0.0, 1000.0)
    """Extra cost of a trajectory ending in a lane that ends (the merge lane); adapter default."""
    preview_s: float = number(0.5, 0.0, 2.0)
    """The command is the trajectory's mean acceleration over its first ``preview_s`` (s; at least one
    step). Adapter default 0.5 s: each step plans again from the acceleration just realised, so over
    one step (0.1 s) the command follows the plan's jerk only slowly; behind the merge of seed 5 the
    SUT then braked to 1 m/s (0.5 s and 1 s: no such stop on seeds 0-5)."""
    look_ahead_m: float = number(150.0, 0.0, 500.0)
    """Vehicles up to this far ahead (centre to centre, m) are given to the planner; adapter default."""
    look_behind_m: float = number(60.0, 0.0, 500.0)
    """Vehicles up to this far behind (m) are given to the planner; adapter default."""
    reference_behind_m: float = number(10.0, 1.0, 100.0)
    """The reference line starts this far behind the SUT (m); adapter default."""
    settle_tolerance_m: float = number(0.5, 0.0, 1.75)
    """A lane change is offered only within this distance of the lane's centre line (m), as the
    built-in MOBIL and Nilsson wait (docs/plugins.md §8)."""
    fallback_accel_mps2: float = number(1.5, 0.0, 3.0, lo_open=True)
    """Fallback (no valid trajectory): IDM maximum acceleration a (m/s²); Treiber's highway value."""
    fallback_comfort_decel_mps2: float = number(2.0, 0.0, 8.0, lo_open=True)
    """Fallback: IDM comfortable deceleration b (m/s²); Treiber's highway value."""
    lane_end_margin_m: float = number(15.0, 0.0, 100.0)
    """Fallback: on a lane that ends, stop this far before its end (m); the built-in models' merge_stop_margin_m."""


STATION_M = 2.0
"""Spacing of the reference line's points and the corridor's stations (m)."""


def planner_config(p: FissSutParams, dt_s: float) -> fp.PlannerConfig:
    """fiss-planner's configuration for ``p``: its defaults, the fields of ``p``, the step ``dt_s``;
    one thread and no time budget (deterministic)."""
    cfg = fp.make_config(p.planner, dt=dt_s, min_t=float(p.horizon_s[0]), max_t=float(p.horizon_s[1]),
                         num_speed=p.num_speed, num_t=p.num_t, num_width=p.num_width)
    cfg.num_threads = 1
    cfg.keep_candidates = False
    cfg.fiss_plus.time_budget = 0.0  # a time budget would make the answer depend on the machine's speed
    cfg.cost.desired_time_headway = p.time_headway_s
    cfg.cost.w_lane_change = p.lane_change_weight
    cfg.safety.min_gap = p.min_gap_m
    cfg.safety.min_ttc = p.min_ttc_s
    cfg.collision.ignore_rear_in_lane = p.ignore_rear_in_lane
    try:
        cfg.validate()
    except (RuntimeError, ValueError) as exc:  # its own check, beyond the declarators': one line, no traceback
        raise InputError(f"models.fiss: fiss-planner {fp.__version__} refuses the configuration: {exc}") from None
    return cfg


def planner_vehicle(vehicle) -> fp.VehicleParams:
    """fiss-planner's vehicle from the scenario's ``vehicle`` section (evoscen's VehicleParams)."""
    out = fp.VehicleParams()
    out.length = vehicle.length_m
    out.width = vehicle.width_m
    out.wheelbase = vehicle.wheelbase_m
    out.max_accel = vehicle.max_accel_mps2
    out.max_decel = vehicle.max_brake_mps2
    out.max_speed = vehicle.max_speed_mps
    out.max_steer = vehicle.max_steer_rad
    out.max_steer_rate = vehicle.max_steer_rate_radps
    return out


class FissSut:
    """The driver: one fiss-planner ``Planner`` per driven vehicle, asked once per step."""

    def __init__(self, vehicles: np.ndarray, params: FissSutParams, vehicle, dt_s: float) -> None:
        self.vehicles = vehicles
        self.p = params
        self.vehicle = vehicle  # the scenario's vehicle limits: throttle scaling
        self.dt_s = dt_s
        cfg = planner_config(params, dt_s)
        self.planners = [fp.make_planner(cfg, planner_vehicle(vehicle)) for _ in vehicles]
        self.last = [None] * len(vehicles)  # the last PlanResult per vehicle (for inspection)

    def act(self, view):
        accel = np.zeros(len(self.vehicles))
        request = np.zeros(len(self.vehicles), dtype=np.int64)
        for row, i in enumerate(self.vehicles):
            accel[row], request[row] = self.plan(row, view, int(i))
        return accel_to_throttle(accel, self.vehicle), request

    def may_change(self, view, i: int, lane: int) -> bool:
        """Would evoscen execute a lane-change request of vehicle ``i`` now (and is it settled)?"""
        if view.lane_change[i] != 0:
            return False
        s = float(view.s[i])
        if np.isfinite(view.road.distance_to_lane_end(lane, s)):  # leaving a lane that ends: no need to settle
            return True
        return abs(float(view.d[i]) - float(view.road.lane_center_d(lane, s))) <= self.p.settle_tolerance_m

    @staticmethod
    def lanes_along(road, ref_lane: int, road_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The lanes ``ref_lane`` - 1 … + 1 that are on the road and, along ``road_s`` (one row per lane), whether
        each exists and its right and left borders: one broadcast query each, the values of the per-lane ones."""
        lanes = np.arange(max(0, ref_lane - 1), min(road.num_lanes, ref_lane + 2))
        right, left = road.lane_bounds_d(lanes[:, None], road_s[None, :])
        return lanes, road.lane_exists(lanes[:, None], road_s[None, :]), right, left

    def corridor(self, view, i: int, ref_lane: int, road_s: np.ndarray, centre: np.ndarray, along) -> fp.Corridor:
        """The lanes ``ref_lane`` - 1 … + 1 along ``road_s`` (``along``: :meth:`lanes_along`) as bands relative
        to ``centre``."""
        road = view.road
        s, lane = float(view.s[i]), int(view.lane[i])
        allowed = self.may_change(view, i, lane)
        corridor = fp.Corridor(road_s - road_s[0])
        for k, exists, right, left in zip(*along):
            k = int(k)
            if not exists.any():
                continue
            band = fp.LaneBand()
            band.lane_id = k
            band.offset = k - ref_lane
            band.right = (right - centre).tolist()
            band.left = (left - centre).tolist()
            band.center = (0.5 * (right + left) - centre).tolist()  # the centre line (lane_center_d) or, where
            # the lane does not exist, the middle of its zero-width band: the same value
            limit = float(road.speed_limit_max_mps(k, s))
            band.speed_limit = limit if np.isfinite(limit) else float(view.speed_limit_mps[i])
            band.change_allowed = k == ref_lane or (allowed and bool(road.lane_exists(k, s)))
            band.extra_cost = self.p.ending_lane_cost if np.isfinite(road.distance_to_lane_end(k, s)) else 0.0
            corridor.add_lane(band)
        return corridor

    def obstacles(self, view, i: int, horizon_s: float) -> list:
        """The other vehicles near ``i``, each predicted at constant velocity in the (s, d) frame."""
        s = view.s
        near = (s >= s[i] - self.p.look_behind_m) & (s <= s[i] + self.p.look_ahead_m)
        near[i] = False
        return [fp.predict_constant_velocity(int(j), float(s[j]), float(view.d[j]), float(view.psi[j]),
                                             float(view.v[j]), float(view.length[j]), float(view.width[j]),
                                             horizon_s, self.dt_s)
                for j in np.flatnonzero(near)]

    def plan(self, row: int, view, i: int) -> tuple[float, int]:
        """Vehicle ``i``'s acceleration (m/s²) and lane-change request from one planning cycle."""
        road, p = view.road, self.p
        s, d, v, lane = float(view.s[i]), float(view.d[i]), float(view.v[i]), int(view.lane[i])
        ref_lane = int(view.target_lane[i])  # = lane when not changing
        reach = p.horizon_s[1] * self.vehicle.max_speed_mps + 2 * STATION_M
        road_s = s - p.reference_behind_m + np.arange(0.0, p.reference_behind_m + reach, STATION_M)
        along = self.lanes_along(road, ref_lane, road_s)
        right, left = (b[int(np.flatnonzero(along[0] == ref_lane)[0])] for b in along[2:])
        centre = 0.5 * (right + left)  # road.lane_center_d(ref_lane, road_s)
        reference = fp.ReferenceLine(road_s.tolist(), centre.tolist(), STATION_M)
        corridor = self.corridor(view, i, ref_lane, road_s, centre, along)
        psi = float(view.psi[i])
        start = fp.FrenetState(s=s - road_s[0], s_d=v * np.cos(psi), s_dd=float(view.accel[i]),
                               d=d - float(road.lane_center_d(ref_lane, s)), d_d=v * np.sin(psi))
        target = float(np.fmin(p.desired_speed_mps, view.speed_limit_mps[i]))
        result = self.planners[row].plan(start, reference, corridor, self.obstacles(view, i, p.horizon_s[1] + 0.5),
                                         target_speed=target)
        self.last[row] = result
        if not result.success:
            return self.fallback(view, i), 0
        traj = result.trajectory
        s_d = np.asarray(traj.s_d)
        k = min(max(int(round(p.preview_s / self.dt_s)), 1), s_d.size - 1)
        accel = (s_d[k] - s_d[0]) / (k * self.dt_s) if k > 0 else 0.0
        offset = int(traj.lane)
        request = offset if (offset in (-1, 1) and ref_lane == lane and self.may_change(view, i, lane)) else 0
        return float(accel), request

    def idm(self, v: float, v0: float, gap_m: float, v_leader: float) -> float:
        """IDM acceleration (m/s²) at speed ``v`` behind a leader ``gap_m`` ahead at ``v_leader``."""
        p = self.p
        free = 1.0 - (v / v0) ** 4 if v0 > 0.0 else -1.0
        if not np.isfinite(gap_m):  # no leader: gap inf, speed nan
            return p.fallback_accel_mps2 * free
        if gap_m <= 0.0:
            return -self.vehicle.max_brake_mps2
        braking = v * (v - v_leader) / (2.0 * np.sqrt(p.fallback_accel_mps2 * p.fallback_comfort_decel_mps2))
        wanted = p.min_gap_m + max(0.0, v * p.time_headway_s + braking)
        return p.fallback_accel_mps2 * (free - (wanted / gap_m) ** 2)

    def fallback(self, view, i: int) -> float:
        """No valid trajectory: keep the lane (no request) and follow with IDM behind the leader in the own
        lane, during a change also the target lane's, and before the end of a lane that ends."""
        nb = view.neighborhood()
        v, s, lane = float(view.v[i]), float(view.s[i]), int(view.lane[i])
        v0 = float(np.fmin(self.p.desired_speed_mps, view.speed_limit_mps[i]))
        accel = self.idm(v, v0, nb.gap_front_m[i, OWN], nb.leader_speed_mps[i, OWN])
        col = OWN + int(view.target_lane[i]) - lane
        if col != OWN:
            accel = min(accel, self.idm(v, v0, nb.gap_front_m[i, col], nb.leader_speed_mps[i, col]))
        to_end = float(view.road.distance_to_lane_end(int(view.target_lane[i]), s))
        if np.isfinite(to_end):
            accel = min(accel, self.idm(v, v0, to_end - 0.5 * float(view.length[i]) - self.p.lane_end_margin_m, 0.0))
        return accel


def make(vehicles: np.ndarray, params: FissSutParams, config, rng: np.random.Generator) -> FissSut:
    """The factory: the SUT's world index, ``models.fiss``, the scenario, a seeded generator (unused:
    the planner draws nothing)."""
    return FissSut(vehicles, params, config.vehicle, config.dt_s)


SPEC = ModelSpec(name="fiss", roles=("sut",), factory=make, params_type=FissSutParams,
                 description="FISS+ / FISS Frenet sampling planner (fiss-planner 1.0.0, Apache-2.0)")
