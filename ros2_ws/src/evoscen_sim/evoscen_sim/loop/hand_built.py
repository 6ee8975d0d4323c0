"""Helpers for hand-built traffic situations (tests of drivers, SUTs and metrics).

``hand_built_world(road, s, lane, speed)`` places vehicles exactly where a test says —
centred in their lanes, heading along the road — with the default vehicle and control
parameters, so a test reads as the situation it specifies.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from evoscen_sim.physics.control import ControlParams
from evoscen_sim.physics.vehicle import VehicleParams
from evoscen_sim.physics.world import ROLE_BV, InitialState, ReentryParams, World
from evoscen_sim.physics.window import TrafficParams


def hand_built_world(
    road,  # evoscen_sim.road.road_model.RoadModel
    s: Sequence[float],
    lane: Sequence[int],
    speed: Sequence[float],
    *,
    roles: Sequence[int] | None = None,
    reentry: ReentryParams = ReentryParams(),
    vehicle: VehicleParams = VehicleParams(),
    control: ControlParams = ControlParams(),
    dt_s: float = 0.1,
    seed: int = 0,
    first_id: int = 0,
    traffic: TrafficParams | None = None,
) -> World:
    """A world with vehicle ``i`` (id ``first_id + i``) at arc position ``s[i]`` in ``lane[i]`` at ``speed[i]``
    (``traffic``: the traffic window around its SUT, :mod:`evoscen_sim.physics.window`)."""
    n = len(s)
    init = InitialState(
        ids=np.arange(n) + first_id,
        roles=np.full(n, ROLE_BV, dtype=np.int64) if roles is None else np.asarray(roles, dtype=np.int64),
        policies=np.zeros(n, dtype=np.int64),
        s_m=np.asarray(s, dtype=float),
        lane=np.asarray(lane, dtype=np.int64),
        speed_mps=np.asarray(speed, dtype=float),
    )
    return World(road, init, vehicle=vehicle, control=control, reentry=reentry, dt_s=dt_s,
                 rng=np.random.default_rng(seed), traffic=traffic)
