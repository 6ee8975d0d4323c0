"""A BV node: hosts its share of the background vehicles and answers for them in one message per step.

    python -m evoscen_bv.bv_node --ros-args --params-file bv.yaml [-r __node:=evoscen_bv_<part>]

The scenario's ``bvs.nodes`` splits the BVs over BV nodes (:mod:`evoscen_sim.nodes.bv_nodes`;
docs/architecture.md §5, "BV nodes"): the node's name says which share it hosts — ``evoscen_bv``
(``single``: all BVs), ``evoscen_bv_competitive``, ``evoscen_bv_mutual``, ``evoscen_bv_cooperative``,
``evoscen_bv_level0``, … (``by_policy``), ``evoscen_bv_0`` … (a number) — given with ROS's node-name
remapping, the parameter file keyed by that name; it publishes on ``/evoscen/commands/bv_<part>``
(``/evoscen/commands/bv`` for ``single``). A name that is not one of the scenario's BV nodes is a
one-line error naming them (exit 2).

The driver is ``scenario.bvs.driver`` from the model registry (default: learned), built like the
driver of all BVs with the same seeded stream as in-process and cut to the node's share
(:func:`evoscen_sim.scenario_builders.build_bv_driver`), so the commands are the same bytes.
Parameters: ``scenario.*``, ``command_subscribers`` [[evoscen_sim, evoscen_eval]], ``startup_timeout_s`` [30],
``idle_timeout_s`` [60] (see :mod:`evoscen_sim.nodes.controller_node`).
"""

from __future__ import annotations

import sys

from evoscen_contract import topics as T
from evoscen_sim.nodes.bv_nodes import bv_node_of
from evoscen_sim.nodes.controller_node import run_controller
from evoscen_sim.scenario_builders import build_bv_driver


def _spec(cfg, name):
    return T.bv_command_spec(bv_node_of(cfg, name).name)


def _build(params, cfg, name):
    rows = bv_node_of(cfg, name).rows
    return build_bv_driver(cfg, rows), rows


def main(args: list[str] | None = None) -> int:
    """Entry point."""
    return run_controller(T.NODE_BV, _spec, _build, args)


if __name__ == "__main__":
    sys.exit(main())
