"""Level-0 traffic (docs/method.md §3.3): keep the lane, change only where the road forces it.

The level-0 driver is non-strategic. Longitudinally it follows the IDM
(:mod:`evoscen_sim.physics.idm`) behind the nearest vehicle ahead in its lane — and,
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
from evoscen_sim.config.config_schema import Level0Config
from evoscen_sim.jit import kernel
from evoscen_sim.physics.idm import IdmParams, idm_scalar
from evoscen_sim.physics.neighbors import LEFT, OWN
from evoscen_sim.road.road_model import MERGE_LANE


def _idm_from_section(c: Level0Config) -> IdmParams:
    return IdmParams(
        time_headway_s=c.time_headway_s,
        min_gap_m=c.min_gap_m,
        accel_mps2=c.accel_mps2,
        comfort_decel_mps2=c.comfort_decel_mps2,
        delta=c.delta,
    )


_DEFAULTS = Level0Config()
"""The single source of the level-0 defaults: the scenario's ``level0`` section."""


@dataclass(frozen=True)
class Level0Params:
    """Level-0 driver parameters (IDM plus the merge rule): the ``level0`` section, structured
    for the driver; the defaults are the section's (:class:`evoscen_sim.config.scenario_config.Level0Config`)."""

    idm: IdmParams = _idm_from_section(_DEFAULTS)
    desired_speed_range_mps: tuple[float, float] = _DEFAULTS.desired_speed_mps
    merge_min_front_gap_m: float = _DEFAULTS.merge_min_front_gap_m
    merge_min_rear_gap_m: float = _DEFAULTS.merge_min_rear_gap_m
    merge_closing_headway_s: float = _DEFAULTS.merge_closing_headway_s
    merge_stop_margin_m: float = _DEFAULTS.merge_stop_margin_m


class Level0Driver:
    """Level-0 drivers for a fixed set of vehicles (indices into the world's arrays)."""

    def __init__(self, vehicles: np.ndarray, params: Level0Params, rng: np.random.Generator, vehicle_params) -> None:
        self.vehicles = np.asarray(vehicles, dtype=np.int64)
        self.params = params
        self.vehicle_params = vehicle_params
        lo, hi = params.desired_speed_range_mps
        self.desired_speed_mps = rng.uniform(lo, hi, size=self.vehicles.size)
        self.speed_cap = True
        """Whether the desired speed is capped by the lane's speed limit (False: ``bvs.makeup: highd``)."""

    def restrict(self, positions: np.ndarray) -> None:
        """Host only the vehicles at ``positions`` of :attr:`vehicles`, each with the state it was
        built with (a BV node's share: :mod:`evoscen_sim.nodes.bv_nodes`); before the first :meth:`act`."""
        self.vehicles = self.vehicles[positions]
        self.desired_speed_mps = self.desired_speed_mps[positions]

    def _no_limits(self, n: int) -> np.ndarray:
        """Limits that cap nothing (``inf``) for ``n`` vehicles, made once per count (read-only: the kernel only reads)."""
        c = getattr(self, "_inf_limits", None)
        if c is None or c.shape[0] != n:
            c = self._inf_limits = np.full(n, np.inf)
            c.flags.writeable = False
        return c

    def act(self, world) -> tuple[np.ndarray, np.ndarray]:  # world: evoscen_sim.physics.world.World
        """Throttle in [-1, 1] and lane-change request in {-1, 0, +1} for each hosted vehicle."""
        p = self.params
        idm = p.idm
        vp = self.vehicle_params
        nb = world.neighborhood()
        return _level0_kernel(
            self.vehicles, world.v, world.s, world.lane, world.lane_change, world.length,
            world.speed_limit_mps if self.speed_cap else self._no_limits(world.n), self.desired_speed_mps,
            nb.gap_front_m, nb.leader_speed_mps, nb.gap_rear_m, nb.follower_speed_mps,
            float(world.road.lane_end_s[MERGE_LANE]),
            idm.time_headway_s, idm.min_gap_m, idm.accel_mps2, idm.comfort_decel_mps2, idm.delta,
            p.merge_min_front_gap_m, p.merge_min_rear_gap_m, p.merge_closing_headway_s, p.merge_stop_margin_m,
            vp.max_accel_mps2, vp.max_brake_mps2,
        )


@kernel
def _level0_kernel(
    idx, v, s, lane, lane_change, length, speed_limit, desired,
    gap_front, v_front, gap_rear, v_rear, merge_lane_end_s,
    time_headway, min_gap, accel_max, comfort_decel, delta,
    min_front, min_rear, closing_headway, stop_margin, max_accel, max_brake,
):
    """Level-0 decisions of the vehicles ``idx`` (see the module docstring)."""
    m = idx.shape[0]
    throttle = np.empty(m)
    request = np.zeros(m, dtype=np.int64)
    for k in range(m):
        i = idx[k]
        vi = v[i]
        v0 = min(desired[k], speed_limit[i])
        acc = idm_scalar(vi, v0, gap_front[i, OWN], v_front[i, OWN], time_headway, min_gap, accel_max,
                         comfort_decel, delta, max_brake)
        lc = lane_change[i]
        if lc != 0:
            # while changing lanes, also follow the leader in the target lane
            c = OWN + lc
            acc = min(acc, idm_scalar(vi, v0, gap_front[i, c], v_front[i, c], time_headway, min_gap,
                                      accel_max, comfort_decel, delta, max_brake))
        elif lane[i] == MERGE_LANE:
            # the end of the merge lane is a standing obstacle
            end_gap = merge_lane_end_s - stop_margin - (s[i] + 0.5 * length[i])
            acc = min(acc, idm_scalar(vi, v0, end_gap, 0.0, time_headway, min_gap, accel_max,
                                      comfort_decel, delta, max_brake))
            # an acceptable gap in lane II? (no neighbour: no closing speed)
            closing_front = 0.0 if np.isnan(v_front[i, LEFT]) else max(0.0, vi - v_front[i, LEFT])
            closing_rear = 0.0 if np.isnan(v_rear[i, LEFT]) else max(0.0, v_rear[i, LEFT] - vi)
            if (gap_front[i, LEFT] >= min_front + closing_headway * closing_front
                    and gap_rear[i, LEFT] >= min_rear + closing_headway * closing_rear):
                request[k] = 1
        # acceleration -> throttle/brake command (inverse of evoscen_sim.physics.vehicle.throttle_to_accel)
        u = acc / max_accel if acc >= 0.0 else acc / max_brake
        throttle[k] = min(max(u, -1.0), 1.0)
    return throttle, request


def level0_params_from_config(cfg) -> Level0Params:
    """Level-0 parameters from a :class:`evoscen_sim.config.scenario_config.ScenarioConfig`."""
    c = cfg.level0
    return Level0Params(
        idm=_idm_from_section(c),
        desired_speed_range_mps=tuple(c.desired_speed_mps),
        merge_min_front_gap_m=c.merge_min_front_gap_m,
        merge_min_rear_gap_m=c.merge_min_rear_gap_m,
        merge_closing_headway_s=c.merge_closing_headway_s,
        merge_stop_margin_m=c.merge_stop_margin_m,
    )
