"""The compiled check of a driver's common answer (:func:`evoscen_sim.model_registry.checked_answer`)."""

from __future__ import annotations

import numpy as np

from evoscen_sim.jit import kernel


@kernel
def answer_fine(throttle, lane_change):
    """Whether ``throttle`` (float64) is all finite and ``lane_change`` (int64, same length) all in {-1, 0, 1};
    an empty pair is fine. Every element is looked at, in one pass each (what the numpy path of
    :func:`evoscen_sim.model_registry._fine` decides, at a fraction of its per-call cost)."""
    for k in range(throttle.shape[0]):
        if not np.isfinite(throttle[k]):
            return False
    for k in range(lane_change.shape[0]):  # noqa: SIM110 - compiled: no generator in all()
        if lane_change[k] < -1 or lane_change[k] > 1:
            return False
    return True
