"""Building the road model's tables from a parsed OpenDRIVE map (:class:`evoscen_sim.road.road_model.RoadModel`).

The checks of the lane sections the road model supports, and the two tables it is built on: the lane
table on the s breakpoints (widths, presence, speed limits, lane offset) and each lane's extent.
"""

from __future__ import annotations

import math

import numpy as np

from evoscen_sim.errors import InputError
from evoscen_sim.road.opendrive import Lane, LaneSection, Poly3

#: Lane types the simulator can drive on; any other right-lane type is rejected.
DRIVABLE_LANE_TYPES = frozenset(["driving", "entry", "exit", "onRamp", "offRamp", "mwyEntry", "mwyExit"])


def last_at_or_before(starts: list[float], s: float) -> int:
    """Index of the last start <= s (-1 if none)."""
    idx = -1
    for i, v in enumerate(starts):
        if v <= s:
            idx = i
        else:
            break
    return idx


def lane_present(lane: Lane) -> bool:
    """Whether a lane has width anywhere in its section (a lane of constant zero width does not exist)."""
    return any(w.a != 0.0 or not w.is_constant for w in lane.widths)


def check_sections(fname: str, sections: tuple[LaneSection, ...]) -> None:
    """The lane sections the road model supports: right lanes only, each of a drivable type
    (:data:`DRIVABLE_LANE_TYPES`), linked between sections by the same id (InputError otherwise)."""
    for k, sec in enumerate(sections):
        if sec.left:
            raise InputError(
                f"{fname}:{sec.left[0].line}: <lane> id={sec.left[0].id} in <left> is not "
                "supported (expected only right lanes: the reference line is the left edge)"
            )
        if not sec.right:
            raise InputError(
                f"{fname}:{sec.line}: <laneSection> s={sec.s_m:g} has no right lanes "
                "(expected at least one driving lane)"
            )
        for lane in sec.right:
            if lane.type not in DRIVABLE_LANE_TYPES:
                raise InputError(
                    f"{fname}:{lane.line}: <lane> id={lane.id} attribute 'type'='{lane.type}' "
                    f"is not supported by the road model (expected one of: "
                    f"{', '.join(sorted(DRIVABLE_LANE_TYPES))})"
                )
            ids_prev = {l.id for l in sections[k - 1].right} if k > 0 else None
            ids_next = {l.id for l in sections[k + 1].right} if k + 1 < len(sections) else None
            for what, target, ids in (("predecessor", lane.predecessor_id, ids_prev),
                                      ("successor", lane.successor_id, ids_next)):
                if target is None or ids is None:
                    continue
                if target != lane.id or target not in ids:
                    raise InputError(
                        f"{fname}:{lane.line}: <lane> id={lane.id} has {what} id={target} "
                        f"(expected the same id {lane.id}, present in the "
                        f"{'previous' if what == 'predecessor' else 'next'} lane section: "
                        "renumbering lanes across sections is not supported)"
                    )


def lane_table(road, sections, sec_present, n: int, length_m: float):
    """The lane table on the s breakpoints (every section, width, speed, laneOffset and road-type
    start): ``(breaks, width coefficients, width origins, present, max speed, min speed, offset
    coefficients, offset origins)``, one row per breakpoint."""
    breaks = {0.0}
    for sec in sections:
        breaks.add(sec.s_m)
        for lane in sec.right:
            breaks.update(sec.s_m + w.s_m for w in lane.widths)
            breaks.update(sec.s_m + v.s_offset_m for v in lane.speeds)
    breaks.update(p.s_m for p in road.lane_offsets)
    breaks.update(t.s_m for t in road.types)
    br = np.array(sorted(b for b in breaks if b < length_m), dtype=float)
    m = len(br)
    w_coef = np.zeros((m, n, 4))
    w_origin = np.zeros((m, n))
    present = np.zeros((m, n), dtype=bool)
    vmax = np.full((m, n), np.nan)
    vmin = np.full((m, n), np.nan)
    off_coef = np.zeros((m, 4))
    off_origin = np.zeros(m)
    sec_starts = [sec.s_m for sec in sections]
    off_starts = [p.s_m for p in road.lane_offsets]
    type_starts = [t.s_m for t in road.types]
    for j, b in enumerate(br):
        sec = sections[last_at_or_before(sec_starts, b)]
        io = last_at_or_before(off_starts, b)
        if io >= 0:
            p = road.lane_offsets[io]
            off_coef[j] = (p.a, p.b, p.c, p.d)
            off_origin[j] = p.s_m
        it = last_at_or_before(type_starts, b)
        type_speed = math.inf
        if it >= 0 and road.types[it].speed is not None:
            type_speed = road.types[it].speed.max_mps  # type: ignore[union-attr]
        k_sec = sections.index(sec)
        for lane in sec.right:
            i = lane.id + n
            if not sec_present[k_sec][-lane.id - 1]:
                continue
            iw = last_at_or_before([sec.s_m + w.s_m for w in lane.widths], b)
            w = lane.widths[iw]
            w_coef[j, i] = (w.a, w.b, w.c, w.d)
            w_origin[j, i] = sec.s_m + w.s_m
            present[j, i] = True
            iv = last_at_or_before([sec.s_m + v.s_offset_m for v in lane.speeds], b)
            vmax[j, i] = lane.speeds[iv].max_mps if iv >= 0 else type_speed
            vmin[j, i] = lane.min_speed_mps if lane.min_speed_mps is not None else 0.0
    return br, w_coef, w_origin, present, vmax, vmin, off_coef, off_origin


def lane_extents(fname, road, sections, sec_present, n: int):
    """Each lane's ``(start, end, full-width end)`` arc lengths; a lane must exist somewhere, in one
    contiguous range of sections (InputError otherwise)."""
    start = np.full(n, np.nan)
    end = np.full(n, np.nan)
    full_end = np.full(n, np.nan)
    for i in range(n):
        lane_id = i - n
        ks = [k for k, sec in enumerate(sections)
              if len(sec.right) >= -lane_id and sec_present[k][-lane_id - 1]]
        if not ks:
            raise InputError(
                f"{fname}:{road.line}: lane id {lane_id} has zero width in every lane section "
                "(expected every lane id up to the widest section to exist somewhere)"
            )
        if ks != list(range(ks[0], ks[-1] + 1)):
            sec = sections[ks[0]]
            raise InputError(
                f"{fname}:{sec.line}: lane id {lane_id} exists in separate s ranges (sections "
                f"starting at {[sections[k].s_m for k in ks]}); expected one contiguous range"
            )
        start[i] = sections[ks[0]].s_m
        end[i] = sections[ks[-1]].end_s_m
        # records (abs start, poly) over the lane's range, then find where the taper begins
        recs: list[tuple[float, Poly3]] = []
        for k in ks:
            lane = sections[k].right[-lane_id - 1]
            recs.extend((sections[k].s_m + w.s_m, w) for w in lane.widths)
        fe = end[i]
        for s_abs, w in reversed(recs):
            if w.is_constant:
                break
            fe = s_abs
        full_end[i] = fe
    return start, end, full_end
