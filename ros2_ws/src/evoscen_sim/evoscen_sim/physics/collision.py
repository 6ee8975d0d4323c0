"""Collision detection: overlap of oriented bounding boxes (separating-axis test).

Boxes live in the road frame (``s`` along, ``d`` across, heading ``psi`` relative to the
road). On our road (curvature ≤ 1/2000 m⁻¹) the frame's distortion over a car length is
below a millimetre, so the test there equals the Cartesian one.

Broad phase: only pairs whose axis-aligned extents (of the rotated boxes) overlap in both
``s`` and ``d`` go to the exact test; in traffic without contact that is no pair at all.
"""

from __future__ import annotations

import numpy as np

from evoscen_sim.jit import elementwise, kernel


def overlapping_pairs(
    s: np.ndarray, d: np.ndarray, psi: np.ndarray, length: np.ndarray, width: np.ndarray
) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, whose boxes overlap; shape ``(k, 2)``, sorted."""
    return _overlapping_pairs_kernel(s, d, psi, length, width)


def boxes_overlap(s1, d1, psi1, l1, w1, s2, d2, psi2, l2, w2) -> np.ndarray:
    """Separating-axis test for (arrays of) box pairs; touching edges do not count."""
    return _boxes_overlap_ufunc(s1, d1, psi1, l1, w1, s2, d2, psi2, l2, w2)


@kernel
def _sat(s1, d1, psi1, l1, w1, s2, d2, psi2, l2, w2):
    """Separating-axis test of two oriented boxes (centre, heading, length, width)."""
    c1, sn1 = np.cos(psi1), np.sin(psi1)
    c2, sn2 = np.cos(psi2), np.sin(psi2)
    ts, td = s2 - s1, d2 - d1
    # the four candidate axes: each box's length and width directions
    for k in range(4):
        if k == 0:
            ax_s, ax_d = c1, sn1
        elif k == 1:
            ax_s, ax_d = -sn1, c1
        elif k == 2:
            ax_s, ax_d = c2, sn2
        else:
            ax_s, ax_d = -sn2, c2
        dist = abs(ts * ax_s + td * ax_d)
        r1 = 0.5 * l1 * abs(c1 * ax_s + sn1 * ax_d) + 0.5 * w1 * abs(-sn1 * ax_s + c1 * ax_d)
        r2 = 0.5 * l2 * abs(c2 * ax_s + sn2 * ax_d) + 0.5 * w2 * abs(-sn2 * ax_s + c2 * ax_d)
        if dist >= r1 + r2:
            return False
    return True


@elementwise
def _boxes_overlap_ufunc(s1, d1, psi1, l1, w1, s2, d2, psi2, l2, w2):
    return _sat(s1, d1, psi1, l1, w1, s2, d2, psi2, l2, w2)


@kernel
def _overlapping_pairs_kernel(s, d, psi, length, width):
    n = s.shape[0]
    half_s = np.empty(n)
    half_d = np.empty(n)
    for i in range(n):
        c, sn = abs(np.cos(psi[i])), abs(np.sin(psi[i]))
        half_s[i] = 0.5 * (length[i] * c + width[i] * sn)
        half_d[i] = 0.5 * (length[i] * sn + width[i] * c)
    pairs = np.empty((0, 2), dtype=np.int64)
    found = []
    for i in range(n):
        for j in range(i + 1, n):
            # broad phase: the axis-aligned extents of the rotated boxes in (s, d)
            if abs(s[j] - s[i]) >= half_s[i] + half_s[j] or abs(d[j] - d[i]) >= half_d[i] + half_d[j]:
                continue
            if _sat(s[i], d[i], psi[i], length[i], width[i], s[j], d[j], psi[j], length[j], width[j]):
                found.append((i, j))
    if len(found) > 0:
        pairs = np.empty((len(found), 2), dtype=np.int64)
        for k in range(len(found)):
            pairs[k, 0] = found[k][0]
            pairs[k, 1] = found[k][1]
    return pairs
