"""A runnable in-process scenario: the world plus the drivers that command it.

The builders live in :mod:`evoscen_sim.scenario_builders` (each node of the graph uses its part);
this module composes them for the in-process runner.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from evoscen_sim.config.scenario_config import ScenarioConfig
from evoscen_sim.model_registry import checked_answer, driver_identity, plugin_failure
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
        """Ask every driver: ``(bv_throttle, bv_lane_change, sut_throttle, sut_lane_change)``.

        A driver that raises is a :class:`~evoscen_sim.errors.PluginFault` naming it (one line)."""
        try:
            bv_answer = self.bv_driver.act(self.world)
        except Exception as exc:  # a model's failure is named in one line
            raise self._failure(exc, self.bv_driver, ("bv", self.config.bvs.driver)) from exc
        bv_thr, bv_lc = checked_answer(self.bv_driver, bv_answer)
        try:
            sut_answer = self.sut.act(self.world)
        except Exception as exc:
            raise self._failure(exc, self.sut, ("sut", self.config.sut.model)) from exc
        sut_thr, sut_lc = checked_answer(self.sut, sut_answer)
        return bv_thr, bv_lc, sut_thr, sut_lc

    def _failure(self, exc: Exception, driver: object, role_name: tuple[str, str]):
        role, name = role_name
        name, role = driver_identity(driver, (name, role))
        step = self.world.step_index
        return plugin_failure(exc, name, role, f"act() at step {step}", driver, step=step)

    def step(self) -> tuple:
        """One lockstep cycle in-process: ask the drivers, then advance the world; returns the world's
        StepResult. No events, no recording: a test's or a benchmark's step (a run, with its events,
        exposures and recording, is :class:`evoscen_sim.loop.step_loop.StepLoop`'s, whose in-process port
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


def start_overrides(start) -> dict[str, str]:
    """The configuration keys a start read from a file sets (:func:`build_scenario_from_start`): as many
    BVs as it has, none laid out on the merge lane (the spawn layout is not used)."""
    return {"bvs.count": str(len(start.ids) - 1), "spawn.ramp_vehicles": "0"}


def build_scenario_from_start(cfg: ScenarioConfig, start) -> Scenario:
    """A scenario whose world starts in ``start`` (an
    :class:`evoscen_eval.scenes.scenario_export.ImportedStart`: ``run_scenario.py --start-from``,
    docs/export.md "Starting evoscen from an exported scenario") instead of the spawn layout and the
    warm-up: each vehicle at its ``s``, ``d`` and heading in its lane, at its speed, with its length and
    width (a lane change under way is not carried over: the vehicle keeps the lane that holds its centre
    and its lane keeper steers it to that lane's centre); the SUT is vehicle 0. The BVs keep their recorded policy codes
    when ``bvs.driver`` is ``learned`` and the code is a learned one, else they get the scenario's
    (:func:`bv_policy_codes`). ``cfg`` must have ``bvs.count`` = the start's BVs (:func:`start_overrides`).
    """
    from evoscen_contract.contract import POLICY_CODES as CODES
    from evoscen_sim.traffic.scenario_params import reentry_params_from_config, traffic_params_from_config
    from evoscen_sim.physics.world import InitialState

    road = load_road_of(cfg)
    rngs = scenario_rngs(cfg.seed)
    policies = np.asarray(start.policies, dtype=np.int64).copy()
    drawn = bv_policy_codes(cfg, rngs["spawn"])
    learned = {CODES[n] for n in ("competitive", "mutual", "cooperative") if n in CODES}
    for i in range(1, len(policies)):
        if not (cfg.bvs.driver == "learned" and int(policies[i]) in learned):
            policies[i] = drawn[i - 1]
    policies[0] = CODES["sut"]
    initial = InitialState(ids=np.asarray(start.ids, dtype=np.int64), roles=np.asarray(start.roles, dtype=np.int64),
                           policies=policies, s_m=np.asarray(start.s_m, dtype=float),
                           lane=np.asarray(start.lane, dtype=np.int64),
                           speed_mps=np.asarray(start.speed_mps, dtype=float))
    world = World(road, initial, vehicle=cfg.vehicle, control=cfg.control, reentry=reentry_params_from_config(cfg),
                  dt_s=cfg.dt_s, rng=rngs["world"], traffic=traffic_params_from_config(cfg, road))
    world.length[:] = start.length_m
    world.width[:] = start.width_m
    world.d[:] = start.d_m
    world.psi[:] = start.heading_rel
    world.refresh()
    return Scenario(config=cfg, road=road, world=world, bv_driver=build_bv_drivers(cfg),
                    sut=build_sut_driver(cfg), bv_indices=bv_indices(cfg))


def load_road_of(cfg: ScenarioConfig) -> RoadModel:
    """The road of ``cfg``'s map."""
    from evoscen_sim.road.road_model import load_road

    return load_road(cfg.map)
