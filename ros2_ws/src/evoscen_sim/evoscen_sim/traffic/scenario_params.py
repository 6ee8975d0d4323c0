"""The simulation core's parameter objects of a scenario configuration that are built from it.

The ``vehicle``, ``control`` and ``traffic`` sections *are* the core's
:class:`~evoscen_sim.physics.vehicle.VehicleParams`, :class:`~evoscen_sim.physics.control.ControlParams` and
:class:`~evoscen_sim.physics.window.TrafficParams` (one dataclass each, :mod:`evoscen_sim.config.config_schema`):
they are passed as they are, the traffic section once checked against the road here. The re-entry
parameters are built here from their section.
"""

from __future__ import annotations

from evoscen_sim.errors import InputError
from evoscen_sim.physics.world import ReentryParams

from evoscen_sim.physics.window import TrafficParams, check_shift_points


def reentry_params_from_config(cfg) -> ReentryParams:
    """:class:`ReentryParams` from ``cfg.reentry``."""
    return ReentryParams(ramp_share=cfg.reentry.ramp_share, min_gap_m=cfg.reentry.min_gap_m)


def traffic_params_from_config(cfg, road) -> TrafficParams | None:  # a RoadModel
    """:class:`TrafficParams` from ``cfg.traffic`` (None for ``mode: loop``), checked against ``road``.

    Raises:
        InputError: the window's shift points are not on a uniform stretch of the map, or the
            per-lane lists do not have one entry per mainline lane.
    """
    t = cfg.traffic
    if t.mode != "window":
        return None
    mainline = len(road.mainline_lanes)
    for key in ("lane_density_per_km", "lane_speed_mean_mps", "lane_speed_sd_mps"):
        if len(getattr(t, key)) != mainline:
            raise InputError(f"traffic.{key}: expected one entry per mainline lane of the map ({mainline}), "
                             f"got {len(getattr(t, key))}")
    params = t  # the section is the window's TrafficParams (one declaration: config_schema)
    why = check_shift_points(road, params, cfg.sut.s_m)
    if why is not None:
        raise InputError(why)
    return params
