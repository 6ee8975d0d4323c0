"""The lane-change decision model (docs/method.md §3.2): grid observation, action, rule constraints, rewards.

Observation Ω_d of vehicle ``i``: a grid of 5 lanes (row ``r`` = lane offset ``r - 2`` from
the ego's lane, +1 = left) by 25 longitudinal cells of 5 m (cell ``c`` holds centre offsets
Δs = s_j - s_i in [-20 + 5c, -15 + 5c) m, i.e. 20 m behind to 105 m ahead) by 4 layers:

* P: 1 where another vehicle's centre is in the cell, -1 where the cell is off the road
  (the lane does not exist there: beyond the road edges, the merge lane before its start
  and after its end), else 0;
* Δv_s = (v_j - v_i) / v_max, the relative longitudinal speed;
* Δv_d = (v_j sin ψ_j - v_i sin ψ_i) / lateral_speed_scale, the relative lateral speed;
* Δe = (ψ_j - ψ_i) / yaw_scale, the relative yaw (ψ relative to the road).

The ego itself is not in its grid. Two vehicles in one cell: the one nearer the ego
longitudinally is shown. The grid is built for all deciding vehicles in one compiled pass;
the flattened order is (lane row, cell, layer), 500 values.

Action: one continuous output a ∈ [-1, 1] → right (-1) if a < -1/3, left (+1) if a > 1/3,
else keep [choice: thresholds ±1/3].

Rule constraints on the requested action (the executed action can differ; the reward's
J_req fires when it does): a change that would leave the road becomes keep; a change into
a lane with another vehicle within 10 m longitudinally (bumper-to-bumper, overlaps
included; a vehicle changing into that lane, or whose body reaches into it, counts as in
it: :func:`evoscen_bv.car_following.leaders`) becomes keep.
[choice] The 10 m grow with the closing speed, as level-0's merge rule: a vehicle ahead in
the target lane must be at least 10 m + h·max(0, v_i - v_j) away, one behind at least
10 m + h·max(0, v_j - v_i), h = 1.5 s (``CUT_IN_CLOSING_HEADWAY_S``). With the method's
plain 10 m, a merge from standstill in front of traffic at 30 m/s was "legal" and most
lane-change collisions were such cut-ins. h is a parameter of the BV profile (both profiles
keep 1.5 s; docs/bv-profiles.md gives the measurements).
Opt-in (``models.learned.cut_in_decel_mps2`` = b > 0, ``driver`` profile): the gap also holds
c²/(2b), so a new follower that reacts only after its reaction time can match speeds without
braking harder than b. [choice] Off by default: with b = 4 m/s² merging BVs waited at
standstill and jams formed (docs/bv-profiles.md, R5, gives the figures).
[choice] A change into a lane that ends within 200 m ahead (the merge lane, seen from lane
II) becomes keep, like a change off the road: trained BVs moved into the ending merge lane
behind the vehicles waiting at its end, stopped half-way and blocked both lanes.

Rewards (method §3.2), with O the drivable area — the gap to the nearest vehicle ahead
in a lane, also bounded by the end of that lane and by the front view O_max:

* individual: r_i = sgn(ϑO_t - O_c)(ϑO_t - O_c)²/M + J_lc + J_req + O_c'²/O_max²
* mutual: r = r_i
* competitive: r = r_i - u Σ_b (ϑO_c^b)²/O_max² - v Σ_b min(s̈_b|s̈_b|/s̈_max², z)
* cooperative: r = r_i + m Σ_b (ϑO_c^b)²/O_max² + n Σ_b min(ṡ_b|ṡ_b|/ṡ_max², y)

[choice] timing: the lane-change gain (O_c, O_t) and the penalties are evaluated at the
decision (O_t is the lane of the *executed* action; for keep O_t = O_c and the gain is 0);
J_lc applies when a change is executed, J_req when requested ≠ executed (both are
negative numbers). The outcome terms O_c'²/O_max² and the social sums are evaluated at
the next decision, on the vehicles then in the back part of the ego's grid (Ω_b: the
cells behind the ego, Δs in [-20, 0), all five lanes).
[choice] J_lc differs by type (reward shaping, docs/method.md §3.3): -0.4 competitive, -0.8 mutual,
-3.0 cooperative — the equations are the method's, the coefficients per type are ours.
[choice] ϑ favours the left lanes: ϑ = ``theta_left`` for a lane left of the ego's lane,
else 1 (for O_t: a change to the left; for O_c^b: a vehicle b in a lane left of the ego).
The coefficients are the ``reward`` section of the training config
(``share/evoscen_bv/config/training.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evoscen_sim.jit import kernel
from evoscen_sim.physics.neighbors import lane_column

from .car_following import _occupancy

LANES = 5
CELLS = 25
LAYERS = 4
CELL_M = 5.0
BEHIND_M = 20.0
OBS_DIM = LANES * CELLS * LAYERS
BACK_CELLS = int(BEHIND_M / CELL_M)
"""Cells 0..3 are behind the ego (Ω_b)."""
ACTION_THRESHOLD = 1.0 / 3.0
CUT_IN_GAP_M = 10.0
LANE_END_MARGIN_M = 200.0
"""[choice] A change into a lane that ends less than this far ahead becomes keep (m)."""
CUT_IN_CLOSING_HEADWAY_S = 1.5
"""[choice] Seconds of closing speed added to the 10 m cut-in gap (level-0's ``merge_closing_headway_s``)."""
FORCED_MERGE_M = 120.0
"""[choice] Run time: on the last this-many metres of a lane that ends, a learned BV requests the
change towards the lane that goes on, whatever its policy says (:func:`forced_merge_requests`)."""


@dataclass(frozen=True)
class GridParams:
    """Normalisers of the grid layers."""

    v_max_mps: float = 33.33
    lateral_speed_scale_mps: float = 2.0
    """[choice] lateral speeds of a lane change are 0.5-1.5 m/s."""
    yaw_scale_rad: float = 0.2
    """[choice] headings relative to the road stay within ±0.1 rad."""


@dataclass(frozen=True)
class RewardParams:
    """Coefficients of the decision rewards (method §3.2) [choice: values are ours]."""

    front_view_m: float = 100.0
    """O_max: the front view bounding the drivable area (m)."""
    theta_left: float = 1.1
    """ϑ: factor favouring lanes to the left."""
    gain_norm_m2: float = 2500.0
    """M: normaliser of the lane-change gain (m²); a 50 m gain gives 1."""
    lane_change_penalty: float = -0.8
    """J_lc of the mutual driver: added when a lane change is executed (negative)."""
    comp_lane_change_penalty: float = -0.4
    """J_lc of the competitive driver [choice: a smaller penalty — the type that changes most]."""
    coop_lane_change_penalty: float = -3.0
    """J_lc of the cooperative driver [choice: a larger penalty — every change disturbs others;
    at -1.2 the trained cooperative BVs still changed lanes more often than the mutual ones, as
    the followers' space term rewards moving out of their way]."""
    request_penalty: float = -0.5
    """J_req: added when the executed action differs from the requested one (negative)."""
    comp_space_weight: float = 0.1
    """u: competitive weight of the followers' drivable area."""
    comp_brake_weight: float = 4.0
    """v: competitive weight of the followers' signed squared acceleration."""
    comp_brake_bound: float = 0.1
    """z: upper bound of the competitive acceleration term."""
    coop_space_weight: float = 0.1
    """m: cooperative weight of the followers' drivable area [choice: as u; at 0.3, summed over
    every later decision, moving out of the followers' way paid far more than J_lc cost, and
    cooperative BVs changed lanes more often than mutual ones]."""
    coop_speed_weight: float = 0.3
    """n: cooperative weight of the followers' signed squared speed."""
    coop_speed_bound: float = 1.0
    """y: upper bound of the cooperative speed term."""
    accel_norm_mps2: float = 8.0
    """s̈_max (m/s²)."""
    speed_norm_mps: float = 33.33
    """ṡ_max (m/s)."""


def action_to_lane_change(a: np.ndarray) -> np.ndarray:
    """Continuous actions → requests {-1 right, 0 keep, +1 left} (thresholds ±1/3)."""
    a = np.asarray(a, dtype=float)
    return np.where(a > ACTION_THRESHOLD, 1, np.where(a < -ACTION_THRESHOLD, -1, 0)).astype(np.int64)


def cell_centres_m() -> np.ndarray:
    """Longitudinal offset of every cell's centre from the ego (m)."""
    return -BEHIND_M + CELL_M * (np.arange(CELLS) + 0.5)


def observation_grid(view, idx: np.ndarray, params: GridParams = GridParams()) -> np.ndarray:
    """Ω_d of vehicles ``idx`` in ``view`` (a world or world view): shape ``(m, 5, 25, 4)``."""
    idx = np.asarray(idx, dtype=np.int64)
    breaks, present, length_m = view.road.existence_table()
    return _grid_kernel(idx, view.s, view.lane, view.v, view.psi, breaks, present, length_m,
                        params.v_max_mps, params.lateral_speed_scale_mps, params.yaw_scale_rad)


@kernel
def _grid_kernel(idx, s, lane, v, psi, breaks, present, length_m, v_max, lat_scale, yaw_scale):
    m = idx.shape[0]
    n = s.shape[0]
    num_lanes = present.shape[1]
    grid = np.zeros((m, 5, 25, 4))
    nearest = np.full((m, 5, 25), np.inf)
    for k in range(m):
        i = idx[k]
        for c in range(25):  # off-road cells: lane lane_i + offset does not exist at s_i + the cell's centre
            sc = min(max(s[i] - 20.0 + 5.0 * (c + 0.5), 0.0), length_m)
            seg = np.searchsorted(breaks, sc, side="right") - 1
            for r in range(5):
                q = lane[i] + r - 2
                if q < 0 or q >= num_lanes or not present[seg, q]:
                    grid[k, r, c, 0] = -1.0
        vlat_i = v[i] * np.sin(psi[i])
        for j in range(n):
            r = lane_column(lane[i], lane[j])  # the grid's rows are the neighbourhood's columns
            if j == i or r < 0:
                continue
            ds = s[j] - s[i]
            c = int(np.floor((ds + 20.0) / 5.0))
            if c < 0 or c > 24:
                continue
            if abs(ds) >= nearest[k, r, c]:
                continue
            nearest[k, r, c] = abs(ds)
            grid[k, r, c, 0] = 1.0
            grid[k, r, c, 1] = (v[j] - v[i]) / v_max
            grid[k, r, c, 2] = (v[j] * np.sin(psi[j]) - vlat_i) / lat_scale
            grid[k, r, c, 3] = (psi[j] - psi[i]) / yaw_scale
    return grid


def forced_merge_targets(view, idx: np.ndarray, within_m: float = FORCED_MERGE_M) -> np.ndarray:
    """The road's mandatory change of each vehicle ``idx``: +1/-1 for a vehicle in a lane that ends
    less than ``within_m`` ahead beside a lane that ends later (left if both neighbours do), else 0."""
    return _forced_merge_kernel(np.asarray(idx, dtype=np.int64), np.asarray(view.lane, dtype=np.int64),
                                np.asarray(view.s, dtype=np.float64),
                                np.asarray(view.road.lane_end_s, dtype=np.float64), float(within_m))


@kernel
def _forced_merge_kernel(idx, lane, s, end, within_m):
    """:func:`forced_merge_targets` over the vehicles ``idx`` (compiled: called on every step)."""
    out = np.zeros(idx.shape[0], dtype=np.int64)
    lanes = end.shape[0]
    for k in range(idx.shape[0]):
        q = lane[idx[k]]
        if end[q] - s[idx[k]] < within_m:
            if q + 1 < lanes and end[q + 1] > end[q]:
                out[k] = 1
            elif 0 <= q - 1 and end[q - 1] > end[q]:
                out[k] = -1
    return out


def forced_merge_requests(view, idx: np.ndarray, requested: np.ndarray, within_m: float = FORCED_MERGE_M) -> np.ndarray:
    """``requested`` with the road's mandatory changes: a vehicle in a lane that ends less than
    ``within_m`` ahead requests the change to the neighbouring lane that ends later (left if
    both do), like level-0's merge rule "except where the road forces a change" (docs/method.md §3.3).

    [choice] A run-time rule of the scenario's learned BVs, not of the training
    environments (the shipped policies were trained without it, as without the emergency
    brake): a policy that keeps its lane at the end of the merge lane — the cooperative
    one, with J_lc -3.0 — otherwise stood there for good, and a BV that had just merged
    beside it, its body still reaching into the merge lane, stood behind it: both lanes
    blocked. The rule constraints still apply to the forced request (it waits for a gap).
    """
    target = forced_merge_targets(view, idx, within_m)
    return np.where(target != 0, target, np.asarray(requested, dtype=np.int64))


def apply_rule_constraints(view, idx: np.ndarray, requested: np.ndarray,
                           closing_headway_s: float = CUT_IN_CLOSING_HEADWAY_S,
                           closing_decel_mps2: float | None = None,
                           end_margin_m: float = LANE_END_MARGIN_M) -> np.ndarray:
    """The executed actions: ``requested`` with the two rule constraints applied (see module docstring).

    ``closing_headway_s``: h of the cut-in gap 10 m + h·c, c the closing speed (0: the
    method's plain 10 m); ``end_margin_m``: a change into a lane that ends less than this far
    ahead becomes keep (``inf``: never into a lane that ends); ``closing_decel_mps2``: b of the further term c²/(2b), the distance
    in which the slower-to-react vehicle of the pair matches speeds braking at b (``None``:
    no such term). Both are the BV profile's (docs/bv-profiles.md, R5).

    [choice] A vehicle counts as in the target lane when it is in it or changing into it
    (its target lane), so two vehicles cannot cut into the same gap from both sides.
    """
    idx = np.asarray(idx, dtype=np.int64)
    req = np.asarray(requested, dtype=np.int64)
    breaks, present_at, length_m = view.road.existence_table()
    lk = view.lane_lookup()
    lane_end_s = np.asarray(view.road.lane_end_s, dtype=float)
    return _constraint_kernel(idx, req, breaks, present_at, length_m, lane_end_s, float(end_margin_m), view.s, view.d, view.psi, view.v, view.lane, view.lane_change,
                              view.target_lane, view.length, view.width, lk.d_right, lk.d_left, lk.present,
                              CUT_IN_GAP_M, float(closing_headway_s),
                              0.0 if closing_decel_mps2 is None else 1.0 / (2.0 * float(closing_decel_mps2)))


@kernel
def _constraint_kernel(idx, req, breaks, present_at, length_m, lane_end_s, end_margin, s, d, psi, v, lane, lane_change, target_lane, length, width,
                       d_right, d_left, present, min_gap, closing_headway, closing_square):
    m = idx.shape[0]
    n = s.shape[0]
    out = np.zeros(m, dtype=np.int64)
    occ = _occupancy(s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left, present, -1)
    for k in range(m):
        r = req[k]
        if r == 0:
            continue
        i = idx[k]
        tgt = lane[i] + r
        seg = np.searchsorted(breaks, min(max(s[i], 0.0), length_m), side="right") - 1
        if tgt < 0 or tgt >= present_at.shape[1] or not present_at[seg, tgt]:  # off-road change -> keep
            continue
        if lane_end_s[tgt] < length_m and lane_end_s[tgt] - s[i] < end_margin:  # into a lane about to end -> keep
            continue
        ok = True
        for j in range(n):
            if j == i or not (target_lane[j] == tgt or occ[j, tgt]):
                continue
            ds = s[j] - s[i]
            closing = v[i] - v[j] if ds > 0.0 else v[j] - v[i]  # how fast the gap to j shrinks
            c = max(closing, 0.0)
            need = min_gap + closing_headway * c + closing_square * c * c
            if abs(ds) - 0.5 * (length[i] + length[j]) < need:  # cut-in within 10 m (+ closing) -> keep
                ok = False
                break
        if ok:
            out[k] = r
    return out


def drivable_area(view, idx: np.ndarray, lane_offset: np.ndarray, front_view_m: float) -> np.ndarray:
    """O: gap to the nearest vehicle ahead in lane ``lane[i] + offset``, bounded by that lane's end and O_max."""
    idx = np.asarray(idx, dtype=np.int64)
    off = np.asarray(lane_offset, dtype=np.int64)
    nb = view.neighborhood()
    gap = nb.gap_front_m[idx, 2 + off]
    lane = view.lane[idx] + off
    to_end = view.road.distance_to_lane_end(lane, view.s[idx]) - 0.5 * view.length[idx]
    to_end = np.where(np.isnan(to_end), 0.0, to_end)
    return np.clip(np.minimum(gap, to_end), 0.0, front_view_m)


def lane_change_gain(o_current: np.ndarray, o_target: np.ndarray, theta: np.ndarray, p: RewardParams) -> np.ndarray:
    """sgn(ϑO_t - O_c)(ϑO_t - O_c)²/M (method §3.2, individual reward, first term)."""
    x = theta * o_target - o_current
    return np.sign(x) * x**2 / p.gain_norm_m2


def lane_change_penalty(kind: str, p: RewardParams) -> float:
    """J_lc of the driver type ``kind`` (mutual, competitive, cooperative)."""
    return {"mutual": p.lane_change_penalty, "competitive": p.comp_lane_change_penalty,
            "cooperative": p.coop_lane_change_penalty}[kind]


def individual_reward(o_current: np.ndarray, o_target: np.ndarray, theta: np.ndarray, requested: np.ndarray,
                      executed: np.ndarray, o_current_next: np.ndarray, p: RewardParams,
                      kind: str = "mutual") -> np.ndarray:
    """r_i = gain + J_lc + J_req + O_c'²/O_max² (method §3.2, individual reward); J_lc of ``kind``."""
    j_lc = np.where(np.asarray(executed) != 0, lane_change_penalty(kind, p), 0.0)
    j_req = np.where(np.asarray(requested) != np.asarray(executed), p.request_penalty, 0.0)
    return (lane_change_gain(o_current, o_target, theta, p) + j_lc + j_req
            + np.asarray(o_current_next) ** 2 / p.front_view_m**2)


def back_vehicles(view, i: int) -> np.ndarray:
    """Ω_b of vehicle ``i``: indices of the vehicles in the back part of its grid."""
    ds = view.s - view.s[i]
    dl = view.lane - view.lane[i]
    mask = (ds >= -BEHIND_M) & (ds < 0.0) & (np.abs(dl) <= 2)
    mask[i] = False
    return np.flatnonzero(mask)


def social_terms(view, i: int, p: RewardParams) -> tuple[float, float, float]:
    """Σ_b (ϑO_c^b)²/O_max², Σ_b min(s̈_b|s̈_b|/s̈_max², z), Σ_b min(ṡ_b|ṡ_b|/ṡ_max², y) over Ω_b of ``i``."""
    b = back_vehicles(view, i)
    if b.size == 0:
        return 0.0, 0.0, 0.0
    o_b = drivable_area(view, b, np.zeros(b.size, dtype=np.int64), p.front_view_m)
    theta = np.where(view.lane[b] > view.lane[i], p.theta_left, 1.0)
    space = float(np.sum((theta * o_b) ** 2) / p.front_view_m**2)
    a = view.accel[b]
    brake = float(np.sum(np.minimum(a * np.abs(a) / p.accel_norm_mps2**2, p.comp_brake_bound)))
    v = view.v[b]
    speed = float(np.sum(np.minimum(v * np.abs(v) / p.speed_norm_mps**2, p.coop_speed_bound)))
    return space, brake, speed


def social_reward(kind: str, space: float, brake: float, speed: float, p: RewardParams) -> float:
    """The social part of the reward of ``kind`` (mutual: 0; method §3.2)."""
    if kind == "mutual":
        return 0.0
    if kind == "competitive":
        return -p.comp_space_weight * space - p.comp_brake_weight * brake
    if kind == "cooperative":
        return p.coop_space_weight * space + p.coop_speed_weight * speed
    raise ValueError(f"unknown reward kind {kind!r}: expected mutual, competitive or cooperative")


@dataclass(frozen=True)
class MergeSeekParams:
    """The merge's speed adaptation (:func:`merge_seek_accel`; docs/learned-bvs.md, "Merging").

    [choice] An IDM regulator (Treiber, Hennecke, Helbing 2000) on the blocking vehicle of the
    target lane, its desired gap the cut-in gap the rule constraints ask for; a = 1.0 m/s²,
    b = 1.5 m/s², T = 1.0 s, δ = 4 are Treiber's highway values; braking bounded at 3 m/s²,
    below MOBIL's b_safe of 4 m/s² (a driver dropping back to slot in brakes, but not hard).
    """

    accel_mps2: float = 1.0
    comfortable_decel_mps2: float = 1.5
    time_headway_s: float = 1.0
    delta: float = 4.0
    max_decel_mps2: float = 3.0


def merge_seek_accel(view, idx: np.ndarray, targets: np.ndarray, desired_speed: np.ndarray,
                     closing_headway_s: float = CUT_IN_CLOSING_HEADWAY_S,
                     closing_decel_mps2: float | None = None,
                     params: MergeSeekParams = MergeSeekParams()) -> np.ndarray:
    """Acceleration bound (m/s², ``inf`` for none) of each vehicle ``idx`` that must merge.

    A vehicle with ``targets[k]`` != 0 (the forced merge's target lane offset) that is not
    changing lanes finds the vehicles of the target lane that block its change — those the
    rule constraints (:func:`apply_rule_constraints`) would refuse it for: bumper gap below
    10 m + h·c (+ c²/(2b)) — among those ahead of it or alongside (whose front is ahead of its
    rear), and drops back behind the rearmost of them: the bound is the IDM
    acceleration towards it as a leader, with the cut-in gap as the desired gap (negative
    gaps, a blocker alongside, brake at ``max_decel_mps2``). With no blocker there is no bound
    (the change goes ahead at the next decision). A vehicle wholly behind it never makes it
    brake: braking for a faster vehicle behind only raises the closing speed, and with it the
    gap the change needs (tried: the merging BVs braked to a standstill).

    [choice] Why (docs/learned-bvs.md, "Merging"): the decision policies only choose lanes, and
    the car-following controller regulates the gap to the vehicle ahead in the vehicle's own
    lane, so a BV beside traffic at its own speed kept beside it until the merge lane ended,
    stopped there and later merged at a crawl in front of traffic 30 m/s faster — six of seven
    BV–BV collisions of the traffic window. Drivers on an acceleration lane adapt their speed to
    a gap; SUMO's LC2013 likewise adapts the speed of a vehicle that must change lanes.
    """
    idx = np.asarray(idx, dtype=np.int64)
    lk = view.lane_lookup()
    return _merge_seek_kernel(idx, np.asarray(targets, dtype=np.int64), np.asarray(desired_speed, dtype=float),
                              view.s, view.d, view.psi, view.v, view.lane, view.lane_change, view.target_lane,
                              view.length, view.width, lk.d_right, lk.d_left, lk.present, CUT_IN_GAP_M,
                              float(closing_headway_s),
                              0.0 if not closing_decel_mps2 else 1.0 / (2.0 * float(closing_decel_mps2)),
                              params.accel_mps2, params.comfortable_decel_mps2, params.time_headway_s, params.delta,
                              params.max_decel_mps2)


@kernel
def _merge_seek_kernel(idx, targets, desired, s, d, psi, v, lane, lane_change, target_lane, length, width,
                       d_right, d_left, present, min_gap, closing_headway, closing_square, a_max, b_comf, headway,
                       delta, b_max):
    m = idx.shape[0]
    n = s.shape[0]
    out = np.full(m, np.inf)
    occ = _occupancy(s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left, present, -1)
    for k in range(m):
        i = idx[k]
        if targets[k] == 0 or lane_change[i] != 0:
            continue
        tgt = lane[i] + targets[k]
        if tgt < 0 or tgt >= present.shape[1]:
            continue
        best = -1
        for j in range(n):  # the rearmost blocker in the target lane
            if j == i or not (target_lane[j] == tgt or occ[j, tgt]):
                continue
            ds = s[j] - s[i]
            closing = v[i] - v[j] if ds > 0.0 else v[j] - v[i]
            c = max(closing, 0.0)
            need = min_gap + closing_headway * c + closing_square * c * c
            if ds + 0.5 * (length[i] + length[j]) <= 0.0:  # wholly behind: it passes or stays behind
                continue
            if abs(ds) - 0.5 * (length[i] + length[j]) < need and (best < 0 or s[j] < s[best]):
                best = j
        if best < 0:
            continue
        gap = s[best] - s[i] - 0.5 * (length[i] + length[best])
        dv = v[i] - v[best]
        c = max(dv, 0.0)
        s_star = min_gap + closing_headway * c + closing_square * c * c + v[i] * headway \
            + v[i] * dv / (2.0 * np.sqrt(a_max * b_comf))
        s_star = max(s_star, min_gap)
        v0 = max(desired[k], 1.0)
        if gap <= 0.1:
            acc = -b_max
        else:
            acc = a_max * (1.0 - (v[i] / v0) ** delta - (s_star / gap) ** 2)
        out[k] = max(acc, -b_max)
    return out
