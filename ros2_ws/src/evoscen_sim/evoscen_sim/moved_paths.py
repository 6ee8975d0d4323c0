"""The import paths of 0.6 that moved, kept for one release: each imports as an alias of the module's
new path, with one DeprecationWarning naming it (``evoscen_sim.physics.view is deprecated (moved in
evoscen 0.7.0; removed in 0.8.0): use evoscen_sim.loop.view``).

[choice] A warning, not an error, for one release: a plug-in or script written for 0.6 keeps working
while its author moves it to the new paths — a plug-in to the face that lasts, :mod:`evoscen`
(docs/plugins.md §19). The rooms these modules moved into: docs/architecture.md §1. Standard library
only: every package imports this module from its ``__init__`` (:func:`install`).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

ROOMS_MOVED_IN = "0.7.0"
"""The release that moves the modules of :data:`ROOM_MODULES`."""

ROOMS_REMOVED_IN = "0.8.0"
"""The release that drops the aliases of :data:`ROOM_MODULES`."""

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
    "evoscen_sim.physics.traffic": "evoscen_sim.physics.window",
    "evoscen_sim.physics.view": "evoscen_sim.loop.view",
}
"""0.6 module path -> its path since :data:`ROOMS_MOVED_IN` (docs/architecture.md §1)."""


def _stacklevel() -> int:
    """The ``stacklevel`` that points a warning at the code that imports: past this module's frames
    (importlib's own frames :func:`warnings.warn` skips itself)."""
    frame, level = sys._getframe(2), 1  # the frame of _warn's caller
    while frame is not None and (frame.f_code.co_filename == __file__
                                 or frame.f_code.co_filename.startswith("<frozen importlib")):
        if not frame.f_code.co_filename.startswith("<frozen importlib"):
            level += 1
        frame = frame.f_back
    return level + 1


def _warn(old: str, new: str) -> None:
    warnings.warn(f"{old} is deprecated (moved in evoscen {ROOMS_MOVED_IN}; removed in {ROOMS_REMOVED_IN}): use {new}",
                  DeprecationWarning, stacklevel=_stacklevel())


class _Alias(types.ModuleType):
    """A 0.6 module path: every attribute is its new module's (live)."""

    def __getattr__(self, name: str):
        return getattr(importlib.import_module(ROOM_MODULES[self.__name__]), name)


class _Loader(importlib.abc.Loader):
    def create_module(self, spec):
        return _Alias(spec.name)

    def exec_module(self, module) -> None:
        new = ROOM_MODULES[module.__name__]
        _warn(module.__name__, new)
        target = importlib.import_module(new)
        module.__doc__ = target.__doc__
        module.__file__ = getattr(target, "__file__", None)


class _Finder(importlib.abc.MetaPathFinder):
    """Finds the moved module paths of :data:`ROOM_MODULES` (only those)."""

    def find_spec(self, fullname, path, target=None):
        if fullname not in ROOM_MODULES:
            return None
        return importlib.util.spec_from_loader(fullname, _Loader())


def install() -> None:
    """Put the finder of the moved module paths on ``sys.meta_path`` (once per process)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
