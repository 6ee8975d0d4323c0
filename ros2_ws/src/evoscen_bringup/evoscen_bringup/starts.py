"""Shared episode starts: the warm-up and the set-up computed once for every run that begins alike.

Runs that differ only in the SUT model (an experiment's SUT variants on one seed: the intact
model and its mutants, the planners of a leaderboard) begin from the same state by design
(:func:`evoscen_sim.scenario_builders.warm_up`: the warm-up's drivers are the BVs' own and the
lane keeper on the SUT's vehicle, whatever the SUT model). A :class:`StartCache` builds that
state once — the road, the world after the warm-up (with its random stream) and the fresh BV
driver(s) — and hands every run a **deep copy** of it, so each run steps its own objects and gets
exactly what building it from scratch would give (docs/performance.md "Experiments"). The copy
is generic (:func:`copy.deepcopy` of the world and the drivers; only the road, whose arrays are
read-only, is shared): a field added to the world or to a driver is copied with the rest.

:func:`start_key` says which runs share a start: the resolved configuration without what picks
the SUT's driver (``sut.model`` and, unless the BVs or the warm-up use the same model, its
``models.<name>`` parameters).
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
from collections import OrderedDict
from pathlib import Path

from evoscen_sim.config.scenario_config import ScenarioConfig, config_to_dict
from evoscen_sim.road.road_model import RoadModel, load_road
from evoscen_sim.scenario_builders import WARMUP_SUT_MODEL, build_bv_driver, build_sut_driver, build_world, bv_indices

from evoscen_bringup.scenario import Scenario

CACHED_STARTS = 4
"""Starts a :class:`StartCache` keeps (least recently used dropped): a worker runs the variants of
one start together (:func:`evoscen_experiments.campaign.run_campaign`'s groups), so a few suffice; each
holds a world and its BV drivers (about 2 MB with the learned policies)."""


def start_key(cfg: ScenarioConfig, *, partitioned: bool = True) -> str:
    """A hash of what decides a run's start: ``cfg`` without ``sut.model`` and, when no other part of
    the start uses that model (``bvs.driver``, the warm-up's SUT driver), without its ``models.<name>``
    section; and whether the BVs are driven as their BV nodes (``partitioned``) or by one driver."""
    d = config_to_dict(cfg)
    sut = d["sut"].pop("model")
    if sut not in (cfg.bvs.driver, WARMUP_SUT_MODEL):
        d.get("models", {}).pop(sut, None)
    text = json.dumps({"config": d, "partitioned": partitioned}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _road_stamp(path: str) -> tuple:
    """What identifies a map file's contents here: its resolved path, size and modification time."""
    p = Path(path).resolve()
    st = os.stat(p)
    return (str(p), st.st_size, st.st_mtime_ns)


class StartCache:
    """Builds :class:`~evoscen_bringup.scenario.Scenario` objects from shared starts (see the module
    docstring); roads are loaded once per map file."""

    def __init__(self, size: int = CACHED_STARTS) -> None:
        self.size = size
        self._starts: OrderedDict[str, tuple] = OrderedDict()  # key -> (world, bv driver), never stepped
        self._roads: dict[tuple, RoadModel] = {}
        self.built = 0
        """Starts built (warm-ups run)."""
        self.reused = 0
        """Scenarios handed out from a start built before."""

    def road(self, path: str) -> RoadModel:
        """The road of map file ``path`` (loaded once while the file is unchanged)."""
        stamp = _road_stamp(path)
        road = self._roads.get(stamp)
        if road is None:
            road = self._roads[stamp] = load_road(path)
        return road

    def scenario(self, cfg: ScenarioConfig, *, partitioned: bool = True) -> Scenario:
        """A scenario for ``cfg``, equal to :func:`evoscen_bringup.scenario.build_scenario`'s (with
        ``partitioned=False``: the BVs driven by one driver of all BVs, as ``bvs.nodes: single``),
        its world and BV driver deep copies of the shared start, its SUT driver built fresh."""
        key = start_key(cfg, partitioned=partitioned)
        start = self._starts.get(key)
        if start is None:
            road = self.road(cfg.map)
            start = (build_world(cfg, road), _bv_driver(cfg, partitioned))
            self._starts[key] = start
            self.built += 1
            while len(self._starts) > self.size:
                self._starts.popitem(last=False)
        else:
            self._starts.move_to_end(key)
            self.reused += 1
        world, bv = start
        memo = {id(world.road): world.road}  # read-only arrays: shared, not copied
        world, bv = _copy_drivers(copy.deepcopy((world, bv), memo), memo, bv)
        return Scenario(config=cfg, road=world.road, world=world, bv_driver=bv, sut=build_sut_driver(cfg),
                        bv_indices=bv_indices(cfg))


def _copy_drivers(copied: tuple, memo: dict, bv) -> tuple:
    """``copied`` with every driver copy known to the model registry as its original is (model, role,
    vehicles: what :func:`evoscen_sim.model_registry.checked_answer` checks each answer against)."""
    from evoscen_sim.model_registry import _built, _remember

    def drivers(d):  # a driver and those it wraps (PartitionedDriver.parts, RowsOf.driver)
        if d is not None:
            yield d
            yield from drivers(getattr(d, "driver", None))
            for part in getattr(d, "parts", ()):
                yield from drivers(part[1])

    for orig in drivers(bv):
        what = _built(orig)
        if what is not None and id(orig) in memo:
            _remember(memo[id(orig)], what)
    return copied


def _bv_driver(cfg: ScenarioConfig, partitioned: bool):
    from evoscen_sim.nodes.bv_nodes import build_bv_drivers

    return build_bv_drivers(cfg) if partitioned else build_bv_driver(cfg)
