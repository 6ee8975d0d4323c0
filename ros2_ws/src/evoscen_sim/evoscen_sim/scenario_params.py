"""Conversions from the scenario configuration to the simulation core's parameter objects."""

from __future__ import annotations

from .control import ControlParams
from .vehicle import VehicleParams
from .world import ReentryParams


def vehicle_params_from_config(cfg) -> VehicleParams:
    """:class:`VehicleParams` from ``cfg.vehicle``."""
    v = cfg.vehicle
    return VehicleParams(
        length_m=v.length_m,
        width_m=v.width_m,
        wheelbase_m=v.wheelbase_m,
        max_accel_mps2=v.max_accel_mps2,
        max_brake_mps2=v.max_brake_mps2,
        max_speed_mps=v.max_speed_mps,
        max_steer_rad=v.max_steer_rad,
        max_steer_rate_radps=v.max_steer_rate_radps,
    )


def control_params_from_config(cfg) -> ControlParams:
    """:class:`ControlParams` from ``cfg.control``."""
    c = cfg.control
    return ControlParams(
        lat_kp=c.lat_kp,
        lat_ki=c.lat_ki,
        lat_kd=c.lat_kd,
        head_kp=c.head_kp,
        head_ki=c.head_ki,
        head_kd=c.head_kd,
        max_lateral_speed_mps=c.max_lateral_speed_mps,
        max_heading_ref_rad=c.max_heading_ref_rad,
    )


def reentry_params_from_config(cfg) -> ReentryParams:
    """:class:`ReentryParams` from ``cfg.reentry``."""
    return ReentryParams(ramp_share=cfg.reentry.ramp_share, min_gap_m=cfg.reentry.min_gap_m)
