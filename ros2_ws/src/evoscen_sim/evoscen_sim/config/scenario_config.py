"""Scenario configuration: frozen dataclasses, loaded from YAML and validated on load.

A scenario is data. :func:`load_scenario_config` reads a YAML file (the shipped
``config/default_scenario.yaml`` when no path is given), applies dotted-key
overrides (``{"steps": 200, "bvs.mix": "3:4:3"}``, typically from the command
line) and validates everything before building a :class:`ScenarioConfig`.

Every problem raises :class:`evoscen_sim.errors.InputError` with a one-line
message naming the file (or ``command line`` for an override), the dotted key
path, the offending value and what is allowed, e.g.::

    scenario.yaml: key 'steps' = -5: expected an integer >= 1 (line 4)

Keys missing from the file take the defaults documented on the dataclass
fields; unknown keys are errors (with a suggestion of the closest allowed key).

YAML notes: the loader is PyYAML's safe loader with two YAML 1.1 quirks
removed so that what you write is what you get: ``4:3:3`` is the string
``"4:3:3"`` (not the base-60 integer 14583) and ``1e3`` is the float 1000.0.
Booleans are *not* integers: ``steps: true`` is an error.

The choice lists of ``sut.model`` and ``bvs.driver`` are the model registry's
(:data:`evoscen_sim.model_registry.SUT_MODELS` / :data:`~evoscen_sim.model_registry.BV_DRIVERS`,
also readable here as ``config.SUT_MODELS`` / ``config.BV_DRIVERS``), read at
validation time; packages that add drivers or models register them through
:mod:`evoscen_sim.model_registry` (:func:`register_bv_driver` / :func:`register_sut_model`).

Layout. This module is the public face; the work is done in

* :mod:`evoscen_sim.config.config_checks`: the checkers (one per kind of value) and the field
  declarators :func:`number`, :func:`integer`, :func:`flag`, :func:`text`,
  :func:`number_range`;
* :mod:`evoscen_sim.config.config_schema`: the sections as frozen dataclasses, the one place where
  each default is written (the core's :class:`~evoscen_sim.config.config_schema.VehicleParams` and
  :class:`~evoscen_sim.config.config_schema.ControlParams` *are* the ``vehicle`` and ``control``
  sections; the level-0 and re-entry parameter objects take their defaults from
  :class:`Level0Config` / :class:`ReentryConfig`);
* :mod:`evoscen_sim.config.config_load`: YAML with line numbers, the one validator
  (:func:`evoscen_sim.config.config_load.build`, also used by the training configuration and, through
  :func:`config_from_dict`, by the nodes' ``scenario.*`` parameters), overrides, dump;
* :mod:`evoscen_sim.share`: the package-path lookup (:func:`share_path`,
  :func:`share_candidates`);
* :mod:`evoscen_sim.model_registry`: the model registry (imports nothing of the configuration).

Why hand-written checkers and not pydantic v2 (strict). Evaluated for issue 15 (measured on
the development machine): pydantic 2.14.3 is on the configured package index (``pip download
'pydantic==2.*'`` works offline, a 494 kB wheel) but is not installed. It brings
``pydantic-core`` 2.50.4 (a compiled Rust extension), ``annotated-types``,
``typing-extensions`` and ``typing-inspection``: 9.9 MB installed (pydantic 4.3 MB,
pydantic-core 5.3 MB), where this package needs only PyYAML. ``import pydantic`` plus
``BaseModel`` took 150-180 ms in a fresh interpreter; ``import evoscen_sim.config.scenario_config`` takes
about 60 ms with PyYAML loaded (``-X importtime``, the model registry's importlib.metadata
and pathlib included). Strict mode with ``extra="forbid"`` rejects what we reject
(``steps: true``, ``"3"`` for a number, unknown keys), but its errors are multi-line
``ValidationError`` reports (``1 validation error for S`` / ``sut.lane`` / ``Input should be
less than or equal to 4 [type=less_than_equal, input_value=7, input_type=int]`` / a
documentation URL) with no file line numbers and no "did you mean": every message would have
to be re-rendered from ``loc`` through our own line map anyway. What a scenario needs beyond
types would be custom validators either way: ``dt_s`` a whole number of nanoseconds, the
``"4:3:3"`` mix string, choices read from the model registry at validation time,
command-line text read as YAML scalars, "(default)" and "(overriding ...)" notes, plug-in
models' parameter dataclasses declared with :func:`number` & co. (third-party code relies on
those declarators), and the kernels' parameter sets must stay plain frozen dataclasses.
Decision: keep the hand-written checkers (about 250 lines, one error path, no dependency);
pydantic is not a dependency. Revisit only if the schema grows nested types that the
checkers cannot express.
"""

from __future__ import annotations

from typing import Any

from evoscen_sim import model_registry as _registry
from evoscen_sim.config.config_checks import POLICIES, flag, integer, names, number, number_range, text
from evoscen_sim.config.config_load import (
    config_from_dict,
    config_to_dict,
    dump_config,
    evaluation_from_dict,
    load_scenario_config,
    resolve_map_path,
)
from evoscen_sim.config.config_load import parse_yaml as _parse_yaml
from evoscen_sim.config.config_schema import (
    ACCEL_ACTIVITY_FORMS,
    COMPRESSIONS,
    EFFICIENCY_DENSITY_FORMS,
    HARD_BRAKING_RULES,
    MAX_BV_COUNT,
    MAX_RANGE_SPEED_MPS,
    MAX_S_M,
    REAR_BRAKING_RULES,
    REAR_CONFLICT_MODES,
    UNDEFINED_TERM_RULES,
    BvConfig,
    ControlConfig,
    EvaluationConfig,
    Level0Config,
    RecordingConfig,
    ReentryConfig,
    ScenarioConfig,
    SpawnConfig,
    SutConfig,
    TrafficConfig,
    VehicleConfig,
    mix_counts,
)
from evoscen_sim.model_registry import register_bv_driver, register_sut_model
from evoscen_sim.share import share_candidates, share_path

__all__ = [
    "ACCEL_ACTIVITY_FORMS",
    "COMPRESSIONS",
    "EFFICIENCY_DENSITY_FORMS",
    "HARD_BRAKING_RULES",
    "MAX_BV_COUNT",
    "MAX_RANGE_SPEED_MPS",
    "MAX_S_M",
    "POLICIES",
    "REAR_BRAKING_RULES",
    "REAR_CONFLICT_MODES",
    "UNDEFINED_TERM_RULES",
    "BvConfig",
    "ControlConfig",
    "EvaluationConfig",
    "Level0Config",
    "ReentryConfig",
    "RecordingConfig",
    "ScenarioConfig",
    "SpawnConfig",
    "SutConfig",
    "TrafficConfig",
    "VehicleConfig",
    "_parse_yaml",
    "config_from_dict",
    "config_to_dict",
    "dump_config",
    "evaluation_from_dict",
    "flag",
    "integer",
    "load_scenario_config",
    "mix_counts",
    "number",
    "names",
    "number_range",
    "register_bv_driver",
    "register_sut_model",
    "resolve_map_path",
    "share_candidates",
    "share_path",
    "text",
]


def __getattr__(name: str) -> Any:
    """``BV_DRIVERS`` and ``SUT_MODELS``: the registry's current tuples (they grow as models register)."""
    if name in ("BV_DRIVERS", "SUT_MODELS"):
        return getattr(_registry, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
