"""The import paths evoscen 0.5.0 moved, kept working for one release with a DeprecationWarning.

0.5.0 reorganised the packages (CHANGELOG 0.5.0, "Import paths"): 41 modules moved
(:data:`MOVED_MODULES`, :data:`PACKAGE_MODULES`; ``git diff -M --name-status 2988590 877507b``,
the last 0.4.0 commit and 0.5.0) and 32 names left their module (:data:`MOVED_NAMES`; the two of
``evoscen_contract.cdr`` are served by that module, the contract importing no other package).
Until 0.7.0 the old paths still import:

* a moved module (``import evoscen_sim.models``) is an alias of its new module (the same objects,
  live: ``evoscen_sim.models.SUT_MODELS`` is the registry's current tuple), found by a finder on
  ``sys.meta_path`` that each evoscen package installs when it is imported (:func:`install`);
* a moved name (``from evoscen_eval.scoring.streaming import TTC_BINS``, ``from evoscen_sim.config
  import ScenarioConfig``: the old modules ``evoscen_sim.config`` and ``evoscen_sim.road`` are
  packages now) is served by the old module's ``__getattr__`` (:func:`moved_attribute`);

each with one :class:`DeprecationWarning` naming the new path. [choice] A warning, not an error,
for one release: a plug-in written for 0.4 keeps working while its author moves it to
the face that lasts, :mod:`evoscen` (docs/plugins.md §19). Standard library only: every
package imports this module from its ``__init__``.

The simulation's modules moved again into rooms named for what they hold (docs/architecture.md
§1, "Module map"): the paths of 0.6 that moved (:data:`ROOM_MODULES`) are served the same way
from :data:`ROOMS_MOVED_IN` until :data:`ROOMS_REMOVED_IN`, one release; a 0.4 path whose 0.5
module moved again leads straight to the module's current path.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

REMOVED_IN = "0.7.0"
"""The release that drops the aliases of the paths 0.5.0 moved."""

ROOMS_MOVED_IN = "0.7.0"
"""The release that moves the modules of :data:`ROOM_MODULES`."""

ROOMS_REMOVED_IN = "0.8.0"
"""The release that drops the aliases of :data:`ROOM_MODULES`."""

MOVED_MODULES: dict[str, str] = {
    "evoscen_bringup.bag_writer": "evoscen_record.bag_writer",
    "evoscen_bringup.step_recorder": "evoscen_record.step_recorder",
    "evoscen_bringup.testing": "evoscen_bringup.model_testing",
    "evoscen_bv.lane_change": "evoscen_bv.lane_change_decision",
    "evoscen_bv.models": "evoscen_bv.bv_models",
    "evoscen_eval.bag_reader": "evoscen_record.bag_reader",
    "evoscen_eval.mcap_internals": "evoscen_record.mcap_internals",
    "evoscen_eval.recorder": "evoscen_record.recorder",
    "evoscen_eval.reindex": "evoscen_record.reindex",
    "evoscen_eval.schemas": "evoscen_record.schemas",
    "evoscen_eval.testing": "evoscen_eval.scoring.run_fixtures",
    "evoscen_sim.bv_nodes": "evoscen_sim.nodes.bv_nodes",
    "evoscen_sim.car_following": "evoscen_sim.physics.idm",
    "evoscen_sim.collision": "evoscen_sim.physics.collision",
    "evoscen_sim.config_checks": "evoscen_sim.config.config_checks",
    "evoscen_sim.config_load": "evoscen_sim.config.config_load",
    "evoscen_sim.config_schema": "evoscen_sim.config.config_schema",
    "evoscen_sim.control": "evoscen_sim.physics.control",
    "evoscen_sim.controller_node": "evoscen_sim.nodes.controller_node",
    "evoscen_sim.events": "evoscen_sim.danger.events",
    "evoscen_sim.models": "evoscen_sim.model_registry",
    "evoscen_sim.neighbors": "evoscen_sim.physics.neighbors",
    "evoscen_sim.node_params": "evoscen_sim.nodes.node_params",
    "evoscen_sim.opendrive": "evoscen_sim.road.opendrive",
    "evoscen_sim.road_kernels": "evoscen_sim.road.road_kernels",
    "evoscen_sim.safety": "evoscen_sim.danger.safety",
    "evoscen_sim.scenario": "evoscen_sim.scenario_builders",
    "evoscen_sim.scenario_params": "evoscen_sim.traffic.scenario_params",
    "evoscen_sim.sim_node": "evoscen_sim.nodes.sim_node",
    "evoscen_sim.spawn": "evoscen_sim.traffic.spawn",
    "evoscen_sim.step_loop": "evoscen_sim.loop.step_loop",
    "evoscen_sim.testing": "evoscen_sim.loop.hand_built",
    "evoscen_sim.vehicle": "evoscen_sim.physics.vehicle",
    "evoscen_sim.view": "evoscen_sim.loop.view",
    "evoscen_sim.world": "evoscen_sim.physics.world",
    "evoscen_sut.lane_change": "evoscen_sut.krauss_lane_change",
    "evoscen_sut.models": "evoscen_sut.sut_models",
}
"""0.4 module path -> the module's current path (``evoscen_sim.config`` and ``evoscen_sim.road``,
packages now, are in :data:`PACKAGE_MODULES`). ``evoscen_sim.limits``, moved to
``evoscen_sim.config.limits`` in 0.5.0, is the module's own path again (0.7.0): no alias."""

ROOM_MODULES: dict[str, str] = {
    "evoscen_bringup.campaign": "evoscen_experiments.campaign",
    "evoscen_bringup.campaign_spec": "evoscen_experiments.campaign_spec",
    "evoscen_bringup.campaign_summary": "evoscen_experiments.campaign_summary",
    "evoscen_bringup.experiments": "evoscen_experiments.experiments",
    "evoscen_bringup.ray_leftovers": "evoscen_experiments.ray_leftovers",
    "evoscen_bringup.replication": "evoscen_experiments.replication",
    "evoscen_bringup.sensitivity": "evoscen_experiments.sensitivity",
    "evoscen_bringup.stats": "evoscen_experiments.stats",
    "evoscen_eval.animation": "evoscen_eval.scoring.animation",
    "evoscen_eval.behaviour": "evoscen_eval.naturalistic.behaviour",
    "evoscen_eval.bv_realism": "evoscen_eval.naturalistic.bv_realism",
    "evoscen_eval.clips": "evoscen_eval.scenes.clips",
    "evoscen_eval.exposure_rules": "evoscen_eval.scoring.exposure_rules",
    "evoscen_eval.fidelity": "evoscen_eval.naturalistic.fidelity",
    "evoscen_eval.fidelity_highd": "evoscen_eval.naturalistic.fidelity_highd",
    "evoscen_eval.highd": "evoscen_eval.naturalistic.highd",
    "evoscen_eval.highd_export": "evoscen_eval.naturalistic.highd_export",
    "evoscen_eval.metrics": "evoscen_eval.scoring.metrics",
    "evoscen_eval.plot_inputs": "evoscen_eval.scoring.plot_inputs",
    "evoscen_eval.replay": "evoscen_eval.scenes.replay",
    "evoscen_eval.report": "evoscen_eval.scoring.report",
    "evoscen_eval.run_fixtures": "evoscen_eval.scoring.run_fixtures",
    "evoscen_eval.rundata": "evoscen_eval.scoring.rundata",
    "evoscen_eval.scenario_export": "evoscen_eval.scenes.scenario_export",
    "evoscen_eval.similarity": "evoscen_eval.naturalistic.similarity",
    "evoscen_eval.streaming": "evoscen_eval.scoring.streaming",
    "evoscen_eval.sut_collisions": "evoscen_eval.scoring.sut_collisions",
    "evoscen_eval.sut_lane_changes": "evoscen_eval.scoring.sut_lane_changes",
    "evoscen_eval.xosc_readback": "evoscen_eval.scenes.xosc_readback",
    "evoscen_sim.config.limits": "evoscen_sim.limits",
    "evoscen_sim.physics.events": "evoscen_sim.danger.events",
    "evoscen_sim.physics.hand_built": "evoscen_sim.loop.hand_built",
    "evoscen_sim.physics.makeup": "evoscen_sim.traffic.makeup",
    "evoscen_sim.physics.safety": "evoscen_sim.danger.safety",
    "evoscen_sim.physics.scenario_params": "evoscen_sim.traffic.scenario_params",
    "evoscen_sim.physics.spawn": "evoscen_sim.traffic.spawn",
    "evoscen_sim.physics.step_loop": "evoscen_sim.loop.step_loop",
    "evoscen_sim.physics.traffic": "evoscen_sim.traffic.window",
    "evoscen_sim.physics.view": "evoscen_sim.loop.view",
}
"""0.6 module path -> its path since :data:`ROOMS_MOVED_IN` (docs/architecture.md §1)."""

PACKAGE_MODULES: dict[str, str] = {
    "evoscen_sim.config": "evoscen_sim.config.scenario_config",
    "evoscen_sim.road": "evoscen_sim.road.road_model",
    "evoscen_sim.traffic": "evoscen_sim.traffic.window",
}
"""0.4 modules that are packages now (``evoscen_sim.traffic`` since 0.7.0, the room of the traffic):
their 0.4 names (:data:`PACKAGE_NAMES`) come from this module (the package's ``__getattr__``)."""

PACKAGE_NAMES: dict[str, frozenset[str]] = {
    "evoscen_sim.config": frozenset((
        "ACCEL_ACTIVITY_FORMS", "BV_DRIVERS", "BvConfig", "COMPRESSIONS", "ControlConfig",
        "EFFICIENCY_DENSITY_FORMS", "EvaluationConfig", "HARD_BRAKING_RULES", "Level0Config", "MAX_BV_COUNT",
        "MAX_RANGE_SPEED_MPS", "MAX_S_M", "POLICIES", "REAR_BRAKING_RULES", "REAR_CONFLICT_MODES",
        "RecordingConfig", "ReentryConfig", "SUT_MODELS", "ScenarioConfig", "SpawnConfig", "SutConfig",
        "TrafficConfig", "UNDEFINED_TERM_RULES", "VehicleConfig", "config_from_dict", "config_to_dict",
        "dump_config", "evaluation_from_dict", "flag", "integer", "load_scenario_config", "mix_counts", "names",
        "number", "number_range", "register_bv_driver", "register_sut_model", "resolve_map_path",
        "share_candidates", "share_path", "text")),
    "evoscen_sim.road": frozenset((
        "DEFAULT_MAP_PATH", "DRIVABLE_LANE_TYPES", "Lane", "LaneLookup", "LaneMarking", "LaneSection",
        "MARKING_STEP_M", "OpenDriveMap", "Poly3", "RoadModel", "RoadTables", "load_road", "parse_opendrive")),
    "evoscen_sim.traffic": frozenset((
        "ENTRY_RETRY_STEPS", "MERGE_LANE", "NEW_TRIP_MAX_SPEED_MPS", "TrafficParams", "TrafficWindow",
        "check_shift_points", "common_shift", "common_shift_kernel", "insertion_speed", "new_trips", "new_trips_kernel",
        "required_gap")),
}
"""The public names of the 0.4 modules ``evoscen_sim.config``, ``evoscen_sim.road`` and ``evoscen_sim.traffic``."""

MOVED_NAMES: dict[str, dict[str, str]] = {
    "evoscen_experiments.campaign": {
        "INTACT": "evoscen_experiments.campaign_spec",
        "MUTANT_AXIS": "evoscen_experiments.campaign_spec",
        "PACKAGES": "evoscen_experiments.campaign_spec",
        "RECORD_MODES": "evoscen_experiments.campaign_spec",
        "SPEC_KEYS": "evoscen_experiments.campaign_spec",
        "Spec": "evoscen_experiments.campaign_spec",
        "bootstrap_ci": "evoscen_experiments.campaign_summary",
        "cells": "evoscen_experiments.campaign_summary",
        "code_version": "evoscen_experiments.campaign_spec",
        "expand": "evoscen_experiments.campaign_spec",
        "gallery_markdown": "evoscen_experiments.campaign_summary",
        "load_spec": "evoscen_experiments.campaign_spec",
        "plugin_fingerprint": "evoscen_experiments.campaign_spec",
        "plugin_versions": "evoscen_experiments.campaign_spec",
        "run_key": "evoscen_experiments.campaign_spec",
        "summary_markdown": "evoscen_experiments.campaign_summary",
        "summary_plots": "evoscen_experiments.campaign_summary",
        "write_results": "evoscen_experiments.campaign_summary",
    },
    "evoscen_eval.recorder": {
        "METADATA_VERSION": "evoscen_record.metadata_yaml",
        "OrderedBag": "evoscen_record.ordered_bag",
        "ROS_DISTRO": "evoscen_record.metadata_yaml",
    },
    "evoscen_eval.scoring.rundata": {
        "MAP_HASH_KEY": "evoscen_record.scenario_record",
        "portable_map_ref": "evoscen_record.scenario_record",
        "scenario_metadata": "evoscen_record.scenario_record",
    },
    "evoscen_eval.scoring.streaming": {
        "COLLISION_KINDS": "evoscen_eval.scoring.sut_collisions",
        "COLLISION_LOOKBACK_S": "evoscen_eval.scoring.sut_collisions",
        "MAX_SNAPSHOTS": "evoscen_eval.scoring.sut_collisions",
        "SPEED_BINS": "evoscen_eval.scoring.plot_inputs",
        "TIMELINE_POINTS": "evoscen_eval.scoring.plot_inputs",
        "TTC_BINS": "evoscen_eval.scoring.plot_inputs",
    },
}
"""Module (0.4 path) -> {name -> the 0.5 module that defines it}, for names no longer in the module
(or in the module it moved to)."""


def _stacklevel() -> int:
    """The ``stacklevel`` that points a warning at the code that imports: past this module's frames
    and a module's ``__getattr__`` (importlib's own frames :func:`warnings.warn` skips itself)."""
    frame, level = sys._getframe(2), 1  # the frame of _warn's caller
    while frame is not None and (frame.f_code.co_filename == __file__ or frame.f_code.co_name == "__getattr__"
                                 or frame.f_code.co_filename.startswith("<frozen importlib")):
        if not frame.f_code.co_filename.startswith("<frozen importlib"):
            level += 1
        frame = frame.f_back
    return level + 1


def _warn(old: str, new: str) -> None:
    moved, removed = (ROOMS_MOVED_IN, ROOMS_REMOVED_IN) if old in ROOM_MODULES else ("0.5.0", REMOVED_IN)
    warnings.warn(f"{old} is deprecated (moved in evoscen {moved}; removed in {removed}): use {new}",
                  DeprecationWarning, stacklevel=_stacklevel())


def _module_target(old: str) -> str:
    """The current path of a moved module path (:data:`MOVED_MODULES` or :data:`ROOM_MODULES`)."""
    return ROOM_MODULES[old] if old in ROOM_MODULES else MOVED_MODULES[old]


def moved_attribute(module: str, name: str):
    """``module.name`` for a name that moved away (:data:`MOVED_NAMES`, :data:`PACKAGE_MODULES`), with a
    DeprecationWarning; AttributeError otherwise (what a module's ``__getattr__`` must raise)."""
    target = MOVED_NAMES.get(module, {}).get(name)
    if target is None and name in PACKAGE_NAMES.get(module, ()):
        target = PACKAGE_MODULES[module]
    if target is None:
        raise AttributeError(f"module {module!r} has no attribute {name!r}")
    _warn(f"{module}.{name}", f"{target}.{name}")
    return getattr(importlib.import_module(target), name)


class _Alias(types.ModuleType):
    """A 0.4 module path: every attribute is its new module's (live), or a moved name's."""

    def __getattr__(self, name: str):
        old = self.__name__
        target = MOVED_NAMES.get(old, {}).get(name)
        if target is not None:
            return getattr(importlib.import_module(target), name)
        return getattr(importlib.import_module(_module_target(old)), name)


class _Loader(importlib.abc.Loader):
    def create_module(self, spec):
        return _Alias(spec.name)

    def exec_module(self, module) -> None:
        new = _module_target(module.__name__)
        _warn(module.__name__, new)
        target = importlib.import_module(new)
        module.__doc__ = target.__doc__
        module.__file__ = getattr(target, "__file__", None)


class _Finder(importlib.abc.MetaPathFinder):
    """Finds the moved module paths of :data:`MOVED_MODULES` and :data:`ROOM_MODULES` (only those)."""

    def find_spec(self, fullname, path, target=None):
        if fullname not in MOVED_MODULES and fullname not in ROOM_MODULES:
            return None
        return importlib.util.spec_from_loader(fullname, _Loader())


def install() -> None:
    """Put the finder of the moved module paths on ``sys.meta_path`` (once per process)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
