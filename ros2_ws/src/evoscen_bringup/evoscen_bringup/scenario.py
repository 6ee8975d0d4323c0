"""A runnable in-process scenario: the world plus the drivers that command it.

The builders live in :mod:`evoscen_sim.scenario_builders` (each node of the graph uses its part);
this module composes them for the in-process runner.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from evoscen_sim.config.scenario_config import ScenarioConfig
from evoscen_sim.model_registry import checked_answer
from evoscen_sim.nodes.bv_nodes import build_bv_drivers
from evoscen_sim.physics.world import World
from evoscen_sim.road.road_model import RoadModel
from evoscen_sim.scenario_builders import (  # noqa: F401  (re-exported for users of this module)
    POLICY_CODES,
    SUT_INDEX,
    build_bv_driver,
    build_sut_driver,
    build_world,
    bv_indices,
    bv_policy_codes,
    scenario_rngs,
)


@dataclass
class Scenario:
    """A world plus the drivers that command it."""

    config: ScenarioConfig
    road: RoadModel
    world: World
    bv_driver: object
    """Driver of all BVs (``act(view) -> (throttle, lane_change)``), from the model registry: one
    driver per BV node of ``bvs.nodes`` (:func:`evoscen_sim.nodes.bv_nodes.build_bv_drivers`)."""
    sut: object
    """Driver of the SUT, from the model registry."""
    bv_indices: np.ndarray
    sut_index: int = SUT_INDEX

    def commands(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Ask every driver: ``(bv_throttle, bv_lane_change, sut_throttle, sut_lane_change)``."""
        bv_thr, bv_lc = checked_answer(self.bv_driver, self.bv_driver.act(self.world))
        sut_thr, sut_lc = checked_answer(self.sut, self.sut.act(self.world))
        return bv_thr, bv_lc, sut_thr, sut_lc

    def step(self) -> tuple:
        """One lockstep cycle in-process: ask the drivers, then advance the world; returns the world's
        StepResult. No events, no recording: a test's or a benchmark's step (a run, with its events,
        exposures and recording, is :class:`evoscen_sim.physics.step_loop.StepLoop`'s, whose in-process port
        asks :meth:`commands` and :meth:`assemble` likewise)."""
        bv_thr, bv_lc, sut_thr, sut_lc = self.commands()
        return self.apply(bv_thr, bv_lc, sut_thr, sut_lc)

    def apply(self, bv_thr, bv_lc, sut_thr, sut_lc):
        """Advance the world with the drivers' commands; returns the world's StepResult."""
        return self.world.step(*self.assemble(bv_thr, bv_lc, sut_thr, sut_lc))

    def assemble(self, bv_thr, bv_lc, sut_thr, sut_lc) -> tuple[np.ndarray, np.ndarray]:
        """The drivers' commands as one ``(throttle, lane_change)`` pair in world order."""
        n = self.world.n
        throttle = np.empty(n)
        lane_change = np.empty(n, dtype=np.int64)
        throttle[self.bv_indices] = bv_thr
        lane_change[self.bv_indices] = bv_lc
        throttle[self.sut_index] = sut_thr[0]
        lane_change[self.sut_index] = sut_lc[0]
        return throttle, lane_change


def build_scenario(cfg: ScenarioConfig, *, partitioned: bool = True) -> Scenario:
    """Road, spawn layout, world and drivers for ``cfg`` (deterministic in ``cfg.seed``).

    ``partitioned`` (default): the BVs are driven as the BV nodes of ``bvs.nodes`` drive them, one
    driver per node (what a recorded run records); else by one driver of all BVs, as ``bvs.nodes:
    single`` — the same world, events and scores (docs/architecture.md §5, "BV nodes") with the
    per-call cost paid once (docs/performance.md "Experiments")."""
    world = build_world(cfg)
    bv = build_bv_drivers(cfg) if partitioned else build_bv_driver(cfg)
    return Scenario(config=cfg, road=world.road, world=world, bv_driver=bv,
                    sut=build_sut_driver(cfg), bv_indices=bv_indices(cfg))
