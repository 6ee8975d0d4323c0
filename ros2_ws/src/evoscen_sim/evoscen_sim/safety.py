"""The SUT's dangerous states (SPEC 5.1): one definition for the live events and the scores.

A state is **dangerous** when

* the SUT's time to collision with the vehicle ahead *in its path* is below
  ``evaluation.ttc_threshold_s`` [2 s], or
* the SUT's acceleration is below ``-evaluation.hard_brake_mps2`` [-6 m/s²].

**[choice]** "in its path": another vehicle whose body overlaps the SUT's laterally
(|d_j - d_sut| < (w_j + w_sut)/2 in road coordinates) and whose centre is ahead
(s_j > s_sut). The nearest such vehicle is the leader; TTC = bumper-to-bumper gap / closing
speed while closing, else infinite (:func:`evoscen_sim.neighbors.time_to_collision`). Lateral
overlap rather than lane membership makes a cut-in count from the moment the other body
enters the SUT's path, not when its centre crosses the lane line, and follows the SUT
through its own lane changes.

An **exposure** is a maximal run of consecutive dangerous states (events are counted, not
steps). The simulation node publishes an ``evoscen/exposure`` event when one starts; the
evaluator recomputes the same states from the recorded world table with the same functions,
so the live events and the scores cannot disagree.

Every function broadcasts over leading axes: one state (``[V]`` arrays) in the simulation,
a whole run (``[K, V]``) in the evaluator, with identical floating-point results.
"""

from __future__ import annotations

import numpy as np

from .jit import kernel
from .neighbors import time_to_collision


def sut_leader(s: np.ndarray, d: np.ndarray, length: np.ndarray, width: np.ndarray, sut: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Index and bumper-to-bumper gap of the vehicle ahead in the SUT's path.

    Args:
        s, d, length, width: ``[..., V]`` arrays of every vehicle (the SUT included).
        sut: the SUT's index on the last axis.

    Returns:
        ``(leader, gap)``, shape ``[...]``: the leader's index (-1 if none) and the gap (m;
        ``inf`` if none, negative if the bodies overlap longitudinally).
    """
    ds = s - s[..., sut:sut + 1]
    half_widths = 0.5 * (width + width[..., sut:sut + 1])
    in_path = (ds > 0.0) & (np.abs(d - d[..., sut:sut + 1]) < half_widths)
    in_path[..., sut] = False
    gaps = np.where(in_path, ds - 0.5 * (length + length[..., sut:sut + 1]), np.inf)
    leader = np.argmin(np.where(in_path, ds, np.inf), axis=-1)
    gap = np.take_along_axis(gaps, leader[..., None], axis=-1)[..., 0]
    leader = np.where(np.isfinite(gap), leader, -1)
    return leader, gap


def sut_ttc(s: np.ndarray, d: np.ndarray, speed: np.ndarray, length: np.ndarray, width: np.ndarray,
            sut: int) -> np.ndarray:
    """The SUT's time to collision with the vehicle ahead in its path (s; ``inf`` if none or opening)."""
    leader, gap = sut_leader(s, d, length, width, sut)
    lead_speed = np.take_along_axis(speed, np.maximum(leader, 0)[..., None], axis=-1)[..., 0]
    return time_to_collision(gap, speed[..., sut], np.where(leader >= 0, lead_speed, np.nan))


@kernel
def sut_leader_ttc_state(s: np.ndarray, d: np.ndarray, speed: np.ndarray, length: np.ndarray, width: np.ndarray,
                         sut: int) -> tuple[int, float]:
    """:func:`sut_leader`'s leader and :func:`sut_ttc` of ONE state (``[V]`` arrays), compiled.

    The simulation node observes every state (:class:`evoscen_sim.events.ExposureMonitor`):
    the broadcasting numpy definitions above cost ~50 µs per state for 21 vehicles, this
    ~2 µs. The same IEEE operations in the same order (fastmath off), the first of equal
    distances as ``argmin`` takes it, so the results are bit-identical (a test compares them
    on many states); the evaluator keeps the numpy definitions for whole runs.

    Returns:
        ``(leader, ttc)``: the leader's index (-1 if none) and the TTC (s; ``inf`` if none or
        opening).
    """
    s0, d0, w0, l0 = s[sut], d[sut], width[sut], length[sut]
    leader, best = -1, np.inf
    for j in range(s.shape[0]):
        ds = s[j] - s0
        if j != sut and ds > 0.0 and abs(d[j] - d0) < 0.5 * (width[j] + w0) and ds < best:
            leader, best = j, ds
    if leader < 0:
        return -1, np.inf
    gap = (s[leader] - s0) - 0.5 * (length[leader] + l0)
    if not np.isfinite(gap):
        return -1, np.inf
    closing = speed[sut] - speed[leader]
    if closing > 0.0:
        return leader, (gap if gap >= 0.0 else 0.0) / closing
    return leader, np.inf


def dangerous(ttc: np.ndarray, sut_accel: np.ndarray, ttc_threshold_s: float, hard_brake_mps2: float
              ) -> np.ndarray:
    """Whether each state is dangerous (see the module docstring)."""
    return (ttc < ttc_threshold_s) | (sut_accel < -hard_brake_mps2)


def exposure_runs(danger: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Maximal runs of ``True`` in a 1-D boolean array: ``(starts, ends)``, ``ends`` exclusive.

    A run still open at the end of the array ends at ``len(danger)``.
    """
    x = np.concatenate(([False], np.asarray(danger, dtype=bool), [False]))
    edges = np.flatnonzero(x[1:] != x[:-1])
    return edges[0::2], edges[1::2]
