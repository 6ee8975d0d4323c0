"""Compiled road queries: :class:`evoscen_sim.road.road_model.RoadModel`'s look-ups for one ``(lane, s)``
inside other numba kernels (:mod:`evoscen_sim.jit`), and the kernels behind its whole-array
:meth:`~evoscen_sim.road.road_model.RoadModel.lane_lookup` and :meth:`~evoscen_sim.road.road_model.RoadModel.frenet_to_cartesian`.

:meth:`RoadModel.kernel_tables() <evoscen_sim.road.road_model.RoadModel.kernel_tables>` gives the road's
per-``s`` lane tables as one :class:`RoadTables` (a named tuple, passed to a kernel as one
argument); the functions here read it. Each computes what the named ``RoadModel`` method
computes for one vehicle, with the same expressions in the same order (``fastmath`` off), so
the results are bit-identical. Conventions (lane indices, ``s`` clamped to the road, lanes that
run to the road end): :mod:`evoscen_sim.road.road_model` and docs/CONVENTIONS.md.

The lane table: row ``j`` holds the lanes from breakpoint ``breaks[j]`` up to the next one;
:func:`segment_index` finds the row of an ``s``. In that row lane ``l`` exists where
``present[j, l]``, has the speed limit ``max_speed_mps[j, l]``, and the width
``c0 + x (c1 + x (c2 + x c3))`` with ``c = width_coef[j, l]``, ``x = s − width_origin[j, l]``
(clipped at 0); the lane offset (``d`` of the reference line's lane border) is the same cubic
of ``offset_coef[j]``, ``offset_origin[j]``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from evoscen_sim.jit import kernel


class RoadTables(NamedTuple):
    """A road's lane tables for compiled kernels (:meth:`evoscen_sim.road.road_model.RoadModel.kernel_tables`;
    read-only arrays, ``m`` table rows, ``n`` lanes)."""

    breaks: np.ndarray
    """(m,) the rows' start ``s`` (m), ascending, the first 0."""
    present: np.ndarray
    """(m, n) bool: the lane exists in the row."""
    max_speed_mps: np.ndarray
    """(m, n) the lane's maximum speed in the row (m/s; NaN where the lane does not exist)."""
    lane_end_s: np.ndarray
    """(n,) ``RoadModel.lane_end_s``: where each lane ends (m)."""
    reaches_end: np.ndarray
    """(n,) bool: the lane runs to the end of the road."""
    length_m: float
    """The road's length (m)."""
    width_coef: np.ndarray
    """(m, n, 4) the cubic of each lane's width in the row."""
    width_origin: np.ndarray
    """(m, n) the ``s`` the width cubic is measured from (m)."""
    offset_coef: np.ndarray
    """(m, 4) the cubic of the lane offset in the row."""
    offset_origin: np.ndarray
    """(m,) the ``s`` the lane-offset cubic is measured from (m)."""


class BorderTables(NamedTuple):
    """A road's lane-border tables for compiled kernels (:meth:`evoscen_sim.road.road_model.RoadModel.border_tables`;
    read-only arrays, ``m`` table rows, ``n`` lanes): what :func:`lane_lookup_kernel` reads."""

    length_m: float
    breaks: np.ndarray
    """(m,) the rows' start ``s`` (m), ascending, the first 0."""
    seg_const: np.ndarray
    """(m,) bool: every width and the lane offset are constant in the row (borders tabulated)."""
    d_right: np.ndarray
    """(m, n) each lane's right border in a constant row (m)."""
    d_left: np.ndarray
    """(m, n) each lane's left border in a constant row (m)."""
    present: np.ndarray
    """(m, n) bool: the lane exists in the row."""
    width_coef: np.ndarray
    width_origin: np.ndarray
    offset_coef: np.ndarray
    offset_origin: np.ndarray


@kernel
def lane_present(bt, lane, s):
    """``RoadModel.lane_exists(lane, s)`` for one ``(lane, s)`` (``bt``: :class:`BorderTables`)."""
    if lane < 0 or lane >= bt.present.shape[1]:
        return False
    sc = min(max(s, 0.0), bt.length_m)
    return bt.present[np.searchsorted(bt.breaks, sc, side="right") - 1, lane]


@kernel
def lane_borders(bt, lane, s):
    """``(d_right, d_left)`` of ``lane`` (a valid index) at ``s``: the values ``RoadModel.lane_lookup``
    gives (:func:`lane_lookup_kernel`, same expressions in the same order; ``bt``: :class:`BorderTables`)."""
    nl = bt.present.shape[1]
    sc = min(max(s, 0.0), bt.length_m)
    j = np.searchsorted(bt.breaks, sc, side="right") - 1
    if bt.seg_const[j]:
        return bt.d_right[j, lane], bt.d_left[j, lane]
    x = sc - bt.offset_origin[j]
    c = bt.offset_coef[j]
    edge = c[0] + x * (c[1] + x * (c[2] + x * c[3]))
    d_left = edge
    for k in range(nl - 1, lane - 1, -1):  # from the reference line (left) to the right
        x = sc - bt.width_origin[j, k]
        c = bt.width_coef[j, k]
        d_left = edge
        edge -= max(c[0] + x * (c[1] + x * (c[2] + x * c[3])), 0.0)
    return edge, d_left


@kernel
def segment_index(road, s):
    """The lane-table row at ``s`` (clamped to ``[0, length_m]``): the last breakpoint ``<= s``."""
    sc = min(max(s, 0.0), road.length_m)
    return np.searchsorted(road.breaks, sc, side="right") - 1


@kernel
def lane_end_distance(road, lane, s):
    """``RoadModel.distance_to_lane_end(lane, s)`` (raw ``s``), with ``inf`` also for an invalid lane."""
    if lane < 0 or lane >= road.lane_end_s.shape[0]:
        return np.inf
    if road.reaches_end[lane]:
        return np.inf
    return road.lane_end_s[lane] - s


@kernel
def lane_center_d(road, lane, s):
    """``RoadModel.lane_center_d(lane, s)``: ``d`` of the lane's centre line (NaN for an invalid lane)."""
    nl = road.width_coef.shape[1]
    if lane < 0 or lane >= nl:
        return np.nan
    sc = min(max(s, 0.0), road.length_m)
    j = np.searchsorted(road.breaks, sc, side="right") - 1
    do = sc - road.offset_origin[j]
    oc = road.offset_coef[j]
    off = oc[0] + do * (oc[1] + do * (oc[2] + do * oc[3]))
    cs = 0.0
    w_lane = 0.0
    for q in range(nl - 1, lane - 1, -1):  # cs = the widths summed from the last lane down to `lane`
        c = road.width_coef[j, q]
        x = sc - road.width_origin[j, q]
        w = max(c[0] + x * (c[1] + x * (c[2] + x * c[3])), 0.0)
        cs = w if q == nl - 1 else cs + w
        w_lane = w
    d_right = off - cs
    d_left = d_right + w_lane
    return 0.5 * (d_right + d_left)


@kernel
def lane_lookup_kernel(s, d, length, breaks, seg_const, dr_table, dl_table, present, vmax,
                       w_coef, w_origin, off_coef, off_origin, g_s0, g_k):
    """:meth:`RoadModel.lane_lookup <evoscen_sim.road.road_model.RoadModel.lane_lookup>` for ``N`` vehicles
    at ``(s, d)``: every lane's borders, existence and maximum speed, the lane of ``d`` and the
    reference line's curvature (the fields of :class:`evoscen_sim.road.road_model.LaneLookup`)."""
    n = s.shape[0]
    nl = present.shape[1]
    d_right = np.empty((n, nl))
    d_left = np.empty((n, nl))
    here = np.empty((n, nl), dtype=np.bool_)
    vmax_here = np.empty((n, nl))
    lane = np.full(n, -1, dtype=np.int64)
    kappa = np.empty(n)
    widths = np.empty(nl)
    for i in range(n):
        sc = min(max(s[i], 0.0), length)
        j = np.searchsorted(breaks, sc, side="right") - 1
        if seg_const[j]:
            for k in range(nl):
                d_right[i, k] = dr_table[j, k]
                d_left[i, k] = dl_table[j, k]
        else:  # a lane whose width (or the lane offset) varies: evaluate the cubics
            for k in range(nl):
                x = sc - w_origin[j, k]
                c = w_coef[j, k]
                widths[k] = max(c[0] + x * (c[1] + x * (c[2] + x * c[3])), 0.0)
            x = sc - off_origin[j]
            c = off_coef[j]
            edge = c[0] + x * (c[1] + x * (c[2] + x * c[3]))
            for k in range(nl - 1, -1, -1):  # from the reference line (left) to the right
                d_left[i, k] = edge
                edge -= widths[k]
                d_right[i, k] = edge
        for k in range(nl):
            here[i, k] = present[j, k]
            vmax_here[i, k] = vmax[j, k]
        # lane of d: the lowest lane whose (dr, dl] holds d; the right road edge counts
        for k in range(nl):
            dr, dl = d_right[i, k], d_left[i, k]
            if here[i, k] and dl > dr and d[i] <= dl and (d[i] > dr or (d[i] >= dr and dr == d_right[i, 0])):
                lane[i] = k
                break
        g = np.searchsorted(g_s0, s[i], side="right") - 1
        kappa[i] = g_k[min(max(g, 0), g_s0.shape[0] - 1)]
    return d_right, d_left, here, vmax_here, lane, kappa


@kernel
def frenet_to_cartesian_kernel(s, d, g_s0, g_x0, g_y0, g_h0, g_k):
    """:meth:`RoadModel.frenet_to_cartesian <evoscen_sim.road.road_model.RoadModel.frenet_to_cartesian>`:
    ``(x, y, heading)`` of ``N`` points ``(s, d)`` on the planView pieces (start ``s``, ``x``,
    ``y``, heading and curvature per piece; the first/last piece continued beyond the road)."""
    n = s.shape[0]
    x = np.empty(n)
    y = np.empty(n)
    h = np.empty(n)
    last = g_s0.shape[0] - 1
    for i in range(n):
        j = min(max(np.searchsorted(g_s0, s[i], side="right") - 1, 0), last)
        ds = s[i] - g_s0[j]
        k, h0 = g_k[j], g_h0[j]
        half = 0.5 * k * ds
        chord = ds if half == 0.0 else ds * np.sin(half) / half  # = 2 sin(k ds / 2) / k; ds on a line
        h[i] = h0 + k * ds
        x[i] = g_x0[j] + chord * np.cos(h0 + half) - d[i] * np.sin(h[i])
        y[i] = g_y0[j] + chord * np.sin(h0 + half) + d[i] * np.cos(h[i])
    return x, y, h
