"""The SUT plug-in interface and the registry of SUT models by name.

A SUT model is any object with ``act(world) -> (throttle, lane_change)`` returning arrays of
length 1 for the vehicle it drives (throttle in [-1, 1], lane change in {-1, 0, +1}); it is
built by a factory ``factory(vehicle_index, config, rng) -> model``. Registered now:

* ``level0`` — the level-0 driver of :mod:`evoscen_bv.level0` (keep lane, forced merges,
  IDM), the SUT slot's stand-in until the rule-based SUT models exist.
"""

from __future__ import annotations

from typing import Callable, Protocol

import numpy as np

from evoscen_sim.errors import InputError


class SutModel(Protocol):
    """What the simulator asks a SUT model every step."""

    def act(self, world) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - protocol
        """Throttle and lane-change request for the SUT vehicle (arrays of length 1)."""


SutFactory = Callable[[int, object, np.random.Generator], SutModel]
_REGISTRY: dict[str, SutFactory] = {}


def register_sut(name: str, factory: SutFactory) -> None:
    """Register a SUT model factory under ``name`` (replacing an earlier one)."""
    _REGISTRY[name] = factory


def sut_names() -> tuple[str, ...]:
    """Names of the registered SUT models, sorted."""
    return tuple(sorted(_REGISTRY))


def create_sut(name: str, vehicle_index: int, config, rng: np.random.Generator) -> SutModel:
    """Build the SUT model ``name`` for vehicle ``vehicle_index``; unknown names are an InputError."""
    try:
        factory = _REGISTRY[name]
    except KeyError:
        raise InputError(f"unknown SUT model '{name}': expected one of {', '.join(sut_names())}") from None
    return factory(vehicle_index, config, rng)


def _level0_factory(vehicle_index: int, config, rng: np.random.Generator) -> SutModel:
    from evoscen_bv.level0 import Level0Driver, level0_params_from_config
    from evoscen_sim.scenario_params import vehicle_params_from_config

    return Level0Driver(
        np.array([vehicle_index]), level0_params_from_config(config), rng, vehicle_params_from_config(config)
    )


register_sut("level0", _level0_factory)
