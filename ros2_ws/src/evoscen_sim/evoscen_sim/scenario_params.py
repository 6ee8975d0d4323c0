"""The simulation core's parameter objects of a scenario configuration.

The ``vehicle`` and ``control`` sections *are* the core's :class:`VehicleParams` and
:class:`ControlParams` (one dataclass each, :mod:`evoscen_sim.config_schema`), so they are
passed as they are; the re-entry parameters add a core-only field to the ``reentry`` section.
"""

from __future__ import annotations

from .control import ControlParams
from .vehicle import VehicleParams
from .world import ReentryParams


def vehicle_params_from_config(cfg) -> VehicleParams:
    """:class:`VehicleParams` of the scenario: ``cfg.vehicle`` itself."""
    return cfg.vehicle


def control_params_from_config(cfg) -> ControlParams:
    """:class:`ControlParams` of the scenario: ``cfg.control`` itself."""
    return cfg.control


def reentry_params_from_config(cfg) -> ReentryParams:
    """:class:`ReentryParams` from ``cfg.reentry``."""
    return ReentryParams(ramp_share=cfg.reentry.ramp_share, min_gap_m=cfg.reentry.min_gap_m)
