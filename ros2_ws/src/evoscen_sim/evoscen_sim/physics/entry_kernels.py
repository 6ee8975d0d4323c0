"""The compiled parts of a traffic-window entry (:meth:`evoscen_sim.physics.window.TrafficWindow._enter`): the lanes
to try and their order (:func:`_entry_rows`), the entry speeds and points (:func:`_entry_place`), the safe-insertion
rule's placement in a lane (:func:`_place_in_lane`, :func:`_place_first`) and the lane counts and speeds they read
(docs/method.md, the traffic window; docs/performance.md "Per-step work of the world and of the BV drivers")."""

from __future__ import annotations

import math

import numpy as np

from evoscen_sim.jit import kernel
from evoscen_sim.road.road_kernels import BorderTables, lane_borders, lane_present
from evoscen_sim.road.road_model import MERGE_LANE


@kernel
def _lane_mean_speeds(s, v, lane, target_lane, lane_change, lo, hi, num_lanes):
    """Mean speed of the vehicles with ``lo <= s <= hi`` in each lane, the SUT included (the target lane
    while changing lanes; NaN for a lane with none)."""
    total = np.zeros(num_lanes)
    counts = np.zeros(num_lanes, dtype=np.int64)
    for j in range(s.shape[0]):
        if lo <= s[j] <= hi:
            k = target_lane[j] if lane_change[j] != 0 else lane[j]
            if 0 <= k < num_lanes:
                total[k] += v[j]
                counts[k] += 1
    out = np.full(num_lanes, np.nan)
    for k in range(num_lanes):
        if counts[k] > 0:
            out[k] = total[k] / counts[k]
    return out


def _np_clip(x: float, lo: float, hi: float) -> float:
    """``np.clip`` of one float, as numpy computes it (``max`` then ``min``, NaN propagated, of equals ``x``)."""
    if x != x:
        return x
    x = x if x >= lo else lo
    if x != x:
        return x
    return x if x <= hi else hi


@kernel
def _lane_counts(s, lane, target_lane, lane_change, sut, lo, hi, num_lanes):
    """Vehicles but the SUT with ``lo <= s <= hi`` in each lane (the target lane while changing lanes)."""
    counts = np.zeros(num_lanes, dtype=np.int64)
    for j in range(s.shape[0]):
        if j == sut or not (s[j] >= lo and s[j] <= hi):
            continue
        k = target_lane[j] if lane_change[j] != 0 else lane[j]
        if 0 <= k < num_lanes:
            counts[k] += 1
    return counts


@kernel
def _required_gap(v_back, v_front, g0, tau, b):
    """The required gap (:func:`required_gap`; ``max(0.0, x)`` as Python's)."""
    x = (v_back * v_back - v_front * v_front) / (2.0 * b)
    return g0 + v_back * tau + (x if x > 0.0 else 0.0)


@kernel
def _py_min(a, b):
    """Python's ``min(a, b)``: ``b`` only when ``b < a``."""
    return b if b < a else a


@kernel
def _insertion_speed(v_wish, gap_m, v_leader, g0, tau, b, b_tau_sq):
    """The insertion speed (:func:`insertion_speed`; ``b_tau_sq`` = ``(b·τ)**2``, computed by the caller:
    bit-identical to the traffic window's Python form before it was compiled, Python's ``min``)."""
    g = gap_m - g0
    if g < 0.0:
        return -np.inf
    if v_wish <= v_leader or _required_gap(v_wish, v_leader, g0, tau, b) <= gap_m:
        if _required_gap(v_wish, v_leader, g0, tau, b) <= gap_m:
            return v_wish
        return _py_min(v_wish, g / tau)
    v = -b * tau + math.sqrt(b_tau_sq + v_leader * v_leader + 2.0 * b * g)
    if v <= v_leader:
        v = _py_min(v_leader, g / tau)
    return _py_min(v_wish, v)


@kernel
def _follow_speed(v_back, gap_m, g0, tau, b):
    """The lowest speed of a leader ``gap_m`` ahead of a vehicle at ``v_back`` that it can follow
    (:func:`_required_gap` <= gap): ``sqrt(max(0, v_back² − 2b(gap − g0 − v_back·τ)))``; +inf when even a
    leader as fast as it is too close (gap < g0 + v_back·τ)."""
    slack = gap_m - g0 - v_back * tau
    if slack < 0.0:
        return np.inf
    x = v_back * v_back - 2.0 * b * slack
    return math.sqrt(x) if x > 0.0 else 0.0


@kernel
def _place_in_lane(s, d, v, length, width, lane_of, target_lane, i, lane, s_edge, s_sut, v_wish, v_floor,
                   half, band, g0, tau, b, b_tau_sq, tables, v_raise):
    """Where vehicle ``i`` (half length ``half``) drawn at ``v_wish`` may enter ``lane`` from the window's
    edge ``s_edge`` (module docstring, entries; docs/method.md §1): ``(found, s, speed)``.

    The positions tried: the edge, then the middle of the largest gap of the lane within ``band``
    inside the window from it (the merge lane: its start only). A position counts where the lane
    exists, the speed lowered to what the leader allows (:func:`insertion_speed`) is at least
    ``v_floor``, and the follower can follow (:func:`required_gap`). Leader and follower: the
    nearest vehicles ahead (``s`` >= the position) and behind whose lane or target lane is ``lane``
    or whose body reaches across the lane's borders there; of equals the lowest index.

    ``v_raise`` > the speed found: where the follower could not follow, the speed is raised to the lowest
    one it can follow (:func:`_follow_speed`) if that is at most ``v_raise`` and what the leader allows
    at ``v_raise``; 0: never raised (the uniform make-up; docs/bv-profiles.md, "Entries at the front edge").
    """
    n = s.shape[0]
    s_mid = s_edge
    n_pos = 1
    if lane != MERGE_LANE and not band <= 0.0:
        inward = -1.0 if s_edge > s_sut else 1.0
        far = s_edge + inward * band
        lo, hi = (far, s_edge) if far < s_edge else (s_edge, far)  # sorted((s_edge, far))
        buf = np.empty(n + 2)
        m = 0
        for j in range(n):
            if j != i and (lane_of[j] == lane or target_lane[j] == lane) and s[j] >= lo - 100.0 \
                    and s[j] <= hi + 100.0:
                buf[m] = s[j]
                m += 1
        buf[m] = lo - 1e9
        buf[m + 1] = hi + 1e9
        pts = np.sort(buf[:m + 2])
        for q in range(m + 2):  # np.clip(pts, lo, hi)
            x = pts[q]
            if x == x:
                x = x if x > lo else lo
                x = x if x < hi else hi
            pts[q] = x
        k = 0
        best = pts[1] - pts[0]
        for q in range(1, m + 1):  # np.argmax(np.diff(pts)): the first largest
            if pts[q + 1] - pts[q] > best:
                best = pts[q + 1] - pts[q]
                k = q
        s_mid = 0.5 * (pts[k] + pts[k + 1])
        if not abs(s_mid - s_edge) < 1e-9:
            n_pos = 2
    for t in range(n_pos):
        s_try = s_edge if t == 0 else s_mid
        if not lane_present(tables, lane, s_try):
            continue
        right, left = lane_borders(tables, lane, s_try)
        leader = -1
        follower = -1
        for j in range(n):
            if j == i:
                continue
            half_w = 0.5 * width[j]
            if not (lane_of[j] == lane or target_lane[j] == lane
                    or (d[j] + half_w > right and d[j] - half_w < left)):
                continue
            ds = s[j] - s_try
            if ds >= 0.0:
                if leader < 0 or s[j] < s[leader]:
                    leader = j
            elif ds < 0.0 and (follower < 0 or s[j] > s[follower]):
                follower = j
        v_try = v_wish
        v_top = v_raise
        if leader >= 0:
            gap = s[leader] - s_try - 0.5 * length[leader] - half
            v_try = _insertion_speed(v_try, gap, v[leader], g0, tau, b, b_tau_sq)
            if v_raise > v_try:
                v_top = _insertion_speed(v_raise, gap, v[leader], g0, tau, b, b_tau_sq)
        if follower >= 0:
            gap = s_try - s[follower] - 0.5 * length[follower] - half
            if gap < _required_gap(v[follower], v_try, g0, tau, b):
                v_need = _follow_speed(v[follower], gap, g0, tau, b) if v_raise > v_try else np.inf
                v_try = v_need if v_try < v_need <= v_top else -np.inf
        if v_try >= v_floor:
            return True, s_try, v_try
    return False, 0.0, 0.0


@kernel
def _entry_rows(s, v, lane, target_lane, lane_change, sut, s_sut, behind_m, ahead_m, num_lanes, row_lanes, row_density,
                row_mean, row_sd, ramp, ramp_density, ramp_start, ramp_end, ramp_mean, ramp_sd, merge_lane, allowed,
                by_speed, wish):
    """:meth:`TrafficWindow._targets` (of the lanes ``allowed``) and, with ``by_speed``, :func:`_by_speed` for the
    wish ``wish``: the lanes to try, most wanted first, and their entry speeds' (mean, sd). The same arithmetic,
    and the order of Python's stable sorts on the same keys: (deficit, lane), then (speed gap, row)."""
    lo, hi = s_sut - behind_m, s_sut + ahead_m
    counts = _lane_counts(s, lane, target_lane, lane_change, sut, lo, hi, num_lanes)
    m = row_lanes.shape[0] + 1
    deficit = np.empty(m)
    lanes = np.empty(m, dtype=np.int64)
    mean = np.empty(m)
    sd = np.empty(m)
    r = 0
    length_km = (hi - lo) / 1000.0
    for q in range(row_lanes.shape[0]):
        target = row_density[q] * length_km
        if target <= 0.0:
            continue
        deficit[r] = (counts[row_lanes[q]] - target) / target
        lanes[r], mean[r], sd[r] = row_lanes[q], row_mean[q], row_sd[q]
        r += 1
    if ramp:
        target = ramp_density * (min(ramp_end, hi) - ramp_start) / 1000.0
        if lo <= ramp_start <= hi and target > 0.0:  # (the start exactly at the front edge: no room yet)
            deficit[r] = (counts[merge_lane] - target) / target
            lanes[r], mean[r], sd[r] = merge_lane, ramp_mean, ramp_sd
            r += 1
    order = np.empty(r, dtype=np.int64)
    for a in range(r):  # a stable insertion sort by (deficit, lane)
        key = a
        b = a - 1
        while b >= 0 and (deficit[key] < deficit[order[b]]
                          or (deficit[key] == deficit[order[b]] and lanes[key] < lanes[order[b]])):
            order[b + 1] = order[b]
            b -= 1
        order[b + 1] = key
    kept = np.empty(r, dtype=np.int64)
    n = 0
    negative = 0
    for a in range(r):  # the allowed lanes; of them those below their target, if any
        if allowed[lanes[order[a]]]:
            kept[n] = order[a]
            n += 1
            if deficit[order[a]] < 0.0:
                negative += 1
    rows = np.empty(negative if negative else n, dtype=np.int64)
    w = 0
    for a in range(n):
        if negative == 0 or deficit[kept[a]] < 0.0:
            rows[w] = kept[a]
            w += 1
    if by_speed:
        speed = _lane_mean_speeds(s, v, lane, target_lane, lane_change, lo, hi, num_lanes)
        gap = np.empty(w)
        for a in range(w):
            vl = speed[lanes[rows[a]]]
            gap[a] = abs((mean[rows[a]] if np.isnan(vl) else vl) - wish)
        by = np.empty(w, dtype=np.int64)
        for a in range(w):  # stable by (gap, position)
            b = a - 1
            while b >= 0 and gap[a] < gap[by[b]]:
                by[b + 1] = by[b]
                b -= 1
            by[b + 1] = a
        rows = rows[by]
    out_lanes = np.empty(w, dtype=np.int64)
    out_mean = np.empty(w)
    out_sd = np.empty(w)
    for a in range(w):
        out_lanes[a], out_mean[a], out_sd[a] = lanes[rows[a]], mean[rows[a]], sd[rows[a]]
    return out_lanes, out_mean, out_sd


@kernel
def _entry_place(s, d, v, length, width, lane_of, target_lane, i, lanes, means, sds, draws, makeup, wish, v_sut, s_sut,
                 behind_m, ahead_m, ramp_start, half, merge_lane, raise_front, band, g0, tau, b, b_tau_sq, tables_t):
    """The rest of :meth:`TrafficWindow._enter`: each lane's entry speed (``uniform``: mean + sd × its standard
    normal ``draws[k]``, as the generator's ``normal(mean, sd)`` computes it, clipped to the mean
    ± 2 sd, as :func:`_np_clip`, no slower than the mean − 2 sd floor; ``highd``: the wish, at most the ramp's
    mean on the ramp), entry point and front-entry raise, then :func:`_place_first`."""
    n = lanes.shape[0]
    v_try = np.empty(n)
    v_floor = np.zeros(n)
    s_new = np.empty(n)
    v_raise = np.zeros(n)
    for k in range(n):
        mean, sd = means[k], sds[k]
        if not makeup:
            x = mean + sd * draws[k]  # rng.normal(mean, sd) of the standard normal draws[k]
            lo, hi = mean - 2.0 * sd, mean + 2.0 * sd
            if x == x:
                x = x if x >= lo else lo
                if x == x:
                    x = x if x <= hi else hi
            floor = mean - 2.0 * sd
            v_floor[k] = floor if floor > 0.0 else 0.0  # max(0.0, floor)
        else:
            x = wish
            if lanes[k] == merge_lane:  # min(x, mean)
                x = mean if mean < x else x
        v_try[k] = x
        if lanes[k] == merge_lane:
            s_new[k] = ramp_start + half
        elif x < v_sut:
            s_new[k] = s_sut + ahead_m
        else:
            s_new[k] = s_sut - behind_m
        if makeup and raise_front and s_new[k] > s_sut:
            v_raise[k] = v_sut
    return _place_first(s, d, v, length, width, lane_of, target_lane, i, lanes, s_new, s_sut, v_try, v_floor, half,
                        band, g0, tau, b, b_tau_sq, BorderTables(*tables_t), v_raise)


@kernel
def _place_first(s, d, v, length, width, lane_of, target_lane, i, lanes, s_edges, s_sut, v_wish, v_floor, half, band,
                 g0, tau, b, b_tau_sq, tables, v_raise):
    """:func:`_place_in_lane` for vehicle ``i`` in ``lanes[k]`` from ``s_edges[k]`` at ``v_wish[k]``, ``v_floor[k]``,
    ``v_raise[k]``, k = 0, 1, … until a lane has a place: ``(k, s, speed)``; ``(-1, 0, 0)`` when none has."""
    for k in range(lanes.shape[0]):
        found, s_try, v_try = _place_in_lane(s, d, v, length, width, lane_of, target_lane, i, lanes[k], s_edges[k],
                                             s_sut, v_wish[k], v_floor[k], half, band, g0, tau, b, b_tau_sq, tables,
                                             v_raise[k])
        if found:
            return k, s_try, v_try
    return -1, 0.0, 0.0
