"""The BV package's built-in driver models, registered with :mod:`evoscen_sim.models`.

* ``level0`` (roles ``bv`` and ``sut``): the level-0 driver (:mod:`evoscen_bv.level0`),
  parameters from the scenario's ``level0`` section.
"""

from __future__ import annotations

from evoscen_sim.models import ModelSpec, register_model
from evoscen_sim.scenario_params import vehicle_params_from_config

from .level0 import Level0Driver, level0_params_from_config


def _level0(vehicles, params, config, rng):  # noqa: ANN001, ANN202
    return Level0Driver(vehicles, level0_params_from_config(config), rng, vehicle_params_from_config(config))


LEVEL0 = ModelSpec(
    name="level0",
    roles=("bv", "sut"),
    factory=_level0,
    description="level-0 traffic: IDM, keep lane, forced merges only (SPEC 3.3)",
)
register_model(LEVEL0)
