"""Driver models as plug-ins: one registry for SUT models and BV drivers.

A driver model is described by a :class:`ModelSpec`: its name, the roles it can play
(``"sut"``, ``"bv"``), an optional frozen dataclass of parameters, and a factory building a
driver for a set of vehicles. A *driver* is any object with::

    act(view) -> (throttle: np.ndarray, lane_change: np.ndarray)

one entry per vehicle it drives, where ``view`` is a traffic view
(:mod:`evoscen_sim.loop.view`): throttle/brake in [-1, 1], lane-change request in {-1, 0, +1}.

Models come from two places, found by :func:`discover`:

* the built-in modules (``evoscen_bv.bv_models``, ``evoscen_sut.sut_models``), which call
  :func:`register_model` when imported;
* Python entry points in the groups ``evoscen.sut`` and ``evoscen.bv`` whose value is a
  :class:`ModelSpec` — how a user's own package plugs a model in without touching ours::

      # the user's setup.py / pyproject
      entry_points={"evoscen.sut": ["my_sut = my_pkg.my_sut:SPEC"]}

Parameters live in the scenario YAML under ``models.<name>`` and are validated against the
model's parameter dataclass with the same checks and one-line errors as every other key
(declare fields with :func:`evoscen_sim.config.scenario_config.number`, :func:`~evoscen_sim.config.scenario_config.integer`,
:func:`~evoscen_sim.config.scenario_config.flag`). A parameter set that several models read and that is no
model itself (``models.krauss``, the SUTs' car following) is registered with
:func:`register_parameter_set`: valid under ``models``, not as ``sut.model`` or ``bvs.driver``.

This module is the registry the configuration reads (:data:`SUT_MODELS`, :data:`BV_DRIVERS`,
the valid ``sut.model`` and ``bvs.driver``); it imports nothing of the configuration, so the
configuration can import it.
"""

from __future__ import annotations

import importlib
import os
import sys
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from importlib import metadata
from typing import Any, Protocol

from .errors import InputError, PluginFault

ROLES = ("sut", "bv")
ENTRY_POINT_GROUPS = {"sut": "evoscen.sut", "bv": "evoscen.bv"}
BUILTIN_MODULES = ("evoscen_bv.bv_models", "evoscen_sut.sut_models")

#: Background-vehicle driver implementations selectable by ``bvs.driver``, in registration order.
BV_DRIVERS: tuple[str, ...] = ("level0",)
#: System-under-test models selectable by ``sut.model``, in registration order.
SUT_MODELS: tuple[str, ...] = ("level0",)


def register_bv_driver(name: str) -> None:
    """Make ``name`` a valid ``bvs.driver`` (idempotent)."""
    global BV_DRIVERS
    if name not in BV_DRIVERS:
        BV_DRIVERS = (*BV_DRIVERS, name)


def register_sut_model(name: str) -> None:
    """Make ``name`` a valid ``sut.model`` (idempotent)."""
    global SUT_MODELS
    if name not in SUT_MODELS:
        SUT_MODELS = (*SUT_MODELS, name)


class Driver(Protocol):
    """What a model's factory returns (see the module's docstring): one answer per step for the
    vehicles it drives, in the order of its ``vehicles``."""

    def act(self, view: Any) -> tuple[Any, Any]:
        """``(throttle, lane_change)`` for ``view`` (a traffic view): throttle/brake in [-1, 1] and a
        lane-change request in {-1, 0, +1}, numpy arrays with one entry per vehicle driven."""
        ...


@dataclass(frozen=True)
class ModelSpec:
    """A driver model: how to validate its parameters and build it."""

    name: str
    """Registry name (``sut.model``, ``bvs.driver``, ``models.<name>``)."""
    roles: tuple[str, ...]
    """Roles the model can play: ``"sut"`` and/or ``"bv"``."""
    factory: Callable[..., Any]
    """``factory(vehicles, params, config, rng) -> driver``: ``vehicles`` an int array of
    world indices, ``params`` an instance of ``params_type`` (or None), ``config`` the
    :class:`~evoscen_sim.config.scenario_config.ScenarioConfig`, ``rng`` a seeded numpy Generator."""
    params_type: type | None = None
    """Frozen dataclass of the model's parameters (defaults documented per field)."""
    description: str = ""
    """One line for listings."""


_REGISTRY: dict[str, ModelSpec] = {}
_PARAMETER_SETS: dict[str, type] = {}
_PLUGINS: dict[str, metadata.EntryPoint] = {}
_BROKEN: dict[str, str] = {}
"""Entry-point name -> why it failed to load (:func:`discover`)."""
"""Model name -> the entry point that registered it (plug-ins only), for :func:`plugin_entry_point`."""
_discovered = False


def register_model(spec: ModelSpec) -> None:
    """Add (or replace) a model in the registry."""
    bad = [r for r in spec.roles if r not in ROLES]
    if bad or not spec.roles:
        raise ValueError(f"model {spec.name!r}: roles {spec.roles} must be a non-empty subset of {ROLES}")
    if spec.name in _PARAMETER_SETS:
        raise ValueError(f"model {spec.name!r}: the name is taken by the parameter set models.{spec.name}")
    _REGISTRY[spec.name] = spec
    if "sut" in spec.roles:
        register_sut_model(spec.name)
    if "bv" in spec.roles:
        register_bv_driver(spec.name)


def register_parameter_set(name: str, params_type: type) -> None:
    """Make ``models.<name>`` a parameter set validated against ``params_type`` (a frozen
    dataclass declared like a model's parameters) that is no model: models read it from
    ``config.models.get(name)`` (absent: the defaults). Idempotent; a model's name is refused."""
    if name in _REGISTRY:
        raise ValueError(f"parameter set {name!r}: the name is taken by a model")
    _PARAMETER_SETS[name] = params_type


_MAKEUP_DRIVERS: dict[str, Callable[..., Any]] = {}
"""``bvs.makeup`` value -> ``factory(vehicles, makeup, config, car_driver) -> driver`` (see
:func:`register_makeup_driver`)."""


def register_makeup_driver(makeup: str, factory: Callable[..., Any]) -> None:
    """Register how the BVs are driven under ``bvs.makeup: <makeup>``: ``factory(vehicles, makeup,
    config, car_driver)`` wraps the ``bvs.driver`` built for all BVs (``car_driver``) with the
    drivers of the other classes (``makeup``: :class:`evoscen_sim.traffic.makeup.Makeup`)."""
    _MAKEUP_DRIVERS[makeup] = factory


def makeup_driver_factory(makeup: str) -> Callable[..., Any]:
    """The factory :func:`register_makeup_driver` registered for ``makeup``."""
    discover()
    if makeup not in _MAKEUP_DRIVERS:
        raise InputError(f"bvs.makeup = {makeup}: no driver registered for it")
    return _MAKEUP_DRIVERS[makeup]


def unregister_model(name: str) -> None:
    """Remove a model from the registry (tests; plug-ins are normally permanent)."""
    global SUT_MODELS, BV_DRIVERS
    _REGISTRY.pop(name, None)
    _PLUGINS.pop(name, None)
    SUT_MODELS = tuple(n for n in SUT_MODELS if n != name)
    BV_DRIVERS = tuple(n for n in BV_DRIVERS if n != name)


def discover() -> None:
    """Import the built-in model modules and load the entry points (once per process).

    An entry point that fails to load (an import error, a value that is no :class:`ModelSpec`,
    a model name that is taken) does not stop the others: it is reported in one line
    ``warning: entry point 'x' in group 'evoscen.sut' (pkg:SPEC) failed to load: ...`` on stderr
    (when a model is first looked up or listed) and only a run that selects it fails, with that line as its error (:func:`broken_plugin`;
    docs/plugins.md §3). [choice] One stale plug-in in the ``.venv`` must not stop the runs of
    every other model; the warning names it so that it can be fixed or uninstalled.
    """
    global _discovered
    if _discovered:
        return
    _discovered = True
    for module in BUILTIN_MODULES:
        try:
            importlib.import_module(module)
        except ImportError:  # a partial install (e.g. evoscen_sim alone): those models are absent
            pass
    builtin = set(_REGISTRY)
    for role, group in ENTRY_POINT_GROUPS.items():
        for ep in metadata.entry_points(group=group):
            problem = _load_entry_point(ep, role, group, builtin)
            if problem is not None:
                _BROKEN.setdefault(ep.name, problem)


_warned = False


def _warn_broken() -> None:
    """The broken entry points' warnings, once per process (not where :data:`QUIET_ENV` is ``1``).
    Printed when a model is looked up or listed, not at discovery: a run that selects a broken
    plug-in fails with its one line only (the configuration refuses it before any look-up)."""
    global _warned
    if _warned:
        return
    _warned = True
    if os.environ.get(QUIET_ENV) != "1":
        for problem in _BROKEN.values():
            print(f"warning: {problem}", file=sys.stderr)


QUIET_ENV = "EVOSCEN_PLUGIN_WARNINGS_SHOWN"
"""Set to ``1`` in the environment of processes whose parent already printed the broken entry
points' warnings (the node graph's nodes): they keep quiet about them."""


def _load_entry_point(ep: metadata.EntryPoint, role: str, group: str, builtin: set[str]) -> str | None:
    """Register the model of entry point ``ep``; None, or one line saying why it cannot be."""
    where = f"entry point {ep.name!r} in group {group!r} ({ep.value})"
    try:
        spec = ep.load()
    except Exception as exc:  # noqa: BLE001 - a broken plug-in must be named, not crash
        return f"{where} failed to load: {_exception_text(exc)}"
    if not isinstance(spec, ModelSpec):
        return (f"{where} is not an evoscen.ModelSpec (got {type(spec).__name__})")
    taken = ("a built-in model" if spec.name in builtin else
             f"the parameter set models.{spec.name}" if spec.name in _PARAMETER_SETS else None)
    if taken is not None:
        return (f"{where} registers the model {spec.name!r}, the name of {taken}: give the plug-in's "
                "model another name")
    if role not in spec.roles:
        spec = ModelSpec(spec.name, (*spec.roles, role), spec.factory, spec.params_type, spec.description)
    try:
        register_model(spec)
    except ValueError as exc:
        return f"{where}: {exc}"
    _PLUGINS[spec.name] = ep
    return None


def broken_plugin(name: str) -> str | None:
    """Why the entry point named ``name`` could not be loaded (one line), or None if it loaded or
    does not exist. A run that selects it fails with this line (exit status 2)."""
    discover()
    return _BROKEN.get(name)


def broken_plugins() -> dict[str, str]:
    """Every entry point that failed to load: its name -> why (one line)."""
    discover()
    return dict(_BROKEN)


def _exception_text(exc: BaseException) -> str:
    """``Type: first line of the message`` (the type alone when there is no message)."""
    lines = str(exc).strip().splitlines()
    return type(exc).__name__ + (f": {lines[0].strip()}" if lines else "")


def plugin_entry_point(name: str) -> metadata.EntryPoint | None:
    """The entry point that registered model ``name`` (its distribution: ``.dist``; its module:
    ``.module``), or None for a built-in model or an unknown name."""
    discover()
    return _PLUGINS.get(name)


def model_source(name: str) -> str:
    """Where model ``name`` comes from, in words: ``built-in (evoscen_sut)``, ``entry point
    first_sut = first_sut:SPEC (evoscen-first-sut 0.1.0)``, ``registered in this process (module)``."""
    discover()
    ep = _PLUGINS.get(name)
    if ep is not None:
        dist = getattr(ep, "dist", None)
        pkg = f" ({dist.metadata['Name']} {dist.version})" if dist is not None else ""
        return f"entry point {ep.name} = {ep.value}{pkg}"
    spec = _REGISTRY.get(name)
    if spec is None:
        return "unknown"
    module = getattr(spec.factory, "__module__", None) or "?"
    top = module.split(".")[0]
    return f"built-in ({top})" if top.startswith("evoscen_") else f"registered in this process ({module})"


def model_names(role: str) -> tuple[str, ...]:
    """Names of the models that can play ``role``, sorted."""
    discover()
    _warn_broken()
    return tuple(sorted(name for name, spec in _REGISTRY.items() if role in spec.roles))


def get_model(name: str, role: str) -> ModelSpec:
    """The spec of model ``name`` for ``role``; InputError listing the valid choices otherwise."""
    discover()
    if name in _BROKEN:
        raise InputError(_BROKEN[name])
    _warn_broken()
    spec = _REGISTRY.get(name)
    if spec is None or role not in spec.roles:
        key = "sut.model" if role == "sut" else "bvs.driver"
        raise InputError(f"unknown {key} '{name}': expected one of {', '.join(model_names(role))}")
    return spec


def create_driver(name: str, role: str, vehicles, config, rng) -> Any:
    """Build model ``name`` for ``role`` driving world indices ``vehicles``."""
    import numpy as np

    spec = get_model(name, role)
    params = config.models.get(name) if spec.params_type is not None else None
    if spec.params_type is not None and params is None:
        params = spec.params_type()
    vehicles = np.asarray(vehicles, dtype=np.int64)
    try:
        driver = spec.factory(vehicles, params, config, rng)
    except (InputError, PluginFault):  # the model's own one-line error (e.g. a mutant's base), or a nested model's fault
        raise
    except Exception as exc:  # a model's failure is named in one line, not a traceback
        raise plugin_failure(exc, name, role, "its factory", spec.factory) from exc
    _remember(driver, (name, role, len(vehicles)))
    return driver


def plugin_failure(exc: BaseException, name: str, role: str, during: str, code: Any = None,
                   step: int | None = None) -> PluginFault:
    """The :class:`PluginFault` of model ``name`` (``role``) whose code raised ``exc`` while
    ``during`` (``"act() at step 12"``, ``"its factory"``): one line with the exception's type and
    first message line and ``file:line`` of the innermost frame in the model's own code (the
    package or module of its factory, else of ``code``; else the innermost frame)."""
    ep = _PLUGINS.get(name)
    origin = f" (entry point {ep.value})" if ep is not None else ""
    spec = _REGISTRY.get(name)
    where = _frame_in(exc, spec.factory if spec is not None else code)
    return PluginFault(f"{role} model {name!r}{origin}: {during} raised {_exception_text(exc)}"
                       + (f" ({where})" if where else ""), model=name, role=role, step=step)


def driver_identity(driver: Any, default: tuple[str, str]) -> tuple[str, str]:
    """(model name, role) of a driver built by :func:`create_driver`, else ``default``."""
    built = _built(driver)
    return (built[0], built[1]) if built is not None else default


def _frame_in(exc: BaseException, code: Any) -> str:
    """``file:line`` of the innermost traceback frame of ``exc`` in ``code``'s package (see
    :func:`plugin_failure`); the path relative to the working directory when it lies below it."""
    import traceback

    frames = traceback.extract_tb(exc.__traceback__)
    if not frames:
        return ""
    def own(filename: str) -> bool:  # a file of the model's package (a single-module plug-in: that file)
        return False

    module = sys.modules.get(getattr(code, "__module__", None) or type(code).__module__)
    top = sys.modules.get(module.__name__.split(".")[0]) if module is not None else None
    top_file = getattr(top, "__file__", None)
    if top_file:
        top_file = os.path.abspath(top_file)
        if os.path.basename(top_file) == "__init__.py":
            home = os.path.dirname(top_file) + os.sep

            def own(filename: str) -> bool:
                return os.path.abspath(filename).startswith(home)
        else:
            def own(filename: str) -> bool:
                return os.path.abspath(filename) == top_file
    mine = [f for f in frames if own(f.filename)]
    chosen = mine[-1] if mine else frames[-1]
    path = os.path.abspath(chosen.filename)
    rel = os.path.relpath(path)
    return f"{path if rel.startswith('..') else rel}:{chosen.lineno}"


_BUILT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""driver -> (model name, role, number of vehicles), for :func:`checked_answer`'s error line."""
_BUILT_BY_ID: dict[int, tuple[str, str, int]] = {}
"""The same for drivers that cannot be weakly referenced or hashed (keyed by ``id``)."""


def _remember(driver: Any, what: tuple[str, str, int]) -> None:
    try:
        _BUILT[driver] = what
    except TypeError:
        _BUILT_BY_ID[id(driver)] = what


def rehosted(driver: Any, count: int) -> None:
    """Record that ``driver`` (built by :func:`create_driver`) now drives ``count`` vehicles (a BV
    node's share, :func:`evoscen_sim.scenario_builders.build_bv_driver`), for :func:`checked_answer`."""
    what = _built(driver)
    if what is not None:
        _remember(driver, (what[0], what[1], int(count)))


def _built(driver: Any) -> tuple[str, str, int] | None:
    try:
        what = _BUILT.get(driver)
    except TypeError:
        what = None
    return what if what is not None else _BUILT_BY_ID.get(id(driver))


_ANSWER_KERNEL = None
""":func:`evoscen_sim.answer_check.answer_fine`, imported at the first check (numba is not imported with this module)."""


def _fine(throttle: Any, lane_change: Any, count: int | None) -> bool:
    """A quick yes for the common answer: two arrays of ``count``, finite throttle, integer lane changes in {-1, 0, 1}."""
    import numpy as np

    global _ANSWER_KERNEL
    if type(throttle) is not np.ndarray or type(lane_change) is not np.ndarray:
        return False
    if throttle.ndim != 1 or throttle.shape != lane_change.shape or (count is not None and len(throttle) != count):
        return False
    if throttle.dtype.char == "d" and lane_change.dtype.char in "lq":  # float64 and int64: one compiled pass
        if _ANSWER_KERNEL is None:
            from evoscen_sim.answer_check import answer_fine

            _ANSWER_KERNEL = answer_fine
        return _ANSWER_KERNEL(throttle, lane_change)
    if lane_change.dtype.kind not in "iu" or throttle.dtype.kind != "f":
        return False
    if not throttle.size:
        return not lane_change.size
    # the sum of throttle values is finite exactly when they all are (|values| far below overflow)
    return bool(np.isfinite(throttle.sum())) and bool(lane_change.size) and int(np.abs(lane_change).max()) <= 1


def checked_answer(driver: Any, answer: Any, count: int | None = None) -> tuple[Any, Any]:
    """``driver``'s answer ``act(view) -> (throttle, lane_change)``, checked where every runner takes it.

    Returns ``answer`` as it is when it is a pair of ``count`` finite throttle values and ``count``
    lane-change values in {-1, 0, +1} (``count``: the vehicles the driver was built for by
    :func:`create_driver`); otherwise an :class:`InputError` of one line naming the model and its
    role, what it returned and what is expected (the command-line tools: ``error: ...``, exit 2).
    A finite throttle outside [-1, 1] is not refused here (the in-process runner clips it; see
    docs/plugins.md §3).
    """
    import numpy as np

    built = _built(driver)
    if count is None and built is not None:
        count = built[2]
    if (type(answer) is tuple and len(answer) == 2 and _fine(answer[0], answer[1], count)):
        return answer  # every step, twice: the common case in a few µs
    name, role, _ = built or (type(driver).__name__, "driver", None)
    who = f"{role} model {name!r}: act() returned"
    if not isinstance(answer, (tuple, list)) or len(answer) != 2:
        got = f"a {type(answer).__name__}" + (f" of {len(answer)}" if isinstance(answer, (tuple, list)) else "")
        raise InputError(f"{who} {got}; expected a pair (throttle, lane_change) of arrays, one entry per vehicle")
    out = []
    for what, value in zip(("throttle", "lane_change"), answer):
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{who} a {what} of type {type(value).__name__}; expected an array of numbers, "
                             "one per vehicle") from None
        if count is not None and arr.shape != (count,):
            raise InputError(f"{who} a {what} of shape {arr.shape}; expected shape ({count},), one per vehicle")
        out.append(arr)
    throttle, lane_change = out
    if throttle.ndim != 1 or throttle.shape != lane_change.shape:
        raise InputError(f"{who} a throttle of shape {throttle.shape} and a lane_change of shape {lane_change.shape}; "
                         "expected two arrays of the same length, one entry per vehicle")
    bad = ~np.isfinite(throttle)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"{who} throttle {throttle[k]} (entry {k}); expected a finite number in [-1, 1]")
    bad = ~((lane_change == 0.0) | (np.abs(lane_change) == 1.0))  # nan too
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"{who} lane_change {lane_change[k]:g} (entry {k}); expected -1, 0 or 1")
    return answer


def params_type_of(name: str) -> type | None:
    """The parameter dataclass of a registered model or parameter set (None if it has none or is unknown)."""
    discover()
    spec = _REGISTRY.get(name)
    return _PARAMETER_SETS.get(name) if spec is None else spec.params_type


def parameter_names() -> tuple[str, ...]:
    """The names valid under ``models``: the models with parameters and the parameter sets, sorted."""
    discover()
    return tuple(sorted({n for n, spec in _REGISTRY.items() if spec.params_type is not None} | set(_PARAMETER_SETS)))
