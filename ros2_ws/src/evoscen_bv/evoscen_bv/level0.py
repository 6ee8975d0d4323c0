"""Level-0 traffic (SPEC §3.3): keep the lane, change only where the road forces it.

The level-0 driver is non-strategic. Longitudinally it follows the IDM
(:mod:`evoscen_sim.car_following`) behind the nearest vehicle ahead in its lane — and,
while it changes lanes, behind the nearer-braking of the leaders in its current and target
lanes. Laterally it never changes lanes on the mainline. On the merge lane (lane I, whose
end the road forces) it

* requests a change to the left as soon as the gap in lane II is acceptable: front and
  rear bumper gaps of at least ``merge_min_front_gap_m`` / ``merge_min_rear_gap_m`` plus
  ``merge_closing_headway_s`` seconds of any closing speed (so a faster follower or a
  slower leader needs a proportionally larger gap), and
* treats the end of the merge lane as a standing obstacle ``merge_stop_margin_m`` before
  the lane ends, so it waits there rather than running off the road when no gap comes.

It is the training environment's level-0 traffic and the background vehicles' driver
until trained policies exist; the SUT slot can run it too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evoscen_sim.car_following import IdmParams, idm_acceleration
from evoscen_sim.neighbors import LEFT, OWN
from evoscen_sim.vehicle import accel_to_throttle

MERGE_LANE = 0


@dataclass(frozen=True)
class Level0Params:
    """Level-0 driver parameters (IDM plus the merge rule)."""

    idm: IdmParams = IdmParams()
    desired_speed_range_mps: tuple[float, float] = (27.0, 33.0)
    merge_min_front_gap_m: float = 8.0
    merge_min_rear_gap_m: float = 8.0
    merge_closing_headway_s: float = 1.5
    merge_stop_margin_m: float = 15.0


class Level0Driver:
    """Level-0 drivers for a fixed set of vehicles (indices into the world's arrays)."""

    def __init__(self, vehicles: np.ndarray, params: Level0Params, rng: np.random.Generator, vehicle_params) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.params = params
        self.vehicle_params = vehicle_params
        lo, hi = params.desired_speed_range_mps
        self.desired_speed_mps = rng.uniform(lo, hi, size=self.vehicles.size)

    def act(self, world) -> tuple[np.ndarray, np.ndarray]:  # world: evoscen_sim.world.World
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} for each hosted vehicle."""
        idx = self.vehicles
        p = self.params
        nb = world.neighborhood()
        v = world.v[idx]
        v0 = np.minimum(self.desired_speed_mps, world.speed_limit_mps[idx])
        max_decel = self.vehicle_params.max_brake_mps2
        accel = idm_acceleration(v, v0, nb.gap_front_m[idx, OWN], nb.leader_speed_mps[idx, OWN], p.idm, max_decel)
        request = np.zeros(idx.size, dtype=np.int64)

        # while changing lanes, also follow the leader in the target lane
        lc = world.lane_change[idx]
        changing = lc != 0
        if changing.any():
            col = OWN + lc[changing]
            rows = idx[changing]
            a_target = idm_acceleration(
                v[changing], v0[changing], nb.gap_front_m[rows, col], nb.leader_speed_mps[rows, col], p.idm, max_decel
            )
            accel[changing] = np.minimum(accel[changing], a_target)

        on_merge = (world.lane[idx] == MERGE_LANE) & ~changing
        if on_merge.any():
            rows = idx[on_merge]
            vm = v[on_merge]
            # the lane end is a standing obstacle
            end_gap = world.road.lane_end_s[MERGE_LANE] - p.merge_stop_margin_m - (world.s[rows] + 0.5 * world.length[rows])
            a_end = idm_acceleration(vm, v0[on_merge], end_gap, np.zeros(rows.size), p.idm, max_decel)
            accel[on_merge] = np.minimum(accel[on_merge], a_end)
            # acceptable gap in lane II? (fmax drops the nan of a missing neighbour: no closing)
            closing_front = np.fmax(0.0, vm - nb.leader_speed_mps[rows, LEFT])
            closing_rear = np.fmax(0.0, nb.follower_speed_mps[rows, LEFT] - vm)
            front_ok = nb.gap_front_m[rows, LEFT] >= p.merge_min_front_gap_m + p.merge_closing_headway_s * closing_front
            rear_ok = nb.gap_rear_m[rows, LEFT] >= p.merge_min_rear_gap_m + p.merge_closing_headway_s * closing_rear
            request[on_merge] = front_ok & rear_ok
        return accel_to_throttle(accel, self.vehicle_params), request


def level0_params_from_config(cfg) -> Level0Params:
    """Level-0 parameters from a :class:`evoscen_sim.config.ScenarioConfig`."""
    c = cfg.level0
    return Level0Params(
        idm=IdmParams(
            time_headway_s=c.time_headway_s,
            min_gap_m=c.min_gap_m,
            accel_mps2=c.accel_mps2,
            comfort_decel_mps2=c.comfort_decel_mps2,
            delta=c.delta,
        ),
        desired_speed_range_mps=tuple(c.desired_speed_mps),
        merge_min_front_gap_m=c.merge_min_front_gap_m,
        merge_min_rear_gap_m=c.merge_min_rear_gap_m,
        merge_closing_headway_s=c.merge_closing_headway_s,
        merge_stop_margin_m=c.merge_stop_margin_m,
    )
