"""Build a runnable scenario (road, world, drivers) from a :class:`ScenarioConfig`.

Random streams: the scenario seed feeds one :class:`numpy.random.SeedSequence`, spawned
into independent child streams for the spawn layout, the world (re-entry draws), the BV
drivers and the SUT, so adding draws to one consumer never shifts another's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evoscen_sim.config import ScenarioConfig, mix_counts
from evoscen_sim.models import create_driver
from evoscen_sim.road import RoadModel, load_road
from evoscen_sim.scenario_params import (
    control_params_from_config,
    reentry_params_from_config,
    vehicle_params_from_config,
)
from evoscen_sim.spawn import spawn_layout
from evoscen_sim.world import World

POLICY_CODES = {"level0": 0, "mutual": 1, "competitive": 2, "cooperative": 3, "sut": 4, "nilsson": 5, "mobil": 6}
"""Policy codes of the world table (kept equal to ``evoscen_contract.topics.POLICY_CODES``)."""

SUT_INDEX = 0
"""The SUT is always vehicle 0 (id 0)."""


@dataclass
class Scenario:
    """A world plus the drivers that command it."""

    config: ScenarioConfig
    road: RoadModel
    world: World
    bv_driver: object
    """Driver of all BVs (``act(view) -> (throttle, lane_change)``), from the model registry."""
    sut: object
    """Driver of the SUT, from the model registry."""
    bv_indices: np.ndarray
    sut_index: int = SUT_INDEX

    def commands(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Ask every driver: ``(bv_throttle, bv_lane_change, sut_throttle, sut_lane_change)``."""
        bv_thr, bv_lc = self.bv_driver.act(self.world)
        sut_thr, sut_lc = self.sut.act(self.world)
        return bv_thr, bv_lc, sut_thr, sut_lc

    def step(self) -> tuple:
        """One lockstep cycle in-process: ask the drivers, then advance the world."""
        bv_thr, bv_lc, sut_thr, sut_lc = self.commands()
        return self.apply(bv_thr, bv_lc, sut_thr, sut_lc)

    def apply(self, bv_thr, bv_lc, sut_thr, sut_lc):  # noqa: ANN001, ANN201
        """Advance the world with the drivers' commands; returns the world's StepResult."""
        n = self.world.n
        throttle = np.empty(n)
        lane_change = np.empty(n, dtype=np.int64)
        throttle[self.bv_indices] = bv_thr
        lane_change[self.bv_indices] = bv_lc
        throttle[self.sut_index] = sut_thr[0]
        lane_change[self.sut_index] = sut_lc[0]
        return self.world.step(throttle, lane_change)


def bv_policy_codes(cfg: ScenarioConfig, rng: np.random.Generator) -> np.ndarray:
    """Policy code of each BV.

    With the level-0 driver every BV drives level-0 and is recorded as such (the policy
    mix takes effect with learned drivers). Otherwise the mix is split by
    :func:`mix_counts` and shuffled over the BVs with ``rng``.
    """
    n = cfg.bvs.count
    if cfg.bvs.driver == "level0":
        return np.full(n, POLICY_CODES["level0"], dtype=np.int64)
    codes = np.concatenate([np.full(k, POLICY_CODES[name], dtype=np.int64) for name, k in mix_counts(cfg).items()])
    return rng.permutation(codes)


def scenario_rngs(seed: int) -> dict[str, np.random.Generator]:
    """The scenario's independent random streams (the same in every runner and node)."""
    names = ("spawn", "world", "bv", "sut")
    return {name: np.random.default_rng(s) for name, s in zip(names, np.random.SeedSequence(seed).spawn(len(names)))}


def build_world(cfg: ScenarioConfig, road: RoadModel | None = None) -> World:
    """Road, spawn layout and world for ``cfg`` (what the simulation node owns)."""
    road = load_road(cfg.map) if road is None else road
    rngs = scenario_rngs(cfg.seed)
    vehicle = vehicle_params_from_config(cfg)
    initial = spawn_layout(
        road,
        bv_policies=bv_policy_codes(cfg, rngs["spawn"]),
        sut_policy=POLICY_CODES["sut"],
        sut_lane=cfg.sut.lane,
        sut_s_m=cfg.sut.s_m,
        sut_speed_mps=cfg.sut.speed_mps,
        ramp_vehicles=cfg.spawn.ramp_vehicles,
        mainline_gap_m=cfg.spawn.mainline_gap_m,
        speed_range_mps=tuple(cfg.spawn.speed_mps),
        jitter_m=cfg.spawn.jitter_m,
        vehicle_length_m=vehicle.length_m,
        rng=rngs["spawn"],
    )
    return World(
        road,
        initial,
        vehicle=vehicle,
        control=control_params_from_config(cfg),
        reentry=reentry_params_from_config(cfg),
        dt_s=cfg.dt_s,
        rng=rngs["world"],
    )


def bv_indices(cfg: ScenarioConfig) -> np.ndarray:
    """World indices of the BVs: 1..count (the SUT is 0)."""
    return np.arange(1, cfg.bvs.count + 1)


def build_bv_driver(cfg: ScenarioConfig):  # noqa: ANN201
    """The driver of all BVs (what the BV node hosts)."""
    return create_driver(cfg.bvs.driver, "bv", bv_indices(cfg), cfg, scenario_rngs(cfg.seed)["bv"])


def build_sut_driver(cfg: ScenarioConfig, model: str | None = None):  # noqa: ANN201
    """The SUT's driver, model ``cfg.sut.model`` unless ``model`` is given (what the SUT node hosts)."""
    return create_driver(model or cfg.sut.model, "sut", [SUT_INDEX], cfg, scenario_rngs(cfg.seed)["sut"])


def build_scenario(cfg: ScenarioConfig) -> Scenario:
    """Road, spawn layout, world and drivers for ``cfg`` (deterministic in ``cfg.seed``)."""
    world = build_world(cfg)
    return Scenario(config=cfg, road=world.road, world=world, bv_driver=build_bv_driver(cfg),
                    sut=build_sut_driver(cfg), bv_indices=bv_indices(cfg))
