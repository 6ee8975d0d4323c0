"""The scenario configuration of a node, from its ROS 2 parameters (``scenario.*``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import sys
from collections.abc import Callable

from evoscen_contract import graph
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_INTERRUPTED
from evoscen_contract.graph import NodeParameterError

from .config import ScenarioConfig, config_from_dict, config_to_dict
from .errors import InputError


def scenario_from_node(params: Mapping[str, Any], node_name: str) -> ScenarioConfig:
    """The scenario configuration from the ``scenario`` parameters (validated)."""
    scenario = params.get("scenario")
    if not isinstance(scenario, Mapping):
        raise NodeParameterError(f"{node_name}: parameters 'scenario.*' missing: start the node with the "
                                 "parameter file written by scripts/run_scenario.py --mode graph")
    return config_from_dict(_prefix_keys(scenario), source=f"{node_name} parameter 'scenario'")


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

    Bad parameters (InputError, NodeParameterError) are one line ``error: ...`` and exit 2;
    Ctrl-C before the run is 130. After the run the process ends at once with its status,
    without middleware teardown (see :func:`evoscen_contract.graph.exit_now`).
    """
    graph.init(args)
    try:
        try:
            node = make()
        except (InputError, NodeParameterError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        graph.exit_now(node.run())
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    finally:
        graph.shutdown()
    return 0  # not reached: exit_now ends the process
