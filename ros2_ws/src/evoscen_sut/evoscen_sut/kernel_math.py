"""numpy's semantics for single floats inside compiled kernels (:mod:`evoscen_sim.jit`).

The lane-change kernels (:mod:`evoscen_sut.krauss_lane_change`, :mod:`evoscen_sut.mobil`,
:mod:`evoscen_sut.nilsson`) compute, one vehicle at a time, what the vectorised numpy form
computes over arrays. Python's ``min``/``max`` treat NaN differently from ``np.minimum`` /
``np.maximum``; these helpers keep numpy's results, so the kernels stay bit-identical to it.
"""

from __future__ import annotations

import numpy as np
from evoscen_sim.jit import kernel

FLOAT_MAX = float(np.finfo(np.float64).max)
"""The largest float64 (``np.nan_to_num``'s replacement for ``inf``)."""


@kernel
def _first_nan_or(a, b, value):
    """``a`` if it is NaN, else ``b`` if it is NaN, else ``value``: numpy's NaN propagation."""
    if np.isnan(a):
        return a
    if np.isnan(b):
        return b
    return value


@kernel
def minimum(a, b):
    """``np.minimum`` of two floats (NaN propagates, the first NaN wins)."""
    return _first_nan_or(a, b, min(a, b))


@kernel
def maximum(a, b):
    """``np.maximum`` of two floats (NaN propagates, the first NaN wins)."""
    return _first_nan_or(a, b, max(a, b))


@kernel
def nan_to_num(x):
    """``np.nan_to_num(x, nan=0.0)`` of one float."""
    if np.isnan(x):
        return 0.0
    if x == np.inf:
        return FLOAT_MAX
    if x == -np.inf:
        return -FLOAT_MAX
    return x


@kernel
def argmax(x):
    """``np.argmax`` of a 1-d float array (the first maximum; the first NaN if any)."""
    best = 0
    bv = x[0]
    if np.isnan(bv):
        return 0
    for q in range(1, x.shape[0]):
        if np.isnan(x[q]):
            return q
        if x[q] > bv:
            best = q
            bv = x[q]
    return best
