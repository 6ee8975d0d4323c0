"""Helpers for tests that drive a hand-built world (:func:`evoscen_sim.testing.hand_built_world`)
and score the run as the evaluator does, or score a run written down state by state (:func:`make_run`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from evoscen_contract import topics as T
from evoscen_sim.config import EvaluationConfig
from evoscen_sim.events import ExposureMonitor, step_events

from .metrics import evaluate
from .rundata import RunAccumulator, RunData


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
