"""Helpers for tests that run a model in the default scenario (the SUT models' tests).

``model_scenario(spec, params, role)`` builds the default scenario with a model as the SUT or
as every BV's driver; ``run_checked(sc, steps, driven)`` runs it, checking every lane-change
request of the ``driven`` vehicles, and returns the collisions and their completed changes;
``commands_digest(overrides, steps)`` fingerprints every command of a run (a change that must not
alter how the vehicles drive keeps it).
"""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np
from evoscen_sim.config.scenario_config import load_scenario_config
from evoscen_sim.errors import InputError
from evoscen_sim.model_registry import ModelSpec

from evoscen_bringup.scenario import Scenario, build_scenario


def model_scenario(spec: ModelSpec, params: Any, role: str, seed: int = 0) -> Scenario:
    """The default scenario (level-0 BVs) with model ``spec`` as the SUT (``role = "sut"``) or as
    every BV's driver (via the config once registered, else built with the model's factory)."""
    key = "sut.model" if role == "sut" else "bvs.driver"
    try:
        cfg = load_scenario_config(overrides={"bvs.driver": "level0", key: spec.name, "recording.enabled": False,
                                              "seed": seed})
        sc = build_scenario(cfg)
    except InputError:  # not registered yet: build the driver with the model's factory
        cfg = load_scenario_config(overrides={"recording.enabled": False, "seed": seed, "bvs.driver": "level0"})
        sc = build_scenario(cfg)
        rng = np.random.default_rng(seed + 1)
        if role == "sut":
            sc.sut = spec.factory(np.array([sc.sut_index]), params, cfg, rng)
        else:
            sc.bv_driver = spec.factory(sc.bv_indices, params, cfg, rng)
    return sc


def run_checked(sc: Scenario, steps: int, driven: np.ndarray) -> tuple[list, int]:
    """Run ``steps`` steps asserting that the ``driven`` vehicles request only −1, 0, +1, into
    lanes that exist and not while changing lanes; the collisions and the number of lane changes
    the driven vehicles completed."""
    w = sc.world
    collisions, changes = [], 0
    for _ in range(steps):
        bv_thr, bv_lc, sut_thr, sut_lc = sc.commands()
        req = np.empty(w.n, dtype=np.int64)
        req[sc.bv_indices] = bv_lc
        req[sc.sut_index] = sut_lc[0]
        assert set(np.unique(req[driven])) <= {-1, 0, 1}
        moving = driven[req[driven] != 0]
        assert np.all(w.road.lane_exists(w.lane[moving] + req[moving], w.s[moving])), "request to a non-existent lane"
        assert np.all(w.lane_change[moving] == 0), "request while changing lanes"
        r = sc.apply(bv_thr, bv_lc, sut_thr, sut_lc)
        collisions += r.collisions
        changes += sum(1 for c in r.lane_changes_completed if c[0] in set(driven.tolist()))
    return collisions, changes


def commands_digest(overrides: dict, steps: int) -> str:
    """SHA-256 of every BV and SUT command (throttle and lane change, as float64 bytes, BVs then SUT)
    of ``steps`` steps of the default scenario, seed 3, SUT ``mobil``, with ``overrides`` on top."""
    sc = build_scenario(load_scenario_config(None, {"seed": 3, "sut.model": "mobil", **overrides}))
    h = hashlib.sha256()
    for _ in range(steps):
        bt, bl, st, sl = sc.commands()
        for x in (bt, bl, st, sl):
            h.update(np.ascontiguousarray(np.asarray(x, dtype=np.float64)).tobytes())
        sc.apply(bt, bl, st, sl)
    return h.hexdigest()
