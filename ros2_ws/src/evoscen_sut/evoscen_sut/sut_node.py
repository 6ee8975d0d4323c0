"""The SUT node: hosts one SUT model, chosen by parameter.

    python -m evoscen_sut.sut_node --ros-args --params-file sut.yaml [-p model:=mobil]

``model`` (default: ``scenario.sut.model``) names a model of the registry
(:mod:`evoscen_sim.model_registry`: built-ins and ``evoscen.sut`` entry points); an unknown name is a
one-line error listing the valid choices (exit 2). Other parameters: ``scenario.*``,
``command_subscribers`` [[evoscen_sim, evoscen_eval]], ``startup_timeout_s`` [30], ``idle_timeout_s`` [60].
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np
from evoscen_contract import topics as T
from evoscen_sim.config.config_checks import text
from evoscen_sim.model_registry import model_names
from evoscen_sim.nodes.controller_node import run_controller
from evoscen_sim.nodes.node_params import own_parameters
from evoscen_sim.scenario_builders import SUT_INDEX, build_sut_driver


@dataclass(frozen=True)
class SutParams:
    """The SUT node's own parameter beyond the controllers' (``ControllerParams``)."""

    model: str = text("", lambda: model_names("sut"))  # default: the scenario's sut.model


def _build(params, cfg, name):
    model = own_parameters(SutParams, params, T.NODE_SUT, model=cfg.sut.model).model
    return build_sut_driver(cfg, model), np.array([SUT_INDEX])


def main(args: list[str] | None = None) -> int:
    """Entry point."""
    return run_controller(T.NODE_SUT, T.COMMANDS_SUT, _build, args)


if __name__ == "__main__":
    sys.exit(main())
