"""The benchmark's one step-rate loop (:mod:`evoscen_experiments.bench`, :mod:`evoscen_experiments.bench_makeups`)."""

from __future__ import annotations

import time

INPROCESS_WARMUP = 300
"""Untimed steps before each timed in-process run (the compiled kernels loaded, the traffic settled)."""


def timed_runs(cfg, steps: int, repeats: int, warmup: int = INPROCESS_WARMUP):
    """``repeats`` timed runs of ``cfg`` (a fresh scenario each, ``warmup`` untimed steps first): their
    steps/s and the last run's scenario. The benchmark's one step-rate loop."""
    from evoscen_bringup.scenario import build_scenario

    rates, sc = [], None
    for _ in range(repeats):
        sc = build_scenario(cfg)
        for _ in range(warmup):
            sc.step()
        t0 = time.perf_counter()
        for _ in range(steps):
            sc.step()
        rates.append(steps / (time.perf_counter() - t0))
    return rates, sc
