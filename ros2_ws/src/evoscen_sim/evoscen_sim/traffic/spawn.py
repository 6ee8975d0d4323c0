"""Initial placement of the SUT and the background vehicles (the scenario's spawn layout).

Layout, deterministic for a given generator:

* the SUT at ``sut_lane`` / ``sut_s_m`` with ``sut_speed_mps``;
* ``ramp_vehicles`` BVs on the merge lane (lane I), from its start, one every
  ``mainline_gap_m + length`` metres;
* the other BVs on the mainline lanes II–V in a block around the SUT: slots every
  ``mainline_gap_m + length`` metres along each lane, the lanes staggered by a quarter
  slot so no four vehicles stand side by side, filled nearest-to-the-SUT first (ties:
  behind before ahead, then the lower lane) — so the SUT starts in traffic;
* every BV gets a longitudinal jitter uniform in ``±jitter_m`` (limited so neighbours in a
  lane cannot overlap) and a speed uniform in ``speed_range_mps``.
"""

from __future__ import annotations

import numpy as np

from evoscen_sim.errors import InputError
from evoscen_sim.physics.world import ROLE_BV, ROLE_SUT, InitialState
from evoscen_sim.road.road_model import MERGE_LANE


def spawn_layout(
    road,
    *,
    bv_policies: np.ndarray,
    sut_policy: int,
    sut_lane: int,
    sut_s_m: float,
    sut_speed_mps: float,
    ramp_vehicles: int,
    mainline_gap_m: float,
    speed_range_mps: tuple[float, float],
    jitter_m: float,
    vehicle_length_m: float,
    rng: np.random.Generator,
) -> InitialState:
    """Initial state: vehicle 0 is the SUT (id 0), vehicles 1..N are the BVs (ids 1..N)."""
    n_bv = int(len(bv_policies))
    pitch = mainline_gap_m + vehicle_length_m
    jitter = min(jitter_m, max(0.0, 0.5 * mainline_gap_m - 0.5))
    mainline = road.mainline_lanes
    if not road.lane_exists(np.array([sut_lane]), np.array([sut_s_m]))[0]:
        raise InputError(f"spawn: sut.lane {sut_lane} does not exist at sut.s_m = {sut_s_m} m")

    s_list: list[float] = []
    lane_list: list[int] = []
    # ramp vehicles, front first
    start, end = float(road.lane_start_s[MERGE_LANE]), float(road.lane_end_s[MERGE_LANE])
    for j in range(ramp_vehicles):
        s = start + vehicle_length_m + j * pitch
        if s > end - 30.0:
            raise InputError(
                f"spawn: spawn.ramp_vehicles = {ramp_vehicles} do not fit on the merge lane "
                f"({end - start:.0f} m at a pitch of {pitch:.1f} m); allowed at most {j}"
            )
        s_list.append(s)
        lane_list.append(MERGE_LANE)
    # mainline block around the SUT
    n_main = n_bv - ramp_vehicles
    slots = []
    max_j = n_main + 1
    for lane in mainline:
        stagger = (lane - sut_lane) % 4 * 0.25 * pitch
        for j in range(-max_j, max_j + 1):
            s = sut_s_m + j * pitch + stagger
            if lane == sut_lane and j == 0:
                continue
            if s < 5.0 or s > road.length_m - 50.0:
                continue
            slots.append((abs(s - sut_s_m), 0 if s < sut_s_m else 1, lane, s))
    slots.sort()
    if len(slots) < n_main:
        raise InputError(f"spawn: {n_main} mainline vehicles do not fit at spawn.mainline_gap_m = {mainline_gap_m}")
    for _, _, lane, s in slots[:n_main]:
        s_list.append(s)
        lane_list.append(lane)
    s_bv = np.array(s_list, dtype=float) + rng.uniform(-jitter, jitter, size=n_bv)
    # the jitter must not move a ramp vehicle's centre before the merge lane starts
    s_bv[:ramp_vehicles] = np.maximum(s_bv[:ramp_vehicles], start + 0.5 * vehicle_length_m)
    v_bv = rng.uniform(speed_range_mps[0], speed_range_mps[1], size=n_bv)
    return InitialState(
        ids=np.arange(n_bv + 1, dtype=np.int64),
        roles=np.array([ROLE_SUT] + [ROLE_BV] * n_bv, dtype=np.int64),
        policies=np.concatenate([[sut_policy], np.asarray(bv_policies, dtype=np.int64)]).astype(np.int64),
        s_m=np.concatenate([[sut_s_m], s_bv]),
        lane=np.array([sut_lane] + lane_list, dtype=np.int64),
        speed_mps=np.concatenate([[sut_speed_mps], v_bv]),
    )


def window_layout(
    road,
    params,
    *,
    bv_policies: np.ndarray,
    sut_policy: int,
    sut_lane: int,
    sut_s_m: float,
    sut_speed_mps: float,
    vehicle_length_m: float,
    rng: np.random.Generator,
) -> InitialState:
    """Initial state of ``traffic.mode: window``: the BVs fill the traffic window at its densities.

    Each mainline lane gets its share of the BVs (largest remainder of ``lane_density_per_km``),
    evenly spaced over ``[sut_s_m - behind_m, sut_s_m + ahead_m]`` from a random offset, the
    SUT's lane leaving out the slot nearest the SUT; speeds are drawn from the lane's
    distribution (truncated at ±2 sd) and then, front to back in each lane, lowered where needed
    so that every vehicle follows its leader by the safe-insertion rule
    (:func:`evoscen_sim.physics.window.insertion_speed`; the SUT's speed is its own, so a BV that the SUT
    could not follow safely is moved one slot further back). The merge lane starts empty: it is
    fed when its start comes into the window.
    """
    from evoscen_sim.physics.window import insertion_speed, required_gap

    p = params
    n_bv = int(len(bv_policies))
    mainline, counts = _mainline_counts(road, p, n_bv, sut_lane, sut_s_m)
    lo, hi = sut_s_m - p.behind_m, sut_s_m + p.ahead_m
    s_list: list[float] = []
    lane_list: list[int] = []
    v_list: list[float] = []
    half = 0.5 * vehicle_length_m
    for j, lane in enumerate(mainline):
        n = int(counts[j])
        if n == 0:
            continue
        mean, sd = p.lane_speed_mps[j]
        slots_n = n + 1 if lane == sut_lane else n
        pitch = (hi - lo) / slots_n
        offset = rng.uniform(0.0, pitch)
        slots = lo + offset + pitch * np.arange(slots_n)
        if lane == sut_lane:  # the slot nearest the SUT is the SUT's
            slots = np.delete(slots, int(np.argmin(np.abs(slots - sut_s_m))))
        v = np.clip(rng.normal(mean, sd, size=n), mean - 2.0 * sd, mean + 2.0 * sd)
        # front to back: each vehicle follows its leader (the SUT counts in its lane)
        order = np.argsort(-slots)
        lead_s, lead_v = np.inf, 0.0
        for k in order:
            s = float(slots[k])
            if lane == sut_lane and lead_s > sut_s_m > s:
                gap = sut_s_m - s - 2.0 * half
                lead_s, lead_v = sut_s_m, sut_speed_mps
                v[k] = insertion_speed(float(v[k]), gap, lead_v, p)
            elif np.isfinite(lead_s):
                v[k] = insertion_speed(float(v[k]), lead_s - s - 2.0 * half, lead_v, p)
            if lane == sut_lane and s > sut_s_m:
                # the SUT must be able to follow the nearest BV ahead of it
                nxt = slots[slots > sut_s_m]
                if s == float(nxt.min()) and s - sut_s_m - 2.0 * half < required_gap(sut_speed_mps, float(v[k]), p):
                    # as fast as the SUT if its own leader allows it
                    raised = max(float(v[k]), sut_speed_mps)
                    v[k] = insertion_speed(raised, lead_s - s - 2.0 * half, lead_v, p) if np.isfinite(lead_s) else raised
            if not np.isfinite(v[k]) or v[k] < 0.0:
                v[k] = 0.0
            lead_s, lead_v = s, float(v[k])
        s_list.extend(float(x) for x in slots)
        lane_list.extend([lane] * n)
        v_list.extend(float(x) for x in v)
    return InitialState(
        ids=np.arange(n_bv + 1, dtype=np.int64),
        roles=np.array([ROLE_SUT] + [ROLE_BV] * n_bv, dtype=np.int64),
        policies=np.concatenate([[sut_policy], np.asarray(bv_policies, dtype=np.int64)]).astype(np.int64),
        s_m=np.concatenate([[sut_s_m], np.asarray(s_list, dtype=float)]),
        lane=np.array([sut_lane] + lane_list, dtype=np.int64),
        speed_mps=np.concatenate([[sut_speed_mps], np.asarray(v_list, dtype=float)]),
    )


def window_layout_makeup(
    road,
    params,
    makeup,  # evoscen_sim.traffic.makeup.Makeup
    truck_entry_lanes: int,
    *,
    cars_by_speed: bool = False,
    bv_policies: np.ndarray,
    sut_policy: int,
    sut_lane: int,
    sut_s_m: float,
    sut_speed_mps: float,
    sut_length_m: float,
    sut_width_m: float,
    rng: np.random.Generator,
) -> InitialState:
    """:func:`window_layout` for the ``highd`` make-up (docs/bv-profiles.md, "Traffic make-up").

    The same lanes, counts and slots (one ``uniform`` offset per lane), but each BV brings its own
    length and width, trucks take the slots of the rightmost ``truck_entry_lanes`` mainline lanes
    first (the other lanes only when those are full), then the cars — in index order, or with
    ``cars_by_speed`` slowest first, so that the lanes are sorted by speed from right to left
    (``models.highd.car_lanes``) —, and every BV starts at its own desired speed, lowered front to back
    by the safe-insertion rule over the gaps of the actual bodies.
    """
    from evoscen_sim.physics.window import insertion_speed, required_gap

    p = params
    n_bv = int(len(bv_policies))
    mainline, counts = _mainline_counts(road, p, n_bv, sut_lane, sut_s_m)
    # which BV goes to which lane: trucks to the right lanes first, then cars (each in index order)
    lane_of_slot = np.repeat(np.array(mainline[: len(counts)], dtype=np.int64), counts)
    right = np.isin(lane_of_slot, mainline[:truck_entry_lanes])
    slot_order = np.concatenate([np.flatnonzero(right), np.flatnonzero(~right)])
    cars = np.flatnonzero(~makeup.truck)
    if cars_by_speed:
        cars = cars[np.argsort(np.asarray(makeup.desired_speed_mps, dtype=float)[cars], kind="stable")]
    bv_order = np.concatenate([np.flatnonzero(makeup.truck), cars])
    lane_bv = np.empty(n_bv, dtype=np.int64)
    lane_bv[bv_order] = lane_of_slot[slot_order]
    length = np.asarray(makeup.length_m, dtype=float)
    lo, hi = sut_s_m - p.behind_m, sut_s_m + p.ahead_m
    s_bv = np.empty(n_bv)
    v_bv = np.empty(n_bv)
    half_sut = 0.5 * sut_length_m
    for lane in mainline:
        members = np.flatnonzero(lane_bv == lane)
        n = members.size
        if n == 0:
            continue
        slots_n = n + 1 if lane == sut_lane else n
        pitch = (hi - lo) / slots_n
        offset = rng.uniform(0.0, pitch)
        slots = lo + offset + pitch * np.arange(slots_n)
        if lane == sut_lane:
            slots = np.delete(slots, int(np.argmin(np.abs(slots - sut_s_m))))
        s_bv[members] = slots
        v = np.asarray(makeup.desired_speed_mps, dtype=float)[members].copy()
        half = 0.5 * length[members]
        order = np.argsort(-slots)
        lead_s, lead_v, lead_half = np.inf, 0.0, 0.0
        for k in order:
            s = float(slots[k])
            if lane == sut_lane and lead_s > sut_s_m > s:
                lead_s, lead_v, lead_half = sut_s_m, sut_speed_mps, half_sut
            if np.isfinite(lead_s):
                v[k] = insertion_speed(float(v[k]), lead_s - s - lead_half - half[k], lead_v, p)
            if lane == sut_lane and s > sut_s_m:
                nxt = slots[slots > sut_s_m]
                if s == float(nxt.min()) and s - sut_s_m - half[k] - half_sut < required_gap(
                        sut_speed_mps, float(v[k]), p):
                    raised = max(float(v[k]), sut_speed_mps)
                    v[k] = (insertion_speed(raised, lead_s - s - lead_half - half[k], lead_v, p)
                            if np.isfinite(lead_s) else raised)
            if not np.isfinite(v[k]) or v[k] < 0.0:
                v[k] = 0.0
            lead_s, lead_v, lead_half = s, float(v[k]), float(half[k])
        v_bv[members] = v
    return InitialState(
        ids=np.arange(n_bv + 1, dtype=np.int64),
        roles=np.array([ROLE_SUT] + [ROLE_BV] * n_bv, dtype=np.int64),
        policies=np.concatenate([[sut_policy], np.asarray(bv_policies, dtype=np.int64)]).astype(np.int64),
        s_m=np.concatenate([[sut_s_m], s_bv]),
        lane=np.concatenate([[sut_lane], lane_bv]).astype(np.int64),
        speed_mps=np.concatenate([[sut_speed_mps], v_bv]),
        length_m=np.concatenate([[sut_length_m], length]),
        width_m=np.concatenate([[sut_width_m], np.asarray(makeup.width_m, dtype=float)]),
    )


def _mainline_counts(road, p, n_bv: int, sut_lane: int, sut_s_m: float) -> tuple[list[int], np.ndarray]:
    """The window layouts' shared start: the SUT's lane checked, the mainline lanes, and the BVs split
    over them by ``traffic.lane_density_per_km`` (largest remainder)."""
    if not road.lane_exists(np.array([sut_lane]), np.array([sut_s_m]))[0]:
        raise InputError(f"spawn: sut.lane {sut_lane} does not exist at sut.s_m = {sut_s_m} m")
    mainline = road.mainline_lanes
    dens = np.asarray(p.lane_density_per_km, dtype=float)
    if n_bv and dens.sum() <= 0.0:
        raise InputError("traffic.lane_density_per_km: all zero, so the window cannot hold the BVs "
                         f"(bvs.count = {n_bv})")
    quota = n_bv * dens / dens.sum() if n_bv else np.zeros_like(dens)
    counts = np.floor(quota).astype(int)
    for j in np.argsort(-(quota - counts), kind="stable")[: n_bv - int(counts.sum())]:
        counts[j] += 1
    return mainline, counts
