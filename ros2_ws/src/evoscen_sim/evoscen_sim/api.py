"""The plug-in face of 0.6, deprecated: import from :mod:`evoscen` (docs/plugins.md §19).

    from evoscen import ModelSpec, number, accel_to_throttle, OWN, LEFT

Importing this module warns once (DeprecationWarning) and it is removed in 0.8.0; its names are
those of 0.6, each the object :mod:`evoscen` gives under the same name. What follows is how the face
was described in 0.6.

[choice] Plug-ins import from here only: the modules behind these names may move (0.5.0 moved
41 modules, and 13 of the 15 import lines of the example plug-ins changed), this module's names
stay; a name leaves it only after a release in which it warns (``tests/test_plugin_api.py`` pins
the list, so that a change is deliberate). ROS-free, and light: importing it imports nothing;
each name is loaded from its module on first use (``from evoscen_sim.api import ModelSpec``
loads the registry alone, not the road or the world).

The names, by what a plug-in does with them:

* its description and registration: :class:`ModelSpec`, :func:`register_model` and
  :func:`unregister_model` (in-process registration: tests, notebooks), :func:`checked_answer`
  (the check both runners apply to ``act``'s answer);
* its parameters (``models.<name>``): the declarators :func:`number`, :func:`integer`,
  :func:`flag`, :func:`text`, :func:`number_range`, :func:`names`; its own one-line errors:
  :class:`InputError`; the scenario it is built for: :class:`ScenarioConfig`, :class:`VehicleParams`
  (``config.vehicle``), :func:`resolve_map_path` (a map file named like ``map``),
  :func:`scenario_rngs` (the scenario's random streams);
* the view: :class:`TrafficView`, :class:`Neighborhood` and its columns :data:`OWN`, :data:`LEFT`,
  :data:`RIGHT`, :data:`LANE_OFFSETS`, :func:`time_to_collision`, :func:`time_headway`; the codes of
  ``view.role`` and ``view.policy``: :data:`ROLE_BV`, :data:`ROLE_SUT`, :data:`POLICY_CODES`;
  the traffic window: :func:`common_shift`, :func:`new_trips`;
* the road: :class:`RoadModel`, :func:`load_road`;
* the throttle: :func:`accel_to_throttle`, :func:`throttle_to_accel`;
* trying it without a run: :func:`hand_built_world`;
* what a failing driver becomes: :class:`PluginFault`.
"""

from __future__ import annotations

import importlib
import warnings
from typing import Any

warnings.warn("evoscen_sim.api is deprecated (moved in evoscen 0.7.0; removed in 0.8.0): use evoscen",
              DeprecationWarning, stacklevel=2)

_SOURCES: dict[str, str] = {
    # description and registration
    "ModelSpec": "evoscen_sim.model_registry",
    "register_model": "evoscen_sim.model_registry",
    "unregister_model": "evoscen_sim.model_registry",
    "checked_answer": "evoscen_sim.model_registry",
    # parameters, errors, the scenario
    "number": "evoscen_sim.config.config_checks",
    "integer": "evoscen_sim.config.config_checks",
    "flag": "evoscen_sim.config.config_checks",
    "text": "evoscen_sim.config.config_checks",
    "number_range": "evoscen_sim.config.config_checks",
    "names": "evoscen_sim.config.config_checks",
    "InputError": "evoscen_sim.errors",
    "PluginFault": "evoscen_sim.errors",
    "ScenarioConfig": "evoscen_sim.config.scenario_config",
    "VehicleParams": "evoscen_sim.config.config_schema",
    "resolve_map_path": "evoscen_sim.config.config_load",
    "scenario_rngs": "evoscen_sim.scenario_builders",
    # the view
    "TrafficView": "evoscen_sim.loop.view",
    "Neighborhood": "evoscen_sim.physics.neighbors",
    "OWN": "evoscen_sim.physics.neighbors",
    "LEFT": "evoscen_sim.physics.neighbors",
    "RIGHT": "evoscen_sim.physics.neighbors",
    "LANE_OFFSETS": "evoscen_sim.physics.neighbors",
    "time_to_collision": "evoscen_sim.physics.neighbors",
    "time_headway": "evoscen_sim.physics.neighbors",
    "ROLE_BV": "evoscen_contract.contract",
    "ROLE_SUT": "evoscen_contract.contract",
    "POLICY_CODES": "evoscen_contract.contract",
    "common_shift": "evoscen_sim.physics.window",
    "new_trips": "evoscen_sim.physics.window",
    # the road, the throttle, worlds built by hand
    "RoadModel": "evoscen_sim.road.road_model",
    "load_road": "evoscen_sim.road.road_model",
    "accel_to_throttle": "evoscen_sim.physics.vehicle",
    "throttle_to_accel": "evoscen_sim.physics.vehicle",
    "hand_built_world": "evoscen_sim.loop.hand_built",
}
"""Each name of the face -> the module that defines it (loaded on first use)."""

__all__ = sorted(_SOURCES)


def __getattr__(name: str) -> Any:
    """A name of the face, from its module (cached here after the first use)."""
    source = _SOURCES.get(name)
    if source is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r} (the plug-in face: {', '.join(__all__)})")
    value = getattr(importlib.import_module(source), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})

