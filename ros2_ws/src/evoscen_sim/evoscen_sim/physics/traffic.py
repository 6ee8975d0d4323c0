"""The traffic window: traffic that moves with the SUT for the whole run (docs/method.md §1 [choice]).

The SUT drives through a window ``[s_sut - behind_m, s_sut + ahead_m]`` that moves with it.
After every step of the world (:meth:`evoscen_sim.physics.world.World.step`, step 4):

1. **Shift.** When the SUT's arc length reaches ``shift_from_m``, every vehicle's ``s`` is
   reduced by ``shift_from_m - shift_to_m`` (one distance for all: every relative position,
   lane, speed and lateral offset is kept). Both ends of the shift lie on stretches of the
   road where the window sees the same lanes and the same (zero) curvature —
   :func:`check_shift_points` verifies that against the map — so the translation changes
   nothing a driver or the score sees; the road is effectively an endless highway that passes
   the on-ramp once per ``shift_from_m - shift_to_m`` metres. The SUT itself is never moved
   otherwise: it is never re-entered, never put into another lane.
2. **Exits.** A BV whose centre is more than ``exit_margin_m`` beyond either edge of the
   window leaves it.
3. **Entries.** Each vehicle that left enters again at once as a new vehicle (same id: an id
   is a slot; the ``evoscen/reentry`` event marks the new trip), into the lane whose count in
   the window is furthest below its target (``lane_density_per_km`` × window length; the merge
   lane counts when its start lies in the window, with ``ramp_density_per_km`` over the part
   of it in the window). Its speed is drawn from the lane's distribution (``lane_speed_mps``:
   mean and standard deviation, truncated at ±2 standard deviations). A vehicle slower than
   the SUT enters at the window's front edge (traffic the SUT will catch up with), one as fast
   or faster at the rear edge (traffic that will catch up with the SUT); merge-lane vehicles
   enter at the merge lane's start. It is placed only where both it and its new follower can
   follow safely (:func:`insertion_speed`): if the gap to its leader is too short for the drawn
   speed the speed is lowered to the largest safe one (never below the lane's mean minus two
   standard deviations), and if its follower could not follow it, the next lane is tried. A
   vehicle that finds no safe place keeps driving where it is and tries again at the next step;
   one that reaches the road's end waits at the road's start.

Random draws come from the world's seeded generator (docs/architecture.md: random streams).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MERGE_LANE = 0


@dataclass(frozen=True)
class TrafficParams:
    """The traffic window (the ``traffic`` section of the scenario; docs/method.md §1)."""

    behind_m: float = 150.0
    ahead_m: float = 250.0
    exit_margin_m: float = 10.0
    lane_density_per_km: tuple[float, ...] = (12.5, 12.5, 12.5, 12.5)
    """Target density of the mainline lanes, rightmost (II) first (vehicles per km)."""
    lane_speed_mps: tuple[tuple[float, float], ...] = ((26.0, 1.5), (28.0, 1.5), (30.0, 1.5), (32.0, 1.5))
    """(mean, standard deviation) of the entry speed of the mainline lanes, rightmost first (m/s)."""
    ramp_density_per_km: float = 10.0
    ramp_speed_mps: tuple[float, float] = (22.0, 2.0)
    insertion_headway_s: float = 1.0
    insertion_decel_mps2: float = 4.5
    insertion_min_gap_m: float = 2.5
    insertion_band_m: float = 50.0
    """How far inside the window from its edge a vehicle may enter when the edge itself is taken (m)."""
    shift_from_m: float = 2000.0
    shift_to_m: float = 300.0
    warmup_s: float = 20.0


def required_gap(v_back: float, v_front: float, p: TrafficParams) -> float:
    """Bumper gap a vehicle at ``v_back`` needs behind one at ``v_front`` to follow it safely.

    ``g0 + v_back·τ + max(0, (v_back² − v_front²) / (2b))``: the follower reacts after τ and
    then brakes with b to the leader's speed, keeping the standstill gap g0 (SUMO's insertion
    checks use the same idea: the safe following speed of Krauss for both the new vehicle and
    its follower).
    """
    return p.insertion_min_gap_m + v_back * p.insertion_headway_s + max(
        0.0, (v_back * v_back - v_front * v_front) / (2.0 * p.insertion_decel_mps2))


def insertion_speed(v_wish: float, gap_m: float, v_leader: float, p: TrafficParams) -> float:
    """The largest speed <= ``v_wish`` at which a vehicle ``gap_m`` behind a leader at ``v_leader``
    follows it safely (:func:`required_gap` <= gap); -inf when even standing still is not safe."""
    g = gap_m - p.insertion_min_gap_m
    if g < 0.0:
        return -math.inf
    tau, b = p.insertion_headway_s, p.insertion_decel_mps2
    if v_wish <= v_leader or required_gap(v_wish, v_leader, p) <= gap_m:
        if required_gap(v_wish, v_leader, p) <= gap_m:
            return v_wish
        return min(v_wish, g / tau)  # slower than the leader: only the headway binds
    # faster than the leader: the largest v with v·τ + (v² − v_l²)/(2b) <= g (Krauss' safe speed)
    v = -b * tau + math.sqrt((b * tau) ** 2 + v_leader * v_leader + 2.0 * b * g)
    if v <= v_leader:  # then only the headway binds
        v = min(v_leader, g / tau)
    return min(v_wish, v)


def check_shift_points(road, p: TrafficParams, hold_s: float | None = None) -> str | None:  # a RoadModel
    """Why the shift cannot keep every relative position (None when it can).

    The window around the SUT at ``shift_from_m`` and at ``shift_to_m`` (each with the exit
    margin), and at ``hold_s`` (the SUT's start, where it is held during the warm-up) when there is
    one, must see the same lanes and zero curvature everywhere, and the shift must go back.
    """
    if p.shift_to_m >= p.shift_from_m:
        return (f"traffic.shift_to_m = {p.shift_to_m:g} must be below traffic.shift_from_m = "
                f"{p.shift_from_m:g} (the window is moved back along the road)")
    lo, hi = p.behind_m + p.exit_margin_m, p.ahead_m + p.exit_margin_m
    ref = None
    points = [("traffic.shift_from_m", p.shift_from_m), ("traffic.shift_to_m", p.shift_to_m)]
    if p.warmup_s > 0.0 and hold_s is not None:
        points.append(("sut.s_m (held there during traffic.warmup_s)", hold_s))
    for key, at in points:
        a, b = at - lo, at + hi
        if a < 0.0 or b > road.length_m:
            return (f"{key} = {at:g}: the window with its exit margin ({a:g} .. {b:g} m) must lie on "
                    f"the road (0 .. {road.length_m:g} m)")
        s = np.linspace(a, b, max(2, int(math.ceil(b - a)) + 1))
        present = road.lane_lookup(s, np.zeros_like(s)).present
        kappa = np.asarray(road.curvature(s), dtype=float)
        if (present != present[0]).any() or (np.abs(kappa) > 1e-12).any():
            return (f"{key} = {at:g}: the road is not uniform over the window {a:g} .. {b:g} m "
                    f"(lanes or curvature change there); choose a point where it is straight with the "
                    f"same lanes over behind_m + ahead_m + 2 * exit_margin_m")
        if ref is not None and (present[0] != ref).any():
            return (f"{points[0][0]}, {key}: the road has different lanes at these points; all must see "
                    "the same lanes")
        ref = present[0]
    return None


class TrafficWindow:
    """Keeps the traffic of a :class:`~evoscen_sim.physics.world.World` around its SUT (module docstring)."""

    def __init__(self, world, params: TrafficParams, sut_index: int) -> None:
        road = world.road
        self.p = params
        self.sut = int(sut_index)
        self.mainline = [k for k in range(road.num_lanes) if road.lane_start_s[k] <= 0.0]
        if len(params.lane_density_per_km) != len(self.mainline) or len(params.lane_speed_mps) != len(self.mainline):
            raise ValueError(
                f"traffic: lane_density_per_km and lane_speed_mps need one entry per mainline lane "
                f"({len(self.mainline)} on this map), got {len(params.lane_density_per_km)} and "
                f"{len(params.lane_speed_mps)}")
        self.has_ramp = MERGE_LANE not in self.mainline and road.num_lanes > 0
        self.shift_m = params.shift_from_m - params.shift_to_m

    # ------------------------------------------------------------------ one step
    def hold(self, world, s_hold: float) -> None:
        """Move every vehicle back by the SUT's advance beyond ``s_hold`` (the warm-up's treadmill)."""
        world.s -= float(world.s[self.sut]) - s_hold

    def after_step(self, world, result) -> None:
        """Shift, exits and entries after the world integrated a step (results into ``result``)."""
        p = self.p
        s = world.s
        if s[self.sut] >= p.shift_from_m:
            s -= self.shift_m
            result.shift_m = self.shift_m
        s_sut = float(s[self.sut])
        lo = s_sut - p.behind_m - p.exit_margin_m
        hi = s_sut + p.ahead_m + p.exit_margin_m
        out = ((s < lo) | (s > hi)) & (world.role != world.role[self.sut])
        out[self.sut] = False
        road_end = world.road.length_m
        for i in np.flatnonzero(out):
            placed = self._enter(world, int(i))
            if placed is not None:
                result.reentries.append(placed)
            elif s[i] > road_end:  # no safe place: wait at the road's start (outside the window)
                result.reentries.append(world._reenter(int(i)))

    # ------------------------------------------------------------------ entries
    def _targets(self, world, s_sut: float) -> list[tuple[float, int, float, float]]:
        """(relative deficit, lane, mean speed, sd) of every lane that may take a vehicle, most wanted first."""
        p = self.p
        road = world.road
        lo, hi = s_sut - p.behind_m, s_sut + p.ahead_m
        inside = (world.s >= lo) & (world.s <= hi)
        inside[self.sut] = False
        occupied = np.where(world.lane_change != 0, world.target_lane, world.lane)
        rows = []
        length_km = (hi - lo) / 1000.0
        for j, lane in enumerate(self.mainline):
            target = p.lane_density_per_km[j] * length_km
            if target <= 0.0:
                continue
            count = int(np.count_nonzero(inside & (occupied == lane)))
            mean, sd = p.lane_speed_mps[j]
            rows.append(((count - target) / target, lane, mean, sd))
        if self.has_ramp and p.ramp_density_per_km > 0.0:
            start, end = float(road.lane_start_s[MERGE_LANE]), float(road.lane_end_s[MERGE_LANE])
            target = p.ramp_density_per_km * (min(end, hi) - start) / 1000.0
            if lo <= start <= hi and target > 0.0:  # (the start exactly at the front edge: no room yet)
                count = int(np.count_nonzero(inside & (occupied == MERGE_LANE)))
                rows.append(((count - target) / target, MERGE_LANE, *p.ramp_speed_mps))
        rows.sort(key=lambda r: (r[0], r[1]))
        return [r for r in rows if r[0] < 0.0] or rows

    def _enter(self, world, i: int) -> tuple[int, int, float] | None:
        p = self.p
        road = world.road
        s_sut, v_sut = float(world.s[self.sut]), float(world.v[self.sut])
        half = 0.5 * world.vehicle.length_m
        for _, lane, mean, sd in self._targets(world, s_sut):
            v = float(np.clip(world.rng.normal(mean, sd), mean - 2.0 * sd, mean + 2.0 * sd))
            v_floor = max(0.0, mean - 2.0 * sd)
            if lane == MERGE_LANE:
                s_new = float(road.lane_start_s[MERGE_LANE]) + half
            elif v < v_sut:
                s_new = s_sut + p.ahead_m
            else:
                s_new = s_sut - p.behind_m
            for s_try in self._positions(world, i, lane, s_new, s_sut):
                if not bool(road.lane_exists(np.array([lane]), np.array([s_try]))[0]):
                    continue
                v_try = self._safe_speed(world, i, lane, s_try, v, half)
                if v_try >= v_floor:
                    world._place(i, lane, s_try, v_try)
                    return (i, int(lane), float(s_try))
        return None

    def _positions(self, world, i: int, lane: int, s_edge: float, s_sut: float) -> list[float]:
        """Where a vehicle may enter ``lane``: the edge itself, then the middle of the largest gap
        of the lane within ``insertion_band_m`` inside the window from that edge (the merge lane:
        its start only)."""
        band = self.p.insertion_band_m
        if lane == MERGE_LANE or band <= 0.0:
            return [s_edge]
        inward = -1.0 if s_edge > s_sut else 1.0
        a, b = sorted((s_edge, s_edge + inward * band))
        cand = ((world.lane == lane) | (world.target_lane == lane)) & (world.s >= a - 100.0) & (world.s <= b + 100.0)
        cand[i] = False
        s = np.sort(np.concatenate([world.s[cand], [a - 1e9, b + 1e9]]))
        s = np.clip(s, a, b)
        k = int(np.argmax(np.diff(s)))
        mid = 0.5 * (s[k] + s[k + 1])
        return [s_edge] if abs(mid - s_edge) < 1e-9 else [s_edge, float(mid)]

    def _safe_speed(self, world, i: int, lane: int, s_new: float, v: float, half: float) -> float:
        """``v`` lowered to what the leader allows; -inf when the follower could not follow (or the
        vehicle would overlap one)."""
        p = self.p
        leader, follower = _neighbours(world, i, lane, s_new)
        if leader >= 0:
            gap = world.s[leader] - s_new - 0.5 * world.length[leader] - half
            v = insertion_speed(v, gap, float(world.v[leader]), p)
        if follower >= 0:
            gap = s_new - world.s[follower] - 0.5 * world.length[follower] - half
            if gap < required_gap(float(world.v[follower]), v, p):
                return -math.inf
        return v


def _neighbours(world, i: int, lane: int, s_new: float) -> tuple[int, int]:
    """Nearest vehicle ahead of and behind ``s_new`` in ``lane``, -1 if none.

    In the lane means: its lane or its target lane is ``lane``, or its body reaches across the
    lane's border (a vehicle that has just completed a lane change out of it still straddles it).
    """
    look = world.road.lane_lookup(np.array([max(s_new, 0.0)]), np.zeros(1))
    right, left = float(look.d_right[0, lane]), float(look.d_left[0, lane])
    half_w = 0.5 * world.width
    across = (world.d + half_w > right) & (world.d - half_w < left)
    cand = (world.lane == lane) | (world.target_lane == lane) | across
    cand[i] = False
    k = np.flatnonzero(cand)
    if not k.size:
        return -1, -1
    ds = world.s[k] - s_new
    ahead, behind = k[ds >= 0.0], k[ds < 0.0]
    leader = int(ahead[np.argmin(world.s[ahead])]) if ahead.size else -1
    follower = int(behind[np.argmax(world.s[behind])]) if behind.size else -1
    return leader, follower


def common_shift(prev_s: np.ndarray, s: np.ndarray) -> float:
    """The distance all vehicles were moved along the road between two states (a window shift,
    negative), 0.0 when there was none: the median step of ``s`` when it is a fall of more than
    50 m (a shift moves every vehicle by one distance; entries move a few vehicles only). With
    fewer than three vehicles a jump is taken for a re-entry, never a shift."""
    if np.asarray(prev_s).size < 3:
        return 0.0
    med = float(np.median(np.asarray(s, dtype=float) - np.asarray(prev_s, dtype=float)))
    return med if med < -50.0 else 0.0


def new_trips(prev_s: np.ndarray, s: np.ndarray, dt_s: float, *, max_speed_mps: float = 40.0,
              shift_m: float | None = None) -> np.ndarray:
    """Which vehicles began a new trip between two states (entered the window or re-entered the
    road): their step of ``s``, less the common shift (``shift_m``, else :func:`common_shift`), is
    more than 10 m backwards or more than ``max_speed_mps * dt_s + 10`` m forwards. What a driver
    uses to forget a vehicle's past (a window entry can also move a vehicle by less than that: it
    then counts as the same trip)."""
    prev_s = np.asarray(prev_s, dtype=float)
    s = np.asarray(s, dtype=float)
    shift = common_shift(prev_s, s) if shift_m is None else shift_m
    d = s - prev_s - shift
    return (d < -10.0) | (d > max_speed_mps * dt_s + 10.0)
