"""Helpers for tests that drive a hand-built world (:func:`evoscen_sim.loop.hand_built.hand_built_world`)
and score the run as the evaluator does, or score a run written down state by state (:func:`make_run`,
and :func:`rear_run`: a SUT lane change in front of a faster vehicle)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from evoscen_contract import topics as T
from evoscen_sim.config.scenario_config import EvaluationConfig
from evoscen_sim.danger.events import ExposureMonitor, step_events

from evoscen_eval.scoring.metrics import evaluate
from evoscen_eval.scoring.rundata import RunAccumulator, RunData


def drive(world: Any, command: Callable[[int], tuple[Any, Any]], steps: int,
          ev: EvaluationConfig) -> tuple[dict, list]:
    """Run ``steps`` steps with ``command(k) -> (throttle, lane_change)``, recording the world and
    the events as the evaluator does; returns (the run's report under ``ev``, the live events)."""
    acc = RunAccumulator()
    monitor = ExposureMonitor(ev, world.role)
    live = monitor.observe(world)
    acc.add_events(live)
    for k in range(steps):
        acc.add_world_columns(world.columns(), world.time_ns)
        throttle, lane_change = command(k)
        result = world.step(np.asarray(throttle, dtype=float), np.asarray(lane_change, dtype=np.int64))
        events = step_events(world, result) + monitor.observe(world)
        live += events
        acc.add_events(events)
    acc.add_world_columns(world.columns(), world.time_ns)
    return evaluate(acc.run_data(), ev), live


def make_run(states: int, vehicles: int, events: list[dict] | None = None) -> RunData:
    """SUT = vehicle 0 at s = 1000 m, 30 m/s, lane 2; BVs 500 m ahead (out of view) unless moved.

    Every vehicle 4.8 m x 1.9 m; every other world column 0; steps of 0.1 s. A test moves the
    vehicles by writing ``run.columns``."""
    c = {f: np.zeros((states, vehicles)) for f in T.WORLD_FIELDS}
    c["id"][:] = np.arange(vehicles)
    c["role"][:, 0] = 1
    c["length"][:] = 4.8
    c["width"][:] = 1.9
    c["speed"][:] = 30.0
    c["lane"][:] = 2
    c["s"][:, 0] = 1000.0
    c["s"][:, 1:] = 1500.0 + 50.0 * np.arange(vehicles - 1)
    return RunData(time_s=np.arange(states) * 0.1, columns=c, ids=np.arange(vehicles), sut_index=0,
                   events=events or [], dt_s=0.1, complete=True)


def rear_run(states: int = 40) -> RunData:
    """SUT (vehicle 0) at s = 100 m, 25 m/s, lane 2 (d = 0) changing left into lane 3 (d = 3.5)
    over states 5..9 (d = 0.7, 1.4, ..., 3.5); vehicle 1 in lane 3 at s = 90 m, 30 m/s, d = 3.5
    all along. Bodies 4.8 x 1.9 m: vehicle 1 is in the SUT's path (|Δd| < 1.9) from state 7
    (d_sut = 2.1); gap 10 − 4.8 = 5.2 m, TTC = 5.2 / 5 = 1.04 s, DRAC = 5² / (2·5.2) = 2.4038 m/s²,
    PET = 5.2 / 30 = 0.17333 s. dt = 0.1 s."""
    c = {f: np.zeros((states, 2)) for f in T.WORLD_FIELDS}
    c["id"][:] = np.arange(2)
    c["role"][:, 0] = 1
    c["length"][:] = 4.8
    c["width"][:] = 1.9
    c["s"][:, 0], c["s"][:, 1] = 100.0, 90.0
    c["speed"][:, 0], c["speed"][:, 1] = 25.0, 30.0
    c["lane"][:, 0], c["lane"][:, 1] = 2, 3
    c["target_lane"][:] = c["lane"]
    c["d"][:, 1] = 3.5
    c["d"][5:10, 0] = 0.7 * np.arange(1, 6)
    c["d"][10:, 0] = 3.5
    c["lane_change"][5:10, 0] = 1
    c["target_lane"][5:, 0] = 3
    c["lane"][8:, 0] = 3  # centre over the line at state 8
    events = [{"name": T.EVENT_LANE_CHANGE, "step": 10, "time_s": 1.0, "ids": [0], "duration_s": 0.5,
               "kind": "completed"}]
    return RunData(time_s=np.arange(states) * 0.1, columns=c, ids=np.arange(2), sut_index=0,
                   events=events, dt_s=0.1, complete=True)
