"""Collision detection: overlap of oriented bounding boxes (separating-axis test).

Boxes live in the road frame (``s`` along, ``d`` across, heading ``psi`` relative to the
road). On our road (curvature ≤ 1/2000 m⁻¹) the frame's distortion over a car length is
below a millimetre, so the test there equals the Cartesian one.

Broad phase: only pairs whose axis-aligned extents (of the rotated boxes) overlap in both
``s`` and ``d`` go to the exact test; in traffic without contact that is no pair at all.
"""

from __future__ import annotations

import numpy as np


def overlapping_pairs(
    s: np.ndarray, d: np.ndarray, psi: np.ndarray, length: np.ndarray, width: np.ndarray
) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, whose boxes overlap; shape ``(k, 2)``, sorted."""
    # broad phase: axis-aligned extents of the rotated boxes in (s, d)
    c, sn = np.abs(np.cos(psi)), np.abs(np.sin(psi))
    half_s = 0.5 * (length * c + width * sn)
    half_d = 0.5 * (length * sn + width * c)
    near = (np.abs(s[None, :] - s[:, None]) < half_s[None, :] + half_s[:, None]) & (
        np.abs(d[None, :] - d[:, None]) < half_d[None, :] + half_d[:, None]
    )
    i, j = np.nonzero(near)
    keep = i < j
    if not keep.any():
        return np.empty((0, 2), dtype=np.int64)
    i, j = i[keep], j[keep]
    hit = boxes_overlap(
        s[i], d[i], psi[i], length[i], width[i], s[j], d[j], psi[j], length[j], width[j]
    )
    return np.stack([i[hit], j[hit]], axis=1)


def boxes_overlap(s1, d1, psi1, l1, w1, s2, d2, psi2, l2, w2) -> np.ndarray:  # noqa: ANN001
    """Separating-axis test for arrays of box pairs; touching edges do not count."""
    c1, sn1 = np.cos(psi1), np.sin(psi1)
    c2, sn2 = np.cos(psi2), np.sin(psi2)
    # the four candidate axes: each box's length and width directions
    axes = [(c1, sn1), (-sn1, c1), (c2, sn2), (-sn2, c2)]
    ts, td = s2 - s1, d2 - d1
    overlap = np.ones(np.shape(s1), dtype=bool)
    for ax_s, ax_d in axes:
        dist = np.abs(ts * ax_s + td * ax_d)
        r1 = 0.5 * l1 * np.abs(c1 * ax_s + sn1 * ax_d) + 0.5 * w1 * np.abs(-sn1 * ax_s + c1 * ax_d)
        r2 = 0.5 * l2 * np.abs(c2 * ax_s + sn2 * ax_d) + 0.5 * w2 * np.abs(-sn2 * ax_s + c2 * ax_d)
        overlap &= dist < r1 + r2
    return overlap
