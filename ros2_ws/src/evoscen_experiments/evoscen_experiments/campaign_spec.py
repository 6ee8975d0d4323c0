"""Campaign specs and run keys: a spec read and validated, expanded into runs, each keyed once (docs/campaigns.md).

A **spec** names a scenario configuration, the seeds, overrides for every run (``set``) and a
``grid`` of axes (scenario keys such as ``sut.model`` or ``bvs.driver``, and ``mutant``: a
mutant of the run's ``sut.model``, :mod:`evoscen_sut.mutants`, or ``intact``); the campaign is
every combination of the axes' values (a *cell*) for every seed.

A run is keyed by a hash of its whole resolved configuration, of the code version
(:func:`code_version`: the content of evoscen's packages, maps and shipped policies) and, for a
run that uses a plug-in model, of that plug-in (:func:`plugin_versions`: its distribution's name
and version and the content of its module's files); :mod:`evoscen_experiments.campaign` runs each
key once.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import itertools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from evoscen_sim.config.scenario_config import ScenarioConfig, config_to_dict, load_scenario_config
from evoscen_sim.errors import InputError

CHALLENGE_KEY = "challenge.mode"
COMPARED_CHALLENGE = "nade"
"""[choice] A spec with ``compare`` (a paired design) runs the challenge scenario unless ``set`` or ``grid`` names
``challenge.mode``: a harder test, the same for both members of a pair, as the sensitivity experiment and the
leaderboard (docs/challenges.md)."""

SPEC_KEYS = ("name", "config", "steps", "seeds", "set", "grid", "record", "clip_s", "compare")
RECORD_MODES = ("none", "events", "all")
MUTANT_AXIS = "mutant"
INTACT = "intact"
PACKAGES = ("evoscen_contract", "evoscen_sim", "evoscen_bv", "evoscen_sut", "evoscen_record", "evoscen_eval",
            "evoscen_bringup", "evoscen_experiments", "evoscen")


@dataclass(frozen=True)
class Spec:
    """A campaign spec, validated (see the module docstring)."""

    path: Path
    name: str
    config: str | None
    steps: int | None
    seeds: tuple[int, ...]
    fixed: dict[str, str]
    grid: dict[str, tuple[str, ...]]
    record: str = "none"
    compare: tuple[str, str] | None = None
    clip_s: float = 5.0


@dataclass(frozen=True)
class CampaignRun:
    """One run of a campaign: its cell (axis → value), seed, configuration and key."""

    key: str
    cell: tuple[tuple[str, str], ...]
    seed: int
    cfg: ScenarioConfig



def _err(path: Path, key: str, value: Any, expected: str) -> InputError:
    return InputError(f"{path}: key {key!r} = {value!r}: expected {expected}")


def load_spec(path: Path | str) -> Spec:
    """Read and validate a campaign spec; InputError (one line naming the file and key) if it is wrong."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"campaign spec {str(path)!r}: cannot read: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"campaign spec {str(path)!r}: not YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(doc, dict):
        raise InputError(f"campaign spec {str(path)!r}: expected a mapping of {', '.join(SPEC_KEYS)}")
    unknown = [k for k in doc if k not in SPEC_KEYS]
    if unknown:
        raise _err(path, str(unknown[0]), doc[unknown[0]], f"one of the keys {', '.join(SPEC_KEYS)}")
    name = doc.get("name", path.stem)
    if not isinstance(name, str) or not name.strip() or "/" in name:
        raise _err(path, "name", name, "a non-empty name without '/'")
    config = doc.get("config")
    if config is not None and not isinstance(config, str):
        raise _err(path, "config", config, "a scenario YAML file (relative to the spec) or null")
    if config is not None and not Path(config).is_absolute():
        config = str((path.parent / config).resolve())
    steps = doc.get("steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise _err(path, "steps", steps, "an integer >= 1")
    seeds = _seeds(path, doc.get("seeds", {"first": 0, "count": 1}))
    fixed = doc.get("set") or {}
    if not isinstance(fixed, dict):
        raise _err(path, "set", fixed, "a mapping of scenario keys to values")
    grid = doc.get("grid") or {}
    if not isinstance(grid, dict):
        raise _err(path, "grid", grid, "a mapping of axes (scenario keys or 'mutant') to lists of values")
    axes: dict[str, tuple[str, ...]] = {}
    for axis, values in grid.items():
        if not isinstance(values, list) or not values or len({str(v) for v in values}) != len(values):
            raise _err(path, f"grid.{axis}", values, "a non-empty list of distinct values")
        axes[str(axis)] = tuple(_text(v) for v in values)
    if MUTANT_AXIS in axes:
        from evoscen_sut.mutants import LIBRARY

        bad = [m for m in axes[MUTANT_AXIS] if m != INTACT and m not in LIBRARY]
        if bad:
            raise _err(path, f"grid.{MUTANT_AXIS}", bad[0], f"'{INTACT}' or a mutant of {', '.join(LIBRARY)}")
    record = doc.get("record", "none")
    if record not in RECORD_MODES:
        raise _err(path, "record", record, "'none' (scores only), 'events' (critical-event clips) or 'all' "
                   "(clips and the whole bag)")
    clip_s = doc.get("clip_s", 5.0)
    if isinstance(clip_s, bool) or not isinstance(clip_s, (int, float)) or not 0 < clip_s <= 60:
        raise _err(path, "clip_s", clip_s, "seconds in (0, 60] on either side of an event")
    compare = doc.get("compare")
    if compare is not None:
        if (not isinstance(compare, dict) or set(compare) != {"axis", "reference"}
                or compare["axis"] not in axes or _text(compare["reference"]) not in axes[compare["axis"]]):
            raise _err(path, "compare", compare, "{axis: <a grid axis>, reference: <one of its values>}")
        compare = (str(compare["axis"]), _text(compare["reference"]))
    fixed = {str(k): _text(v) for k, v in fixed.items()}
    if compare is not None and CHALLENGE_KEY not in fixed and CHALLENGE_KEY not in axes:
        fixed[CHALLENGE_KEY] = COMPARED_CHALLENGE  # a paired design: the challenge scenario (docs/challenges.md)
    return Spec(path, name.strip(), config, steps, seeds, fixed, axes, record, compare, float(clip_s))


def _text(value: Any) -> str:
    """A spec value as the command-line override text of the scenario loader."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _seeds(path: Path, value: Any) -> tuple[int, ...]:
    if isinstance(value, list) and value and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0
                                                 for s in value) and len(set(value)) == len(value):
        return tuple(value)
    if isinstance(value, dict) and set(value) <= {"first", "count"} and "count" in value:
        first, count = value.get("first", 0), value["count"]
        if all(isinstance(x, int) and not isinstance(x, bool) for x in (first, count)) and first >= 0 and count >= 1:
            return tuple(range(first, first + count))
    raise _err(path, "seeds", value, "a list of distinct integers >= 0, or {first: N, count: M}")


def expand(spec: Spec, version: str | None = None) -> list[CampaignRun]:
    """Every run of the spec: each cell (combination of the axes' values, in the spec's order) × each seed."""
    version = code_version() if version is None else version
    axes = list(spec.grid)
    runs = []
    for values in itertools.product(*(spec.grid[a] for a in axes)) if axes else [()]:
        cell = tuple(zip(axes, values))
        overrides = dict(spec.fixed)
        mutant = None
        for axis, value in cell:
            if axis == MUTANT_AXIS:
                mutant = value
            else:
                overrides[axis] = value
        overrides["recording.enabled"] = "false" if spec.record == "none" else "true"
        if spec.steps is not None:
            overrides["steps"] = str(spec.steps)
        for seed in spec.seeds:
            over = {**overrides, "seed": str(seed)}
            try:
                cfg = load_scenario_config(spec.config, over)
                if mutant is not None and mutant != INTACT:
                    from evoscen_sut.mutants import mutant_overrides

                    cfg = load_scenario_config(spec.config, {**over, **mutant_overrides(cfg.sut.model, mutant)})
            except InputError as exc:
                raise InputError(f"{spec.path}: cell {dict(cell)}: {exc}") from None
            runs.append(CampaignRun(run_key(cfg, version), cell, seed, cfg))
    return runs


def run_key(cfg: ScenarioConfig, version: str) -> str:
    """The run's key: SHA-256 of its whole resolved configuration, the code version and the plug-ins
    the run uses (:func:`plugin_versions`; a run without one keeps the key it had before plug-ins
    were part of it) — 20 hex digits."""
    d = config_to_dict(cfg)
    text = json.dumps(d, sort_keys=True, default=str)
    plugins = plugin_versions(d)
    head = f"{version}\n{plugins}" if plugins else version
    return hashlib.sha256(f"{head}\n{text}".encode()).hexdigest()[:20]


def plugin_versions(config: dict[str, Any]) -> str:
    """The plug-in models a resolved configuration (:func:`config_to_dict`) names — any of its values
    or ``models`` keys that is a plug-in's model name: ``sut.model``, ``bvs.driver``, a mutant's
    ``models.mutant.base`` — each as ``name=distribution==version:hash`` (:func:`plugin_fingerprint`),
    sorted and joined by ``;``; empty when it names none."""
    from evoscen_sim.model_registry import plugin_entry_point

    names: set[str] = set()

    def walk(value: Any) -> None:
        if isinstance(value, str):
            names.add(value)
        elif isinstance(value, dict):
            for v in value.values():
                walk(v)
        elif isinstance(value, (list, tuple)):
            for v in value:
                walk(v)

    walk(config)
    names.update(str(k) for k in (config.get("models") or {}))
    parts = []
    for name in sorted(names):
        ep = plugin_entry_point(name)
        if ep is not None:
            dist = ep.dist
            parts.append(f"{name}={plugin_fingerprint(ep.module, dist.name if dist else '?', dist.version if dist else '?')}")
    return ";".join(parts)


@functools.lru_cache(maxsize=None)
def plugin_fingerprint(module: str, dist_name: str, dist_version: str) -> str:
    """``distribution==version:hash``: the hash (16 hex digits) covers the files of the plug-in's
    top-level module — every file of its package directory (``__pycache__`` left out), or the one
    ``.py`` file of a single-module plug-in — so an edited plug-in (an editable install, a changed
    file in place) gets new keys even when its version stays. Cached per process, like
    :func:`code_version`."""
    import importlib.util

    top = module.split(".")[0]
    spec = importlib.util.find_spec(top)
    files: list[tuple[str, Path]] = []
    if spec is not None and spec.submodule_search_locations:
        root = Path(next(iter(spec.submodule_search_locations))).resolve()
        files = [(f.relative_to(root).as_posix(), f) for f in sorted(root.rglob("*"))
                 if f.is_file() and "__pycache__" not in f.parts]
    elif spec is not None and spec.origin and Path(spec.origin).is_file():
        files = [(Path(spec.origin).name, Path(spec.origin))]
    h = hashlib.sha256()
    for rel, f in files:
        h.update(rel.encode())
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return f"{dist_name}=={dist_version}:{h.hexdigest()[:16]}"


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """A hash of what decides a run's result besides its configuration: the files of evoscen's
    packages (sources, maps, configuration) and the shipped BV policies."""
    from evoscen_bv.learned import shipped_policy_dir

    roots = [Path(importlib.import_module(p).__file__).resolve().parent for p in PACKAGES]
    from evoscen_sim.share import share_candidates

    roots += [c for c in share_candidates("maps") if c.is_dir()][:1]
    policies = shipped_policy_dir()
    if policies.is_dir():
        roots.append(policies.resolve())
    h = hashlib.sha256()
    for root in roots:
        for f in sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
            h.update(f.relative_to(root).as_posix().encode())
            h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()[:16]
