"""evoscen in one import: what a plug-in author, a script writer and a notebook user need.

    import evoscen
    from evoscen import ModelSpec, number, accel_to_throttle, OWN, LEFT

    result = evoscen.run_scenario(overrides={"sut.model": "mobil", "steps": 300}, out="runs/mine")
    print(result.score, result.report["safety"]["collisions"])
    report = evoscen.score_bag("runs/mine/bag")

[choice] One face (docs/plugins.md §19): plug-ins, scripts and notebooks import from here only. The
modules behind these names may move between versions; the names stay, and one leaves only after a
release in which it warns (tests/test_face.py pins the list, so that a change is deliberate).
``evoscen_sim.api`` (the face of 0.6) still works, with a DeprecationWarning, until 0.8.0.

Importing this package starts no ROS and loads nothing else: each name is loaded from its module
on first use (``from evoscen import ModelSpec`` loads the model registry alone, not the road, the
world or rclpy). The names, by what they are for:

* a plug-in's description and registration: :class:`ModelSpec`, :class:`Driver` (what its factory
  returns), :func:`register_model`, :func:`unregister_model`, :func:`checked_answer`;
* its parameters (``models.<name>``): :func:`number`, :func:`integer`, :func:`flag`, :func:`text`,
  :func:`number_range`, :func:`names`; its errors: :class:`InputError`, :class:`PluginFault`; the
  scenario: :class:`ScenarioConfig`, :class:`VehicleParams`, :func:`load_scenario_config`,
  :func:`resolve_map_path`, :func:`scenario_rngs`;
* the view: :class:`TrafficView`, :class:`Neighborhood`, :data:`OWN`, :data:`LEFT`, :data:`RIGHT`,
  :data:`LANE_OFFSETS`, :func:`time_to_collision`, :func:`time_headway`, :data:`ROLE_BV`,
  :data:`ROLE_SUT`, :data:`POLICY_CODES`, :func:`common_shift`, :func:`new_trips`;
* the road: :class:`RoadModel`, :func:`load_road`; the throttle: :func:`accel_to_throttle`,
  :func:`throttle_to_accel`; Krauss car following (the SUTs' follower): :func:`krauss_for`,
  :class:`KraussCarFollowing`, :class:`KraussParams`; trying a driver without a run:
  :func:`hand_built_world`;
* running, scoring and experiments: :func:`run_scenario` (either runner) -> :class:`RunResult`,
  :func:`score_bag` -> the report as a dict (``report.json``'s content), :func:`run_experiment` (the
  intelligence or the sensitivity experiment) -> :class:`ExperimentResult` with the tables it wrote.
"""

from __future__ import annotations

import importlib
from typing import Any

from ._version import __version__ as __version__

_SOURCES: dict[str, str] = {
    # description and registration
    "ModelSpec": "evoscen_sim.model_registry",
    "Driver": "evoscen_sim.model_registry",
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
    "load_scenario_config": "evoscen_sim.config.scenario_config",
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
    # the road, the throttle, Krauss following, worlds built by hand
    "RoadModel": "evoscen_sim.road.road_model",
    "load_road": "evoscen_sim.road.road_model",
    "accel_to_throttle": "evoscen_sim.physics.vehicle",
    "throttle_to_accel": "evoscen_sim.physics.vehicle",
    "krauss_for": "evoscen_sut.krauss",
    "KraussCarFollowing": "evoscen_sut.krauss",
    "KraussParams": "evoscen_sut.krauss",
    "hand_built_world": "evoscen_sim.loop.hand_built",
    # running and scoring
    "run_scenario": "evoscen.runs",
    "score_bag": "evoscen.runs",
    "RunResult": "evoscen.runs",
    "run_experiment": "evoscen.experiment_runs",
    "ExperimentResult": "evoscen.experiment_runs",
}
"""Each name of the face -> the module that defines it (loaded on first use)."""

__all__ = sorted([*_SOURCES, "__version__"])


def __getattr__(name: str) -> Any:
    """A name of the face, from its module (cached here after the first use)."""
    source = _SOURCES.get(name)
    if source is None:
        raise AttributeError(f"module 'evoscen' has no attribute {name!r} (its names: {', '.join(sorted(_SOURCES))})")
    value = getattr(importlib.import_module(source), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
