# --8<-- [start:header]
"""Your first SUT: a small rule-based planner for evoscen (walk-through: docs/plugins.md).

IDM (Treiber, Hennecke, Helbing 2000) behind the own lane's leader, also the target lane's while
changing; a lane that ends (lane 0) ends in a standing obstacle. Change left (never right) when the
left lane is free and the own lane ends or the leader within ``look_ahead_m`` is slower than
``slow_leader_mps``; not while changing, nor before settling near the lane's centre line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from evoscen import LEFT, OWN, ModelSpec, accel_to_throttle, number
# --8<-- [end:header]


# --8<-- [start:params]
@dataclass(frozen=True)
class FirstSutParams:
    """``models.first_sut`` in the scenario YAML, validated like any scenario key."""

    desired_speed_mps: float = number(30.0, 0.0, 40.0, lo_open=True)
    """IDM desired speed v0 (m/s), capped by the lane's speed limit."""
    time_gap_s: float = number(1.5, 0.0, 10.0, lo_open=True)
    """IDM time gap T (s); Treiber's highway value."""
    min_gap_m: float = number(2.0, 0.0, 50.0)
    """IDM standstill gap s0 (m); Treiber's highway value."""
    accel_mps2: float = number(1.5, 0.0, 3.0, lo_open=True)
    """IDM maximum acceleration a (m/s²); at most vehicle.max_accel_mps2 (3)."""
    comfort_decel_mps2: float = number(2.0, 0.0, 8.0, lo_open=True)
    """IDM comfortable deceleration b (m/s²); Treiber's highway value."""
    slow_leader_mps: float = number(27.0, 0.0, 40.0)
    """Overtake a leader slower than this (m/s)."""
    look_ahead_m: float = number(80.0, 0.0, 500.0)
    """Only a leader within this bumper gap counts (m)."""
    min_front_gap_m: float = number(20.0, 0.0, 200.0)
    """Left lane free: bumper gap to its leader at least (m)."""
    min_rear_gap_m: float = number(10.0, 0.0, 200.0)
    """Left lane free: bumper gap to its follower at least (m) ..."""
    rear_time_gap_s: float = number(2.0, 0.0, 10.0)
    """... plus this per m/s the follower is faster (s)."""
    settle_tolerance_m: float = number(0.3, 0.0, 1.75)
    """Decide again only this close to the lane's centre line (m)."""
    lane_end_margin_m: float = number(15.0, 0.0, 100.0)
    """Stop this far before a lane's end (m), as the built-ins' merge_stop_margin_m (closer: into the taper)."""
# --8<-- [end:params]


# --8<-- [start:driver]
class FirstSut:
    """The driver: ``act(view)`` for its vehicles (the SUT: one)."""

    def __init__(self, vehicles: np.ndarray, params: FirstSutParams, vehicle_params) -> None:
        self.vehicles = vehicles
        self.p = params
        self.vehicle = vehicle_params  # vehicle limits: throttle scaling

    def act(self, view):  # view: a traffic view (evoscen.TrafficView)
        nb = view.neighborhood()
        accel = np.zeros(len(self.vehicles))
        request = np.zeros(len(self.vehicles), dtype=np.int64)
        for row, i in enumerate(self.vehicles):
            accel[row] = self.acceleration(view, nb, i)
            request[row] = self.decide(view, nb, i)
        return accel_to_throttle(accel, self.vehicle), request
# --8<-- [end:driver]

    # --8<-- [start:idm]
    def idm(self, v: float, v0: float, gap_m: float, v_leader: float) -> float:
        """IDM acceleration (m/s²) at speed ``v`` behind a leader ``gap_m`` ahead at ``v_leader``."""
        p = self.p
        free = 1.0 - (v / v0) ** 4
        if not np.isfinite(gap_m):  # no leader: gap inf, speed nan
            return p.accel_mps2 * free
        if gap_m <= 0.0:  # touching or overlapping: full brake
            return -self.vehicle.max_brake_mps2
        braking = v * (v - v_leader) / (2.0 * np.sqrt(p.accel_mps2 * p.comfort_decel_mps2))
        wanted = p.min_gap_m + max(0.0, v * p.time_gap_s + braking)
        return p.accel_mps2 * (free - (wanted / gap_m) ** 2)

    def acceleration(self, view, nb, i: int) -> float:
        """Vehicle ``i``'s acceleration (m/s²): IDM behind every leader that matters."""
        v, s, lane = float(view.v[i]), float(view.s[i]), int(view.lane[i])
        v0 = float(np.fmin(self.p.desired_speed_mps, view.speed_limit_mps[i]))  # fmin: a nan limit is ignored
        accel = self.idm(v, v0, nb.gap_front_m[i, OWN], nb.leader_speed_mps[i, OWN])
        col = OWN + int(view.target_lane[i]) - lane  # the target lane's column
        if col != OWN:  # changing lanes: the target lane's leader too
            accel = min(accel, self.idm(v, v0, nb.gap_front_m[i, col], nb.leader_speed_mps[i, col]))
        else:
            to_end = float(view.road.distance_to_lane_end(lane, s))  # inf where the lane runs on
            if np.isfinite(to_end):  # the merge lane: its end is an obstacle
                gap = to_end - 0.5 * float(view.length[i]) - self.p.lane_end_margin_m
                accel = min(accel, self.idm(v, v0, gap, 0.0))
        return accel
    # --8<-- [end:idm]

    # --8<-- [start:decide]
    def decide(self, view, nb, i: int) -> int:
        """Vehicle ``i``'s lane-change request: +1 (left) or 0 (keep)."""
        p = self.p
        if view.lane_change[i] != 0:  # changing: a request would be ignored
            return 0
        s, lane = float(view.s[i]), int(view.lane[i])
        if not bool(view.road.lane_exists(lane + 1, s)):  # the leftmost lane: nowhere to go
            return 0
        lane_ends = bool(np.isfinite(view.road.distance_to_lane_end(lane, s)))  # the merge lane
        # a change completes ~1.75 m short of the target's centre line: deciding there ping-pongs, so
        # settle first (not on a lane that ends: a vehicle stopped there cannot settle)
        off_centre_m = abs(float(view.d[i]) - float(view.road.lane_center_d(lane, s)))
        if not lane_ends and off_centre_m > p.settle_tolerance_m:
            return 0
        slow_leader = (nb.gap_front_m[i, OWN] < p.look_ahead_m  # no leader: gap inf, speed nan
                       and nb.leader_speed_mps[i, OWN] < p.slow_leader_mps)
        if (lane_ends or slow_leader) and self.left_lane_free(view, nb, i):
            return 1
        return 0

    def left_lane_free(self, view, nb, i: int) -> bool:
        """The gap rule for the lane to the left of vehicle ``i``."""
        p = self.p
        closing_mps = np.fmax(nb.follower_speed_mps[i, LEFT] - view.v[i], 0.0)  # fmax: no follower (nan) -> 0
        if nb.gap_front_m[i, LEFT] < p.min_front_gap_m:
            return False
        if nb.gap_rear_m[i, LEFT] < p.min_rear_gap_m + p.rear_time_gap_s * closing_mps:
            return False
        # one two lanes over changing into the same lane is not in the LEFT column yet
        left = int(view.lane[i]) + 1
        moving_in = (view.lane_change != 0) & (view.target_lane == left) & (view.lane != left)
        near = np.abs(view.s - view.s[i]) < max(p.min_front_gap_m, p.min_rear_gap_m) + view.length[i]
        return not bool(np.any(moving_in & near))
    # --8<-- [end:decide]


# --8<-- [start:spec]
def make(vehicles: np.ndarray, params: FirstSutParams, config, rng: np.random.Generator) -> FirstSut:
    """The factory: the SUT's world index, ``models.first_sut``, the scenario, a seeded generator."""
    return FirstSut(vehicles, params, config.vehicle)


SPEC = ModelSpec(name="first_sut", roles=("sut",), factory=make, params_type=FirstSutParams,
                 description="your first SUT: IDM, change left past a slow leader (docs/plugins.md)")
# --8<-- [end:spec]
