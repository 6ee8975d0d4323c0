"""Build a scenario's world and drivers from a :class:`ScenarioConfig` — the same in every runner.

Random streams: the scenario seed feeds one :class:`numpy.random.SeedSequence`, spawned
into independent child streams for the spawn layout, the world (re-entry draws), the BV
drivers and the SUT, so adding draws to one consumer never shifts another's, and each
node of the graph rebuilds exactly its own part (the simulation node the world, the BV
node the BV driver, the SUT node the SUT).
"""

from __future__ import annotations

import numpy as np
from evoscen_contract.contract import POLICY_CODES

from .config.scenario_config import ScenarioConfig, mix_counts
from .model_registry import checked_answer, create_driver, makeup_driver_factory, rehosted
from .physics.world import World
from .danger.challenge import OnsetProcess, Tilt, build_challenge
from .road.road_model import RoadModel, load_road
from .traffic.makeup import HIGHD, HighdMakeupParams, Makeup, draw_makeup, window_makeup
from .traffic.scenario_params import reentry_params_from_config, traffic_params_from_config
from .traffic.spawn import spawn_layout, window_layout, window_layout_makeup

SUT_INDEX = 0
"""The SUT is always vehicle 0 (id 0)."""


def bv_policy_codes(cfg: ScenarioConfig, rng: np.random.Generator) -> np.ndarray:
    """Policy code of each BV.

    A rule-based BV driver (level-0, Nilsson, MOBIL) drives every BV, which is recorded with
    that driver's code (a plug-in driver without a code of its own as level-0). The policy
    mix applies to the learned drivers (``bvs.driver: learned``): it is split by
    :func:`mix_counts` and shuffled over the BVs with ``rng``.
    """
    n = cfg.bvs.count
    if cfg.bvs.driver != "learned":
        return np.full(n, POLICY_CODES.get(cfg.bvs.driver, POLICY_CODES["level0"]), dtype=np.int64)
    codes = np.concatenate([np.full(k, POLICY_CODES[name], dtype=np.int64) for name, k in mix_counts(cfg).items()])
    return rng.permutation(codes)


def scenario_rngs(seed: int) -> dict[str, np.random.Generator]:
    """The scenario's independent random streams (the same in every runner and node)."""
    names = ("spawn", "world", "bv", "sut", "warmup_bv", "warmup_sut", "makeup", "challenge")  # (a new name goes last:
    # each child's seed depends on its position only, so the streams before it keep their draws)
    return {name: np.random.default_rng(s) for name, s in zip(names, np.random.SeedSequence(seed).spawn(len(names)))}


def highd_params(cfg: ScenarioConfig) -> HighdMakeupParams:
    """The ``models.highd`` parameter set of ``cfg`` (absent: its defaults)."""
    return cfg.models.get(HIGHD) or HighdMakeupParams()


def bv_makeup(cfg: ScenarioConfig) -> Makeup | None:
    """The BV slots' classes, bodies and desired speeds under ``bvs.makeup: highd`` (from the
    ``makeup`` stream: the same in the simulation node and every BV node); None for ``uniform``."""
    if cfg.bvs.makeup != HIGHD:
        return None
    return draw_makeup(cfg.bvs.count, highd_params(cfg), cfg.vehicle.width_m, scenario_rngs(cfg.seed)["makeup"])


def build_world(cfg: ScenarioConfig, road: RoadModel | None = None) -> World:
    """Road, spawn layout and world for ``cfg`` (what the simulation node owns), after the warm-up; with
    ``challenge.mode`` other than ``none`` its challenge layer set from then on (docs/challenges.md)."""
    world = _build_world(cfg, road)
    ch = cfg.challenge
    if ch.mode != "none":
        learned, truck = _params(cfg, "learned"), _params(cfg, "truck")
        process = OnsetProcess(float(learned.hard_brake_per_1000km),
                               (float(learned.hard_brake_decel_min_mps2), float(learned.hard_brake_decel_max_mps2)),
                               (float(learned.hard_brake_duration_min_s), float(learned.hard_brake_duration_max_s)),
                               float(learned.hard_brake_min_speed_mps))
        world.challenge = build_challenge(ch.mode, Tilt(ch.max_multiplier, ch.headway_full_s, ch.headway_none_s),
                                          process, world, scenario_rngs(cfg.seed)["challenge"],
                                          float(truck.max_decel_mps2))
    return world


def _params(cfg: ScenarioConfig, name: str):
    """The ``models.<name>`` parameter set of ``cfg`` (absent: the model's defaults)."""
    from .model_registry import params_type_of

    params = cfg.models.get(name)
    return params if params is not None else params_type_of(name)()


def _build_world(cfg: ScenarioConfig, road: RoadModel | None) -> World:
    road = load_road(cfg.map) if road is None else road
    rngs = scenario_rngs(cfg.seed)
    vehicle = cfg.vehicle
    traffic = traffic_params_from_config(cfg, road)
    makeup = bv_makeup(cfg)
    if traffic is not None and makeup is not None:
        entries = window_makeup(makeup, highd_params(cfg))  # (the spawn reads the same lane rules)
        initial = window_layout_makeup(
            road, traffic, makeup, entries.truck_entry_lanes, cars_by_speed=entries.cars_by_speed,
            bv_policies=bv_policy_codes(cfg, rngs["spawn"]),
            sut_policy=POLICY_CODES["sut"], sut_lane=cfg.sut.lane, sut_s_m=cfg.sut.s_m,
            sut_speed_mps=cfg.sut.speed_mps, sut_length_m=vehicle.length_m, sut_width_m=vehicle.width_m,
            rng=rngs["spawn"])
        world = World(road, initial, vehicle=vehicle, control=cfg.control,
                      reentry=reentry_params_from_config(cfg), dt_s=cfg.dt_s, rng=rngs["world"], traffic=traffic,
                      makeup=entries)
        warm_up(world, cfg, int(round(traffic.warmup_s / cfg.dt_s)))
        return world
    if traffic is not None:
        initial = window_layout(
            road, traffic, bv_policies=bv_policy_codes(cfg, rngs["spawn"]), sut_policy=POLICY_CODES["sut"],
            sut_lane=cfg.sut.lane, sut_s_m=cfg.sut.s_m, sut_speed_mps=cfg.sut.speed_mps,
            vehicle_length_m=vehicle.length_m, rng=rngs["spawn"])
        world = World(road, initial, vehicle=vehicle, control=cfg.control,
                      reentry=reentry_params_from_config(cfg), dt_s=cfg.dt_s, rng=rngs["world"], traffic=traffic)
        warm_up(world, cfg, int(round(traffic.warmup_s / cfg.dt_s)))
        return world
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
        control=cfg.control,
        reentry=reentry_params_from_config(cfg),
        dt_s=cfg.dt_s,
        rng=rngs["world"],
    )


WARMUP_SUT_MODEL = "level0"
"""Who drives the SUT's vehicle during the warm-up: the lane keeper, the same for every SUT model."""


def warm_up(world: World, cfg: ScenarioConfig, steps: int) -> None:
    """Let the traffic evolve ``steps`` steps around the SUT's start before step 0 (``traffic.warmup_s``).

    The BVs drive with drivers of their own (``bvs.driver``, from the ``warmup_bv`` stream), the
    SUT's vehicle with :data:`WARMUP_SUT_MODEL` (``warmup_sut`` stream); after every step every
    vehicle is moved back by the SUT's advance, so the SUT stays at ``sut.s_m`` (the road is uniform
    around it: checked with the shift points) while the window's exits and entries go on. Then the
    clock is set back to 0 (lane changes in progress keep their elapsed time) and the drivers are
    dropped: the run's drivers start fresh on this state, in every runner and node alike, whatever
    the SUT model — so SUT variants on the same seed meet the same start.
    """
    if steps <= 0 or world.window is None:
        return
    rngs = scenario_rngs(cfg.seed)
    bvs = bv_indices(cfg)
    bv_driver = make_bv_driver(cfg, bvs, rngs["warmup_bv"]) if bvs.size else None
    sut_driver = create_driver(WARMUP_SUT_MODEL, "sut", [SUT_INDEX], cfg, rngs["warmup_sut"])
    s_hold = float(world.s[SUT_INDEX])
    throttle = np.zeros(world.n)
    lane_change = np.zeros(world.n, dtype=np.int64)
    for _ in range(steps):
        if bv_driver is not None:
            thr, lc = checked_answer(bv_driver, bv_driver.act(world))
            throttle[bvs], lane_change[bvs] = thr, lc
        thr, lc = checked_answer(sut_driver, sut_driver.act(world))
        throttle[SUT_INDEX], lane_change[SUT_INDEX] = thr[0], lc[0]
        world.step(throttle, lane_change)
        world.window.hold(world, s_hold)
        world.refresh()
    world.restart_clock()


def bv_indices(cfg: ScenarioConfig) -> np.ndarray:
    """World indices of the BVs: 1..count (the SUT is 0)."""
    return np.arange(1, cfg.bvs.count + 1)


def make_bv_driver(cfg: ScenarioConfig, bvs: np.ndarray, rng: np.random.Generator):
    """The driver of all BVs ``bvs``: ``bvs.driver`` built from ``rng``; under ``bvs.makeup: highd`` its cars
    keep it with their drawn desired speeds, not capped at the lane's limit, and its trucks get the truck
    driver (:func:`evoscen_sim.model_registry.create_driver` of ``truck``: docs/bv-profiles.md)."""
    driver = create_driver(cfg.bvs.driver, "bv", bvs, cfg, rng)
    makeup = bv_makeup(cfg)
    if makeup is None:
        return driver
    return makeup_driver_factory(cfg.bvs.makeup)(bvs, makeup, cfg, driver)


def build_bv_driver(cfg: ScenarioConfig, rows: np.ndarray | None = None):
    """The driver of the BVs at world indices ``rows`` (default: all BVs; what one BV node hosts).

    It is built for all BVs from the ``bv`` stream, then keeps only ``rows``
    (docs/architecture.md §5, "BV nodes"), so every vehicle draws what it draws in the driver of
    all BVs and the world does not depend on ``bvs.nodes``: a driver with a ``restrict(positions)``
    method (the built-in BV drivers) keeps their state only; any other (a plug-in) is run for all
    BVs and its answer cut to ``rows`` (:class:`RowsOf`) — exact whatever it draws per step.
    """
    bvs = bv_indices(cfg)
    driver = make_bv_driver(cfg, bvs, scenario_rngs(cfg.seed)["bv"])
    if rows is None or np.array_equal(rows, bvs):
        return driver
    positions = np.searchsorted(bvs, np.asarray(rows, dtype=np.int64))
    if positions.size == 0:
        return NoVehicles()
    if hasattr(driver, "restrict"):
        driver.restrict(positions)
        rehosted(driver, positions.size)  # its answers are checked against its share
        return driver
    return RowsOf(driver, positions)


class RowsOf:
    """A driver of all BVs whose answer is cut to the BVs at ``positions`` (see :func:`build_bv_driver`)."""

    def __init__(self, driver, positions: np.ndarray) -> None:
        self.driver, self.positions = driver, positions
        self.vehicles = np.asarray(driver.vehicles)[positions] if hasattr(driver, "vehicles") else None

    def act(self, view) -> tuple[np.ndarray, np.ndarray]:
        throttle, lane_change = self.driver.act(view)
        return np.asarray(throttle)[self.positions], np.asarray(lane_change)[self.positions]


class NoVehicles:
    """The driver of a BV node without BVs (``bvs.nodes`` larger than ``bvs.count``): empty answers."""

    vehicles = np.zeros(0, dtype=np.int64)

    def act(self, view) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(0), np.zeros(0, dtype=np.int64)


def build_sut_driver(cfg: ScenarioConfig, model: str | None = None):
    """The SUT's driver, model ``cfg.sut.model`` unless ``model`` is given (what the SUT node hosts)."""
    return create_driver(model or cfg.sut.model, "sut", [SUT_INDEX], cfg, scenario_rngs(cfg.seed)["sut"])


