"""Helpers for tests that drive a hand-built world (:func:`evoscen_sim.testing.hand_built_world`)
and score the run as the evaluator does."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from evoscen_sim.config import EvaluationConfig
from evoscen_sim.events import ExposureMonitor, step_events

from .metrics import evaluate
from .rundata import RunAccumulator


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
