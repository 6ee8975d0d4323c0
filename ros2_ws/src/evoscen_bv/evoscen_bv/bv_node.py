"""The BV node: hosts the background vehicles and answers for all of them in one message per step.

    python -m evoscen_bv.bv_node --ros-args --params-file bv.yaml   (or: ros2 run evoscen_bv bv_node ...)

The driver is ``scenario.bvs.driver`` from the model registry (default: learned), built for all
BVs with the same seeded stream as in-process, so the commands are the same bytes.
Parameters: ``scenario.*``, ``command_subscribers`` [[evoscen_sim, evoscen_eval]], ``startup_timeout_s`` [30],
``idle_timeout_s`` [60] (see :mod:`evoscen_sim.controller_node`).
"""

from __future__ import annotations

import sys

from evoscen_contract import topics as T
from evoscen_sim.controller_node import run_controller
from evoscen_sim.scenario import build_bv_driver, bv_indices


def _build(params, cfg):  # noqa: ANN001, ANN202
    return build_bv_driver(cfg), bv_indices(cfg)


def main(args: list[str] | None = None) -> int:
    """Entry point."""
    return run_controller(T.NODE_BV, T.COMMANDS_BV, _build, args)


if __name__ == "__main__":
    sys.exit(main())
