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
   vehicle that finds no safe place keeps driving where it is and tries again ``entry_retry_s``
   later (:func:`entry_retry_steps`); one that reaches the road's end waits at the road's start.

Random draws come from the world's seeded generator (docs/architecture.md: random streams): one
``normal`` per lane tried, in Python. The search for a place (positions, lane existence, neighbours,
safe speed) is one compiled call for all the lanes of an entry, :func:`_place_first` over
:func:`_place_in_lane` (:mod:`evoscen_sim.jit`); the draws of every lane are made before it, and the
generator's state is put back and only the tried lanes' draws made again when a lane before the last
takes the vehicle, so the stream is that of one draw per lane tried (docs/performance.md). Its
:func:`_insertion_speed` and :func:`_required_gap` are also what :func:`insertion_speed` and
:func:`required_gap` compute (one definition each).
"""

from __future__ import annotations

import math

import numpy as np

from evoscen_sim.config.config_schema import TrafficParams
from evoscen_sim.jit import kernel, plain
from evoscen_sim.physics.entry_kernels import (  # noqa: F401 - re-exported: the entry's kernels, tested from here
    _entry_place,
    _entry_rows,
    _follow_speed,
    _insertion_speed,
    _lane_counts,
    _lane_mean_speeds,
    _np_clip,
    _place_first,
    _place_in_lane,
    _required_gap,
)
from evoscen_sim.road.road_model import MERGE_LANE


def entry_retry_steps(retry_s: float, dt_s: float) -> int:
    """Steps after which a vehicle that found no place to enter tries again (``traffic.entry_retry_s``, at
    least one step); 0 for ``retry_s`` 0: at the next step. [choice] 1 s, 10 steps at dt = 0.1 s: trucks
    enter lane II only and waited there often, and the search every step cost ``highd`` a tenth of its step
    rate and ``uniform`` about a quarter of its step time (docs/method.md §1, docs/bv-profiles.md)."""
    return 0 if retry_s <= 0.0 else max(1, int(round(retry_s / dt_s)))


def required_gap(v_back: float, v_front: float, p: TrafficParams) -> float:
    """Bumper gap a vehicle at ``v_back`` needs behind one at ``v_front`` to follow it safely.

    ``g0 + v_back·τ + max(0, (v_back² − v_front²) / (2b))``: the follower reacts after τ and
    then brakes with b to the leader's speed, keeping the standstill gap g0 (SUMO's insertion
    checks use the same idea: the safe following speed of Krauss for both the new vehicle and
    its follower). Computed by the entry search's kernel, :func:`_required_gap`.
    """
    return float(_required_gap(float(v_back), float(v_front), float(p.insertion_min_gap_m),
                               float(p.insertion_headway_s), float(p.insertion_decel_mps2)))


def insertion_speed(v_wish: float, gap_m: float, v_leader: float, p: TrafficParams) -> float:
    """The largest speed <= ``v_wish`` at which a vehicle ``gap_m`` behind a leader at ``v_leader``
    follows it safely (:func:`required_gap` <= gap); -inf when even standing still is not safe.

    Slower than the leader only the headway binds (``(gap − g0) / τ``); faster, Krauss' safe speed,
    the largest v with ``v·τ + (v² − v_l²)/(2b) <= gap − g0``. Computed by the entry search's
    kernel, :func:`_insertion_speed`."""
    tau, b = float(p.insertion_headway_s), float(p.insertion_decel_mps2)
    return float(_insertion_speed(float(v_wish), float(gap_m), float(v_leader), float(p.insertion_min_gap_m),
                                  tau, b, float((b * tau) ** 2)))


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

    def __init__(self, world, params: TrafficParams, sut_index: int, makeup=None) -> None:
        road = world.road
        self.sut = int(sut_index)
        self.mainline = road.mainline_lanes
        self.p = params
        self.makeup = makeup
        """The highd make-up's entries (:class:`evoscen_sim.traffic.makeup.WindowMakeup`); None: uniform."""
        self._retry_steps = entry_retry_steps(params.entry_retry_s, world.dt_s)
        self._retry_step = np.zeros(world.n, dtype=np.int64) if self._retry_steps else None
        """The step from which each vehicle that found no place tries again (None: at every step)."""
        self.truck_lanes = (frozenset([*self.mainline[:makeup.truck_entry_lanes],
                                       *([MERGE_LANE] if makeup.truck_ramp_entries else [])])
                            if makeup is not None else frozenset())
        if len(params.lane_density_per_km) != len(self.mainline) or len(params.lane_speed_mps) != len(self.mainline):
            raise ValueError(
                f"traffic: lane_density_per_km and lane_speed_mps need one entry per mainline lane "
                f"({len(self.mainline)} on this map), got {len(params.lane_density_per_km)} and "
                f"{len(params.lane_speed_mps)}")
        self.has_ramp = road.has_merge_lane
        self.shift_m = params.shift_from_m - params.shift_to_m
        self._tables = road.border_tables()
        self._ramp_start_s = float(road.lane_start_s[MERGE_LANE]) if self.has_ramp else 0.0
        self._ramp_end_s = float(road.lane_end_s[MERGE_LANE]) if self.has_ramp else 0.0
        self._num_lanes = road.num_lanes
        self._all_lanes = np.ones(road.num_lanes, dtype=np.bool_)
        self._truck_mask = np.zeros(road.num_lanes, dtype=np.bool_)  # the lanes a truck may enter
        self._truck_mask[list(self.truck_lanes)] = True

    @property
    def p(self) -> TrafficParams:
        """The window's parameters (set: what the entries read of them is worked out once, here)."""
        return self._p

    @p.setter
    def p(self, params: TrafficParams) -> None:
        self._p = params
        self._lane_rows = tuple(zip(self.mainline, params.lane_density_per_km, params.lane_speed_mps))
        """(lane, target density, (mean, sd) of entry speed) of each mainline lane, rightmost first."""
        self._row_arrays = (np.array([r[0] for r in self._lane_rows], dtype=np.int64),
                            np.array([float(r[1]) for r in self._lane_rows], dtype=np.float64),
                            np.array([float(r[2][0]) for r in self._lane_rows], dtype=np.float64),
                            np.array([float(r[2][1]) for r in self._lane_rows], dtype=np.float64))
        """:attr:`_lane_rows` as the compiled entry's arrays (lanes, densities, means, sds)."""
        self._consts = (float(params.insertion_band_m), float(params.insertion_min_gap_m),
                        float(params.insertion_headway_s), float(params.insertion_decel_mps2),
                        float((params.insertion_decel_mps2 * params.insertion_headway_s) ** 2))
        """The safe-insertion rule's band, g0, τ, b and (b·τ)² (:func:`insertion_speed`)."""

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
        road_end = world.road.length_m
        retry = self._retry_step
        for i in _exits(s, world.role, self.sut, lo, hi):
            if retry is not None and retry[i] > world.step_index:
                placed = None  # it found no place lately; it tries again at its retry step
            else:
                placed = self._enter(world, int(i))
                if placed is None and retry is not None:
                    retry[i] = world.step_index + self._retry_steps
            if placed is not None:
                result.reentries.append(placed)
            elif s[i] > road_end:  # no safe place: wait at the road's start (outside the window)
                result.reentries.append(world._reenter(int(i)))

    # ------------------------------------------------------------------ entries
    def _targets(self, world, s_sut: float, allowed: frozenset | None = None) -> list[tuple[float, int, float, float]]:
        """(relative deficit, lane, mean speed, sd) of every lane that may take a vehicle, most wanted first
        (of the lanes in ``allowed`` only, when given: a truck's)."""
        p = self.p
        lo, hi = s_sut - p.behind_m, s_sut + p.ahead_m
        counts = _lane_counts(world.s, world.lane, world.target_lane, world.lane_change, self.sut, lo, hi,
                              self._num_lanes)
        rows = []
        length_km = (hi - lo) / 1000.0
        for lane, density, (mean, sd) in self._lane_rows:
            target = density * length_km
            if target <= 0.0:
                continue
            count = int(counts[lane])
            rows.append(((count - target) / target, lane, mean, sd))
        if self.has_ramp and p.ramp_density_per_km > 0.0:
            start, end = self._ramp_start_s, self._ramp_end_s
            target = p.ramp_density_per_km * (min(end, hi) - start) / 1000.0
            if lo <= start <= hi and target > 0.0:  # (the start exactly at the front edge: no room yet)
                count = int(counts[MERGE_LANE])
                rows.append(((count - target) / target, MERGE_LANE, *p.ramp_speed_mps))
        rows.sort(key=lambda r: (r[0], r[1]))
        if allowed is not None:
            rows = [r for r in rows if r[1] in allowed]
        return [r for r in rows if r[0] < 0.0] or rows

    def _enter(self, world, i: int) -> tuple[int, int, float] | None:
        """Vehicle ``i`` entered in the first of :meth:`_targets`'s lanes (a car of ``highd``'s ``by_speed`` in
        :func:`_by_speed`'s order) that has a safe place (:func:`_place_first`), or None. Compiled
        (:func:`_entry_rows`, :func:`_entry_place`: the same numbers and order as the rows built here before,
        :meth:`_enter_rows` being that reference; docs/performance.md "Per-step work of the world and of the BV
        drivers"); ``uniform``'s entry speeds are drawn here, one normal per lane tried."""
        p = self.p
        sut = self.sut
        mk = self.makeup
        truck = mk is not None and bool(mk.truck[i])
        wish = float(mk.wish_mps[i]) if mk is not None else 0.0
        lanes, means, sds = _entry_rows(
            world.s, world.v, world.lane, world.target_lane, world.lane_change, sut, float(world.s[sut]),
            float(p.behind_m), float(p.ahead_m), self._num_lanes, *self._row_arrays,
            self.has_ramp and p.ramp_density_per_km > 0.0, float(p.ramp_density_per_km), self._ramp_start_s,
            self._ramp_end_s, float(p.ramp_speed_mps[0]), float(p.ramp_speed_mps[1]), MERGE_LANE,
            self._truck_mask if truck else self._all_lanes, mk is not None and mk.cars_by_speed and not truck, wish)
        n = lanes.shape[0]
        rng = world.rng
        state = None
        draws = _NO_DRAWS
        if mk is None and n:  # every lane's draw made here: the kernel tries them in order (one draw per lane tried)
            state = rng.bit_generator.state if n > 1 else None
            # standard normals: the kernel takes mean + sd·z, as rng.normal(mean, sd) computes it, the same stream
            draws = rng.standard_normal(n)
        c = self._consts
        k, s_at, v_at = _entry_place(
            world.s, world.d, world.v, world.length, world.width, world.lane, world.target_lane, i, lanes, means, sds,
            draws, mk is not None, wish, float(world.v[sut]), float(world.s[sut]), float(p.behind_m), float(p.ahead_m),
            self._ramp_start_s, 0.5 * world.length[i], MERGE_LANE, mk is not None and mk.raise_front_entries,
            c[0], c[1], c[2], c[3], c[4], plain(self._tables))
        if state is not None and 0 <= k < n - 1:  # placed before the last lane: only k + 1 draws were due
            rng.bit_generator.state = state
            rng.standard_normal(k + 1)
        if k < 0:
            return None
        lane = int(lanes[k])
        world._place(i, lane, s_at, v_at)
        return (i, lane, float(s_at))

    def _enter_rows(self, world, i: int) -> list[tuple[float, int, float, float]]:
        """The rows :meth:`_enter` tries, in order, as Python builds them (:meth:`_targets`, :func:`_by_speed`): what
        :func:`_entry_rows` must equal (a test compares them)."""
        p = self.p
        s_sut = float(world.s[self.sut])
        mk = self.makeup
        allowed = self.truck_lanes if mk is not None and mk.truck[i] else None
        rows = self._targets(world, s_sut, allowed)
        if mk is not None and mk.cars_by_speed and not mk.truck[i]:
            rows = _by_speed(rows, float(mk.wish_mps[i]), _lane_mean_speeds(
                world.s, world.v, world.lane, world.target_lane, world.lane_change,
                s_sut - p.behind_m, s_sut + p.ahead_m, world.road.num_lanes))
        return rows


_NO_DRAWS = np.zeros(0)


def _by_speed(rows: list, wish: float, lane_speed: np.ndarray) -> list:
    """``rows`` of :meth:`TrafficWindow._targets` for a car under ``models.highd.car_lanes: by_speed``:
    the lanes nearest in speed first — the mean speed of the lane's vehicles in the window, or the
    row's entry mean while it has none —, ties by the rows' order (docs/bv-profiles.md, "Traffic
    make-up")."""
    def gap(k: int) -> float:
        _, lane, mean, _ = rows[k]
        v = lane_speed[lane]
        return abs((mean if np.isnan(v) else v) - wish)
    return [rows[k] for k in sorted(range(len(rows)), key=lambda k: (gap(k), k))]


@kernel
def _exits(s, role, sut, lo, hi):
    """The vehicles outside ``[lo, hi]`` that are not of the SUT's role, in index order (step 2 of
    :meth:`TrafficWindow.after_step`; compiled: every step)."""
    n = s.shape[0]
    out = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if i != sut and (s[i] < lo or s[i] > hi) and role[i] != role[sut]:
            out[m] = i
            m += 1
    return out[:m]


def common_shift(prev_s: np.ndarray, s: np.ndarray) -> float:
    """The distance all vehicles were moved along the road between two states (a window shift,
    negative), 0.0 when there was none: the median step of ``s`` when it is a fall of more than
    50 m (a shift moves every vehicle by one distance; entries move a few vehicles only). With
    fewer than three vehicles a jump is taken for a re-entry, never a shift."""
    return float(common_shift_kernel(np.asarray(prev_s, dtype=np.float64).ravel(),
                                     np.asarray(s, dtype=np.float64).ravel()))


@kernel
def common_shift_kernel(prev_s, s):
    """:func:`common_shift` of 1-D float arrays, for compiled callers."""
    if prev_s.shape[0] < 3:
        return 0.0
    med = _median(s - prev_s)
    return med if med < -50.0 else 0.0


@kernel
def _median(x):
    """``np.median`` of a 1-D float array: NaN if any value is NaN, else the middle value of the sorted
    values, or for an even count the mean of the two middle ones, ``(a + b) / 2`` (numpy's mean of
    two) — the same bits, but for the sign of a zero median (numpy's partition and this sort may put
    -0.0 and 0.0 in either order; :func:`common_shift` maps both to 0.0). Compiled: called every step
    by drivers that remember vehicles."""
    n = x.shape[0]
    for i in range(n):
        if x[i] != x[i]:
            return np.nan
    y = np.sort(x)
    h = n // 2
    if n % 2 == 1:
        return y[h]
    return (y[h - 1] + y[h]) / 2.0


NEW_TRIP_MAX_SPEED_MPS = 40.0
"""A vehicle that moved farther than this speed allows (+ 10 m) began a new trip (:func:`new_trips`)."""


def new_trips(prev_s: np.ndarray, s: np.ndarray, dt_s: float, *, max_speed_mps: float = NEW_TRIP_MAX_SPEED_MPS,
              shift_m: float | None = None) -> np.ndarray:
    """Which vehicles began a new trip between two states (entered the window or re-entered the
    road): their step of ``s``, less the common shift (``shift_m``, else :func:`common_shift`), is
    more than 10 m backwards or more than ``max_speed_mps * dt_s + 10`` m forwards. What a driver
    uses to forget a vehicle's past (a window entry can also move a vehicle by less than that: it
    then counts as the same trip)."""
    prev_s = np.asarray(prev_s, dtype=np.float64)
    s = np.asarray(s, dtype=np.float64)
    shift = common_shift(prev_s, s) if shift_m is None else float(shift_m)
    return new_trips_kernel(prev_s, s, shift, float(max_speed_mps) * float(dt_s) + 10.0)


@kernel
def new_trips_kernel(prev_s, s, shift, forward_m):
    """:func:`new_trips` with the shift and the forward limit (``max_speed_mps * dt_s + 10``) given,
    for compiled callers."""
    out = np.empty(s.shape[0], dtype=np.bool_)
    for j in range(s.shape[0]):
        d = s[j] - prev_s[j] - shift
        out[j] = d < -10.0 or d > forward_m
    return out
