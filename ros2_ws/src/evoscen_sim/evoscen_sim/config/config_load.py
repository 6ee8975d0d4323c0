"""Loading and validating configurations: YAML with line numbers, the one validator, overrides, dump.

:func:`build` is the validator of every evoscen configuration: it walks a frozen dataclass's
fields, applies the checker each declares (:mod:`evoscen_sim.config.config_checks`), recurses into
sections, rejects unknown keys and reports the first problem as one line::

    <file or source>: key '<dotted.key>' = <value>: expected <what is allowed> (line <n>)

(``command line`` and ``(overriding <file>)`` for a value from an override). The scenario
(:func:`load_scenario_config`, :func:`config_from_dict`; a node's ``scenario.*`` parameters
go through :func:`config_from_dict`), the driver models' parameters (``models.<name>``) and
the training configuration (:func:`evoscen_bv.training_config.load_training_config`) are all
validated by it; :func:`parse_yaml` gives the line numbers.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NoReturn

import yaml

from evoscen_sim.config.config_checks import _Bad, _join, _show, _unknown_text
from evoscen_sim.config.config_schema import MAKEUP_CAR_DRIVERS, EvaluationConfig, ScenarioConfig
from evoscen_sim.limits import MAX_CONFIG_BYTES, check_yaml_depth, read_text_limited
from evoscen_sim.errors import InputError
from evoscen_sim.model_registry import broken_plugin, broken_plugins, discover, parameter_names, params_type_of
from evoscen_sim.share import PACKAGE, share_candidates, share_path

_DEFAULT_CONFIG = "config/default_scenario.yaml"

# --------------------------------------------------------------------------------------------
# YAML loading with line numbers
# --------------------------------------------------------------------------------------------

class _Loader(yaml.SafeLoader):
    """Safe loader without YAML 1.1 base-60 numbers; floats may omit the dot (``1e3``)."""


_INT_TAG = "tag:yaml.org,2002:int"
_FLOAT_TAG = "tag:yaml.org,2002:float"
_Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(
    _INT_TAG,
    re.compile(r"^(?:[-+]?0b[0-1_]+|[-+]?0x[0-9a-fA-F_]+|[-+]?(?:0|[1-9][0-9_]*))$"),
    list("-+0123456789"))
_Loader.add_implicit_resolver(
    _FLOAT_TAG,
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?(?:[eE][-+]?[0-9]+)?
                   |[-+]?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
                   |[-+]?\.(?:inf|Inf|INF)
                   |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def _record_lines(node: yaml.Node, path: str, lines: dict[str, int], label: str,
                  seen_nodes: set[int] | None = None) -> None:
    """Map dotted key paths to 1-based line numbers of their values; reject duplicate keys.

    A node reached again through an alias is not walked again (a chain of aliases would
    otherwise cost exponential time, YAML's "billion laughs")."""
    if not isinstance(node, yaml.MappingNode):
        return
    if seen_nodes is None:
        seen_nodes = set()
    if id(node) in seen_nodes:
        return
    seen_nodes.add(id(node))
    seen: set[str] = set()
    for key_node, value_node in node.value:
        if not isinstance(key_node, yaml.ScalarNode):
            continue
        key_path = _join(path, key_node.value)
        line = key_node.start_mark.line + 1
        if key_node.value in seen:
            raise InputError(f"{label}: key '{key_path}' appears twice (line {line}): "
                             "expected each key once")
        seen.add(key_node.value)
        lines[key_path] = line
        _record_lines(value_node, key_path, lines, label, seen_nodes)


def parse_yaml(text: str, label: str, what: str = "scenario config") -> tuple[Any, dict[str, int]]:
    """The document in ``text`` and the line number of each dotted key; InputError (one line,
    naming ``label`` and the line) for bad YAML, a duplicate key or nesting deeper than the
    limit (``what`` names the kind of file there)."""
    check_yaml_depth(text, label, what, _Loader)
    lines: dict[str, int] = {}
    loader = None
    try:
        loader = _Loader(text)  # the reader checks the characters here (YAMLError)
        node = loader.get_single_node()
        if node is None:
            return None, lines
        _record_lines(node, "", lines, label)
        return loader.construct_document(node), lines
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = " ".join(str(exc.problem or exc.context or "invalid YAML").split())
        raise InputError(f"{label}: YAML syntax error{where}: {problem}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{label}: YAML error: {' '.join(str(exc).split())}") from None
    finally:
        if loader is not None:
            loader.dispose()


_CLI_DECIMAL = re.compile(r"^[-+]?[0-9]+$")
_CLI_FLOAT = re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?$")


_CLI_SCALARS: dict[str, Any] = {}
"""Texts :func:`_parse_cli_scalar` read as a plain scalar (str, int, float, bool, None; immutable, so shared):
an experiment builds thousands of configurations from the same few override texts (docs/performance.md,
"Start-up")."""
_CLI_SCALARS_MAX = 4096


def _parse_cli_scalar(text: str) -> Any:
    """Interpret an override given as text (``"200"``, ``"true"``, ``"[24, 30]"``) as YAML.

    Numbers on the command line are strict: a plain decimal integer (``16``, not ``0x10``,
    ``0b10000`` or ``1_6``, which YAML would read as 16) or a plain decimal float; anything
    else stays text, so the key's check rejects it naming the value as typed."""
    try:
        return _CLI_SCALARS[text]
    except KeyError:
        pass
    value = _read_cli_scalar(text)
    if type(value) in (str, int, float, bool, type(None)) and len(_CLI_SCALARS) < _CLI_SCALARS_MAX:
        _CLI_SCALARS[text] = value  # a list or a mapping is read anew each time (the caller may change it)
    return value


def _read_cli_scalar(text: str) -> Any:
    """:func:`_parse_cli_scalar` without its memo."""
    if len(text) > 10_000:
        return text
    try:
        value = yaml.load(text, Loader=_Loader)  # _Loader is a SafeLoader
    except (yaml.YAMLError, RecursionError):
        return text
    stripped = text.strip()
    if isinstance(value, int) and not isinstance(value, bool) and not _CLI_DECIMAL.match(stripped):
        return text
    if isinstance(value, float) and not _CLI_FLOAT.match(stripped):
        return text
    return value


class Context:
    """Where values came from, for the one-line error messages of :func:`build`.

    ``label`` names the file (or source), ``lines`` maps dotted keys to their line numbers
    (:func:`parse_yaml`), ``cli_paths`` / ``override_keys`` the keys set on the command line.
    ``top_level`` names what the document's top level holds, for the error when it is not a
    mapping; ``default_check(field)`` gives the checker of a field that declares none (the
    training configuration's parameter dataclasses, checked by the type of their defaults).
    """

    def __init__(self, label: str, lines: dict[str, int] | None = None, cli_paths: set[str] | None = None,
                 override_keys: set[str] | None = None, *, top_level: str = "scenario keys",
                 default_check: Callable[[dataclasses.Field], Any] | None = None) -> None:
        self.label = label
        self.lines = lines if lines is not None else {}
        self.cli_paths = cli_paths if cli_paths is not None else set()
        self.override_keys = override_keys if override_keys is not None else set()
        self.top_level = top_level
        self.default_check = default_check

    def from_cli(self, path: str) -> bool:
        if path in self.cli_paths:
            return True
        parts = path.split(".")
        return any(".".join(parts[:i]) in self.override_keys for i in range(1, len(parts)))

    def _prefix(self, path: str) -> tuple[str, str]:
        if self.from_cli(path):
            return "command line", f" (overriding {self.label})"
        line = self.lines.get(path)
        return self.label, (f" (line {line})" if line else "")

    def fail(self, path: str, value: Any, expected: str, *, is_default: bool = False) -> NoReturn:
        source, suffix = self._prefix(path)
        default = " (default)" if is_default else ""
        raise InputError(f"{source}: key '{path}' = {_show(value)}{default}: {expected}{suffix}")

    def unknown(self, path: str, key: Any, allowed: tuple[str, ...] | list[str]) -> NoReturn:
        key_path = _join(path, str(key))
        source, suffix = self._prefix(key_path)
        raise InputError(f"{source}: key '{key_path}': {_unknown_text(key, allowed)}{suffix}")


def build(cls: type, raw: Any, path: str, ctx: Context,
          explicit: set[str]) -> Any:
    """Validate ``raw`` (a mapping or None) against dataclass ``cls``; record explicit keys.

    ``path`` is the dotted key of ``raw`` ("" at the top level). A field with metadata
    ``section`` is a nested dataclass, ``models`` the driver models' parameters, ``check`` a
    checker of :mod:`evoscen_sim.config.config_checks`; the first problem raises InputError.
    """
    fields = dataclasses.fields(cls)
    names = [f.name for f in fields]
    if raw is None:  # an empty section (all lines commented out) means all defaults
        raw = {}
    if not isinstance(raw, Mapping):
        if not path:
            raise InputError(f"{ctx.label}: expected a mapping of {ctx.top_level} at top level "
                             f"({', '.join(names)}), got {type(raw).__name__} {_show(raw)}")
        ctx.fail(path, raw, "expected a mapping with keys " + ", ".join(names))
    for key in raw:
        if key not in names:
            ctx.unknown(path, key, names)
    kwargs: dict[str, Any] = {}
    for f in fields:
        if f.name not in raw:
            continue
        key_path = _join(path, f.name)
        value = raw[f.name]
        explicit.add(key_path)
        if "section" in f.metadata:
            kwargs[f.name] = build(f.metadata["section"], value, key_path, ctx, explicit)
            continue
        if "models" in f.metadata:
            kwargs[f.name] = _build_models(value, key_path, ctx, explicit)
            continue
        if "check" in f.metadata:
            checker = f.metadata["check"]
        elif ctx.default_check is not None:  # the training configuration's dataclasses
            checker = ctx.default_check(f)
        else:  # a plug-in's field declared without a declarator
            ctx.fail(key_path, value, f"a field declared with number(), integer(), flag(), text(), number_range() or "
                                      f"names() (evoscen_sim.config.scenario_config); {cls.__module__}.{cls.__qualname__}.{f.name} "
                                      f"has no declarator, so it cannot be set")
        if isinstance(value, str) and not checker.takes_str and ctx.from_cli(key_path):
            value = _parse_cli_scalar(value)
        try:
            kwargs[f.name] = checker(value)
        except _Bad as bad:
            if bad.subkey is None:
                ctx.fail(key_path, value, bad.expected)
            sub_path = _join(key_path, bad.subkey)
            if bad.allowed is not None:
                ctx.unknown(key_path, bad.subkey, bad.allowed)
            ctx.fail(sub_path, bad.value, bad.expected)
    return cls(**kwargs)


def _build_models(raw: Any, path: str, ctx: Context, explicit: set[str]) -> dict[str, Any]:
    """The ``models`` section: model name -> validated parameter dataclass."""
    if raw is None:
        return {}
    with_params = parameter_names()
    if not isinstance(raw, Mapping):
        ctx.fail(path, raw, "expected a mapping of model name -> parameters (models with parameters: "
                 + ", ".join(with_params) + ")")
    out: dict[str, Any] = {}
    for name, section in raw.items():
        cls = params_type_of(str(name))
        if cls is None:
            ctx.unknown(path, name, with_params)
        out[str(name)] = build(cls, section, _join(path, str(name)), ctx, explicit)
    return out


def _refuse_broken_plugins(data: Any, ctx: Context) -> None:
    """A ``sut.model``, ``bvs.driver`` or ``models.<name>`` naming an entry point that failed to
    load: its one line (why it failed) as this run's error (docs/plugins.md §3)."""
    if not broken_plugins() or not isinstance(data, Mapping):
        return
    for section, key in (("sut", "model"), ("bvs", "driver")):
        part = data.get(section)
        name = part.get(key) if isinstance(part, Mapping) else None
        if isinstance(name, str) and broken_plugin(name) is not None:
            ctx.fail(f"{section}.{key}", name, broken_plugin(name))
    models = data.get("models")
    for name in models if isinstance(models, Mapping) else ():
        if isinstance(name, str) and broken_plugin(name) is not None:
            ctx.fail(f"models.{name}", "{...}", broken_plugin(name))


def _cross_check(cfg: ScenarioConfig, ctx: Context, explicit: set[str]) -> None:
    count_text = f"bvs.count = {cfg.bvs.count}"
    if ctx.from_cli("bvs.count") and not ctx.from_cli("spawn.ramp_vehicles"):
        count_text += " (set on the command line)"
    if cfg.spawn.ramp_vehicles > cfg.bvs.count:
        ctx.fail("spawn.ramp_vehicles", cfg.spawn.ramp_vehicles,
                 f"expected an integer in [0, bvs.count] with {count_text}",
                 is_default="spawn.ramp_vehicles" not in explicit)
    if cfg.bvs.makeup != "uniform":
        # [choice] the default make-up (highd) is not dropped silently where it cannot apply: the line
        # says so, and bvs.makeup: uniform is the one key that selects the traffic without trucks
        default = "bvs.makeup" not in explicit
        if cfg.traffic.mode != "window":
            ctx.fail("bvs.makeup", cfg.bvs.makeup, "expected uniform with traffic.mode = "
                     f"{cfg.traffic.mode} (the highd make-up needs traffic.mode: window; set bvs.makeup: uniform)",
                     is_default=default)
        if cfg.bvs.driver not in MAKEUP_CAR_DRIVERS:
            ctx.fail("bvs.makeup", cfg.bvs.makeup, f"expected uniform with bvs.driver = {cfg.bvs.driver} "
                     f"(the highd make-up's cars are {', '.join(MAKEUP_CAR_DRIVERS)} drivers; set bvs.makeup: "
                     "uniform)", is_default=default)
    ch = cfg.challenge
    if ch.headway_full_s >= ch.headway_none_s:
        ctx.fail("challenge.headway_full_s", ch.headway_full_s,
                 f"expected a number below challenge.headway_none_s = {ch.headway_none_s:g}",
                 is_default="challenge.headway_full_s" not in explicit)
    ev = cfg.evaluation
    if ev.weight_safety + ev.weight_efficiency + ev.weight_interaction == 0:
        ctx.fail("evaluation.weight_safety", ev.weight_safety,
                 "expected weights not all 0 (evaluation.weight_safety, weight_efficiency, weight_interaction)")
    if cfg.bvs.count > 0 and sum(cfg.bvs.mix.values()) == 0:
        ctx.fail("bvs.mix", cfg.bvs.mix,
                 f"expected at least one non-zero share when {count_text}",
                 is_default="bvs.mix" not in explicit)


def evaluation_from_dict(raw: Any, source: str) -> EvaluationConfig:
    """Validate an ``evaluation`` section alone (e.g. from a bag's recorded scenario), as the
    whole file would be; ``source`` names it in errors."""
    cfg = build(EvaluationConfig, raw, "evaluation", Context(source, {}, set(), set()), set())
    if cfg.weight_safety + cfg.weight_efficiency + cfg.weight_interaction == 0:
        raise InputError(f"{source}: key 'evaluation.weight_safety' = 0: expected weights not all 0 "
                         "(evaluation.weight_safety, weight_efficiency, weight_interaction)")
    return cfg


def resolve_map_path(value: str, base_dir: str | Path | None = None) -> Path:
    """Resolve a ``map`` value to an existing file's absolute path.

    Order: ``value`` itself if absolute (``~`` expanded); else ``base_dir / value`` (the config
    file's directory; the current directory when ``base_dir`` is None); else
    ``share_path("maps/" + value)``. Raises InputError listing the places tried.
    """
    candidate = Path(os.path.expanduser(value))
    if candidate.is_absolute():
        tried = [candidate]
    else:
        base = Path(base_dir) if base_dir is not None else Path.cwd()
        tried = [base / candidate, *share_candidates(f"maps/{value}", PACKAGE)]
    for path in tried:
        if path.is_file():
            return _resolved(str(path))
    raise InputError(f"map '{value}': file not found (tried {', '.join(map(str, tried))})")


@functools.lru_cache(maxsize=256)
def _resolved(path: str) -> Path:
    """``Path(path).resolve()``, once per path (symbolic links followed: an installed workspace's share files are
    links; an experiment resolves thousands of configurations' maps, docs/performance.md "Start-up")."""
    return Path(path).resolve()


def config_from_dict(data: Any, *, source: str = "<dict>",
                     base_dir: str | Path | None = None,
                     overrides: Mapping[str, object] | None = None,
                     _lines: dict[str, int] | None = None) -> ScenarioConfig:
    """Validate an already-parsed mapping (e.g. from a ROS parameter file) into a config.

    ``source`` names it in error messages; ``base_dir`` anchors a relative ``map``.
    """
    discover()  # the registered models define the valid sut.model, bvs.driver and models.*
    override_keys: set[str] = set()
    cli_paths: set[str] = set()
    if overrides:
        data = _apply_overrides(data, overrides, source, override_keys, cli_paths)
    ctx = Context(source, _lines or {}, cli_paths, override_keys)
    _refuse_broken_plugins(data, ctx)
    explicit: set[str] = set()
    cfg = build(ScenarioConfig, data, "", ctx, explicit)
    _cross_check(cfg, ctx, explicit)
    map_base = None if ctx.from_cli("map") else base_dir
    try:
        # a relative map given on the command line is looked up from the current directory
        map_path = resolve_map_path(cfg.map, map_base)
    except InputError as exc:
        detail = str(exc).split(": ", 1)[1]
        ctx.fail("map", cfg.map, detail + "; expected an existing OpenDRIVE file: an absolute "
                 "path, a path relative to the config file, or a name under evoscen_sim maps/",
                 is_default="map" not in explicit)
    return dataclasses.replace(cfg, map=str(map_path))


def _apply_overrides(data: Any, overrides: Mapping[str, object], label: str,
                     override_keys: set[str], cli_paths: set[str]) -> dict[str, Any]:
    """Return a deep-enough copy of ``data`` with dotted-key overrides set."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        return data  # the top-level error is reported by build
    result: dict[str, Any] = _copy_mappings(data)
    for key, value in overrides.items():
        parts = key.split(".") if isinstance(key, str) else []
        if not parts or not all(parts):
            raise InputError(f"command line: override key {_show(key)} = {_show(value)}: "
                             "expected a dotted key such as 'bvs.count'")
        node = result
        for i, part in enumerate(parts[:-1]):
            sub_path = ".".join(parts[: i + 1])
            child = node.get(part)
            if child is None:
                if part not in node:
                    cli_paths.add(sub_path)
                child = node[part] = {}
            elif not isinstance(child, dict):
                raise InputError(f"command line: key '{key}' = {_show(value)}: cannot set "
                                 f"inside '{sub_path}', which is {_show(child)} in {label}, "
                                 "not a mapping")
            node = child
        node[parts[-1]] = value
        override_keys.add(key)
        cli_paths.add(key)
    return result


def _copy_mappings(data: Mapping[Any, Any]) -> dict[Any, Any]:
    return {k: _copy_mappings(v) if isinstance(v, Mapping) else v for k, v in data.items()}

def load_scenario_config(path: str | Path | None = None,
                         overrides: Mapping[str, object] | None = None) -> ScenarioConfig:
    """Load, override and validate a scenario YAML file (None: the shipped default).

    ``overrides`` maps dotted keys to values (``{"bvs.count": 5, "bvs.mix": "3:4:3"}``); they
    are applied before validation and get the same checks. Text values for non-text keys are
    read as YAML scalars (``"200"`` -> 200), as a command line would give them.
    """
    file_path = share_path(_DEFAULT_CONFIG) if path is None else Path(path)
    label = str(path) if path is not None else str(file_path)
    text = read_text_limited(file_path, label, "scenario config file", MAX_CONFIG_BYTES)
    data, lines = parse_yaml(text, label)
    if not isinstance(data, Mapping):
        what = "an empty document" if data is None else f"{type(data).__name__} {_show(data)}"
        raise InputError(f"{label}: expected a mapping of scenario keys at top level, "
                         f"got {what}")
    return config_from_dict(data, source=label, base_dir=file_path.resolve().parent,
                            overrides=overrides, _lines=lines)


_FIELD_NAMES: dict[type, tuple[str, ...]] = {}
"""Each config dataclass's field names, in order (``dataclasses.fields`` builds them anew at every call)."""
_PLAIN_SCALARS = frozenset({str, int, float, bool, type(None)})


def config_to_dict(cfg: Any) -> dict[str, Any]:
    """Plain nested dict (str keys; int/float/str/bool/list values) of a config or section."""
    names = _FIELD_NAMES.get(type(cfg))
    if names is None:
        names = _FIELD_NAMES[type(cfg)] = tuple(f.name for f in dataclasses.fields(cfg))
    return {name: _plain(getattr(cfg, name)) for name in names}


def _plain(value: Any) -> Any:
    if type(value) in _PLAIN_SCALARS:  # most values: the checks below would leave them as they are
        return value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return config_to_dict(value)
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def dump_config(cfg: ScenarioConfig, path: str | Path) -> None:
    """Write ``cfg`` as YAML that :func:`load_scenario_config` reads back to an equal config."""
    text = yaml.safe_dump(config_to_dict(cfg), sort_keys=False, default_flow_style=None)
    Path(path).write_text(f"# evoscen scenario '{cfg.name}'\n{text}", encoding="utf-8")
