"""A node's parameters: the scenario configuration (``scenario.*``) and the node's own.

Both are validated by :func:`evoscen_sim.config.config_load.build`, so a bad value is the one-line
error of a bad scenario key. The node's own parameters are a frozen dataclass per node whose
fields declare their checks (:mod:`evoscen_sim.config.config_checks`); :func:`own_parameters` names
the node's parameter file and the line of the value (or ``command line`` for ``-p``, or the
node when it got no file)::

    sim.yaml: key 'deadline_s' = -1.0: expected a number > 0 (node evoscen_sim, line 7)
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Mapping
from typing import Any

from evoscen_contract import graph
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_INTERRUPTED
from evoscen_contract.graph import NodeParameterError, parameter_sources

from evoscen_sim.config.config_checks import _Bad
from evoscen_sim.config.config_load import Context, build, parse_yaml
from evoscen_sim.limits import MAX_CONFIG_BYTES, read_text_limited
from evoscen_sim.config.scenario_config import ScenarioConfig, config_from_dict, config_to_dict
from evoscen_sim.errors import InputError, PluginFault


def scenario_from_node(params: Mapping[str, Any], node_name: str) -> ScenarioConfig:
    """The scenario configuration from the ``scenario`` parameters (validated)."""
    scenario = params.get("scenario")
    if not isinstance(scenario, Mapping):
        raise NodeParameterError(f"{node_name}: parameters 'scenario.*' missing: start the node with the "
                                 "parameter file written by scripts/run_scenario.py --mode graph")
    # the source names the parameter file that holds them (the last one given), as a node's own
    # parameters do; without one (parameters set in code, tests) the node
    files, _cli = parameter_sources(node_name)
    source = f"{files[-1]} (node {node_name}, scenario.*)" if files else f"{node_name} parameter 'scenario'"
    return config_from_dict(_prefix_keys(scenario), source=source)


class _NodeContext(Context):
    """:class:`Context` of a node's own parameters: the parameter file that holds a key and
    its line (parsed only for an error), ``command line`` for a ``-p`` value, else the node."""

    def __init__(self, node_name: str, files: list[str], cli_keys: set[str]) -> None:
        super().__init__(files[-1] if files else node_name, top_level="node parameters")
        self.node_name, self.files, self.cli_keys = node_name, files, cli_keys

    def _where(self, key: str) -> tuple[str, int | None]:
        """The last parameter file that sets ``key`` for this node, and the line."""
        found: tuple[str, int | None] = (self.label, None)
        for path in self.files:
            try:
                _doc, lines = parse_yaml(read_text_limited(path, path, "parameter file", MAX_CONFIG_BYTES),
                                         path, "parameter file")
            except (InputError, OSError):
                continue  # rcl read it; no line number then
            for dotted, line in lines.items():
                scope, _, rest = dotted.partition(".ros__parameters.")
                if rest == key and (scope.lstrip("/") == self.node_name or scope in ("/**", "**")):
                    found = (path, line)
        return found

    def _prefix(self, path: str) -> tuple[str, str]:
        key = path.split(".", 1)[0]
        if key in self.cli_keys:
            return "command line", f" (node {self.node_name})"
        if not self.files:
            return self.node_name, ""
        source, line = self._where(key)
        return source, f" (node {self.node_name}" + (f", line {line})" if line else ")")


def own_parameters(cls: type, params: Mapping[str, Any], node_name: str, **defaults: Any) -> Any:
    """The node's own parameters: dataclass ``cls`` validated from ``params`` (the node's
    parameters, :func:`evoscen_contract.graph.node_parameters`; keys that are not fields of
    ``cls``, such as ``scenario``, are not looked at) by :func:`config_load.build`.

    ``defaults`` replaces the defaults of some fields (e.g. the SUT node's ``model``, the
    scenario's ``sut.model``). A field left at a default that fails its own check is a
    required parameter: the error says ``(default)``. InputError (one line) otherwise.
    """
    files, cli_keys = graph.parameter_sources(node_name)
    ctx = _NodeContext(node_name, files, cli_keys)
    fields = dataclasses.fields(cls)
    raw = {f.name: params[f.name] for f in fields if f.name in params}
    explicit: set[str] = set()
    own = build(cls, raw, "", ctx, explicit)
    own = dataclasses.replace(own, **{k: v for k, v in defaults.items() if k not in explicit})
    for f in fields:
        if f.name not in explicit:
            try:
                f.metadata["check"](getattr(own, f.name))
            except _Bad as bad:
                ctx.fail(f.name, getattr(own, f.name), bad.expected, is_default=True)
    return own


def _prefix_keys(mapping: Mapping[str, Any]) -> dict[str, Any]:
    return {k: (_prefix_keys(v) if isinstance(v, Mapping) else v) for k, v in mapping.items()}




def scenario_parameters(cfg: ScenarioConfig) -> dict[str, Any]:
    """The ``scenario`` parameters of a node parameter file: the config as nested mappings.

    Empty mappings are left out (a ROS 2 parameter file cannot hold them; the keys then take
    their defaults, which an empty mapping means anyway).
    """
    def prune(value: Any) -> Any:
        if isinstance(value, Mapping):
            return {k: prune(v) for k, v in value.items() if not (isinstance(v, Mapping) and not v)}
        return value

    return prune(config_to_dict(cfg))


def run_node(make: Callable[[], object], args: list[str] | None) -> int:
    """``main`` of an evoscen node: ``make()`` builds it (after ``rclpy.init``), ``.run()`` runs it.

    Bad parameters (InputError, NodeParameterError) are one line ``error: ...`` and exit 2; a driver
    model that raises while the node is built (:class:`~evoscen_sim.errors.PluginFault`) one line and exit 3;
    Ctrl-C before the run is 130. The process ends at once with its status, without middleware
    teardown (see :func:`evoscen_contract.graph.exit_now`): also after bad parameters, whose node
    already holds a DDS participant — destroying it could hang under load (seen in CI: the one
    error line printed, then no exit within 60 s), and there is nothing to finish.
    """
    graph.init(args)
    try:
        try:
            node = make()
        except (InputError, NodeParameterError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            graph.exit_now(EXIT_BAD_INPUT)
        except PluginFault as exc:  # a driver model raised while built or warming up: a controller fault
            print(f"error: {exc}", file=sys.stderr)
            graph.exit_now(EXIT_FAULT)
        graph.exit_now(node.run())
    except KeyboardInterrupt:
        graph.exit_now(EXIT_INTERRUPTED)
    finally:
        graph.shutdown()  # only on an unexpected exception (a traceback follows)
    return 0  # not reached: exit_now ends the process
