"""The learned car-following controller (docs/method.md §3.1): observation, reward, throttle.

Observation of vehicle ``i`` (method §3.1), relative to the nearest vehicle ahead in its
lane within the view ``o_smax``::

    s = [Δs / o_smax, Δṡ / v_max, Δs̈ / a_max, λ]

with Δs the bumper-to-bumper gap (m), Δṡ = v_leader - v_i, Δs̈ = a_leader - a_i, λ = 1 when
such a leader is in view, else 0 and the three differences are 0.

[choice] ``own_accel_in_observation`` (default true: the method's Δs̈). False puts the
leader's acceleration alone in the third slot, a_leader / a_max. The reason: the BV's own
acceleration is the one input that answers the policy's command within one step (throttle
at step k is the acceleration observed at k + 1), so a trained gain above 1 on it closes a
period-2 loop — the controllers trained with V at the view's edge alternated ±2.5 m/s²
every step behind a steady leader (docs/learned-bvs.md). Without it the policy's feedback
runs through the gap and the speed difference only, which integrate its command.

Reward (docs/method.md eqs. (1)-(2))::

    r = -C                           on a collision
    r = μ V(s') + k (V(s') - V(s))   otherwise,   V(s) = -(Δs - g)² / V_max²

[choice] target gap g = 25 m (the method's policies settle at 24-27 m), V_max = o_smax
= 100 m, μ = 1, k = 10, C = 10; without a leader in view V = 0 (nothing to regulate).

[choice] Free road. The method's controller regulates a gap; it has no desired speed. A
learned BV therefore also has a desired speed ``v_des`` (drawn per vehicle like level-0's,
capped by the lane's speed limit) and its throttle is
``min(π(s), k_v (v_des - v) / a_scale)``: the proportional speed term takes over on a free
road and caps the speed behind a fast leader. Training uses the same composition.

The end of the merge lane counts as a standing leader (as for level-0 traffic), so a BV
that finds no gap waits there instead of running off the road.

[choice] Leaders. A BV follows the nearest vehicle ahead *occupying* its lane: in it, or
changing lanes into it — a merging vehicle's body reaches into the target lane before its
centre crosses, and a follower there must see it (without this, most collisions among
learned BVs were vehicles in lane II running into a merging vehicle that had stopped
half-way). While changing lanes it also follows the target lane's leader.

[choice] Committed lane changes. While a BV changes lanes the controller regulates the gap
to the *target* lane's leader only; the leader in the lane it leaves only bounds the
throttle through the emergency brake below. A vehicle at rest cannot move sideways: with
the gap regulator on the old lane's leader (target gap 25 m), a BV that began to merge
behind a queue stopped ~18 m behind it, half in each lane, for good — and the lanes
behind it jammed.

[choice] Emergency brake. The method's controller regulates the gap to a target; trained
on 2 CPU cores it brakes too late for a standing queue met at highway speed (from 31 m/s it
hit a standing vehicle first seen 95 m ahead). Every learned BV therefore also bounds its
throttle by an emergency brake: with closing speed Δv = v - v_leader > 0 and gap Δs, the
constant deceleration that matches the leader's speed at a margin m is
b = Δv² / (2 (Δs - m)) — and behind a braking leader (deceleration b_l) the one that stops
behind the point where it stops, v² / (2 (Δs - m + v_l² / (2 b_l))), if larger; when b ≥
``emergency_decel_mps2`` (4 m/s², MOBIL's b_safe) the throttle is at most -b / b_max. It acts only where the policy's own braking is too weak;
it is part of the run-time driver, so the decision policies are trained with it; the
controller itself is trained without it (trained with it, it leaned on it: a tenth of its
evaluation gaps fell under 2 m).

Profiles (``models.learned.profile``; docs/bv-profiles.md). The above is the ``safety_net``
profile: every leader is followed from the first step it occupies the lane, and the
emergency brake acts at once, up to the full brake. The ``driver`` profile
(:class:`ReactionState`, :func:`_driver_throttle_kernel`) gives the BV a driver's limits:
a vehicle is perceived as a leader in a lane only once it has occupied that lane ahead of
the BV for the reaction time τ (N = round(τ/dt) steps), the emergency brake acts only once
the BV has been alerted (trigger reached on the leaders actually there) for N steps, and
every braking command is bounded by ``max_decel_mps2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evoscen_sim.jit import kernel

OBS_DIM = 4


@dataclass(frozen=True)
class CarFollowingParams:
    """Observation scales, reward coefficients and the free-road speed term (see module docstring)."""

    view_m: float = 100.0
    """o_smax: the view ahead (m); also the gap normaliser."""
    v_max_mps: float = 33.33
    """v_max: speed-difference normaliser (m/s), 120 km/h."""
    a_max_mps2: float = 8.0
    """a_max: acceleration-difference normaliser (m/s²), the braking limit."""
    target_gap_m: float = 25.0
    """g: target bumper-to-bumper gap (m) [choice]."""
    value_scale_m: float = 100.0
    """V_max of V(s) = -(Δs - g)² / V_max² (m) [choice]."""
    mu: float = 1.0
    """μ: weight of V(s') [choice]."""
    k: float = 10.0
    """k: weight of the improvement V(s') - V(s) [choice]."""
    collision_penalty: float = 10.0
    """C: reward -C on a collision [choice]."""
    speed_gain: float = 0.5
    """k_v: free-road speed term, throttle per (m/s) of speed error, as accel (1/s) [choice]."""
    merge_stop_margin_m: float = 60.0
    """The merge lane's end is a standing leader this far before the lane ends (m) [choice:
    60 m = where the taper begins (900 m), so a BV that finds no gap waits at full lane width
    instead of in the taper, where its body would reach into lane II]."""
    emergency_decel_mps2: float = 4.0
    """The emergency brake acts when matching the leader's speed before the margin needs at
    least this constant deceleration (m/s²) [choice: MOBIL's safe braking b_safe]."""
    emergency_margin_m: float = 2.0
    """Bumper gap the emergency brake keeps to a slower leader (m) [choice]."""
    no_leader_at_view_edge: bool = False
    """V(s) without a leader in view: 0 (False, the form every shipped controller was trained
    with) or the value at the view's edge, Δs = o_smax (True). [choice] Both have a measured
    defect (docs/method.md §3.1): with 0, losing the leader from view pays k·(0 − V(95 m))
    ≈ +4.9 at once and the shipped controller brakes hard for leaders 80–100 m ahead; with the
    edge value that incentive is gone, but the controllers trained so fall into a period-2
    limit cycle (±2.5 m/s² every step) while following."""
    own_accel_in_observation: bool = True
    """The observation's third slot: (a_leader − a_i) / a_max, the method's Δs̈ (True), or
    a_leader / a_max (False) [choice, see the module docstring]. A policy runs with the value
    it was trained with (its directory's training.yaml)."""

    @property
    def own_accel_weight(self) -> float:
        """w in the third slot (a_leader − w a_i) / a_max: 1 (the method's Δs̈) or 0."""
        return 1.0 if self.own_accel_in_observation else 0.0


def leader_state(gap_m: np.ndarray, leader_speed: np.ndarray, leader_accel: np.ndarray,
                 speed: np.ndarray, accel: np.ndarray, params: CarFollowingParams) -> np.ndarray:
    """Observations (m, 4) of vehicles with speeds/accels ``speed``/``accel`` behind their leaders.

    ``gap_m`` is ``inf`` (and the leader's speed/accel ``nan``) without a leader.
    """
    return _obs_kernel(np.asarray(gap_m, float), np.asarray(leader_speed, float), np.asarray(leader_accel, float),
                       np.asarray(speed, float), np.asarray(accel, float),
                       params.view_m, params.v_max_mps, params.a_max_mps2, params.own_accel_weight)


@kernel
def _obs_kernel(gap, v_lead, a_lead, v, a, view, v_max, a_max, own_w):
    m = gap.shape[0]
    obs = np.zeros((m, 4))
    for k in range(m):
        if gap[k] <= view and not np.isnan(v_lead[k]):  # method §3.1: a leader in view
            obs[k, 0] = gap[k] / view
            obs[k, 1] = (v_lead[k] - v[k]) / v_max
            obs[k, 2] = (a_lead[k] - own_w * a[k]) / a_max  # own_w = 1: the method's Δs̈ (exact: 1.0 * a == a)
            obs[k, 3] = 1.0
    return obs


def gap_value(obs: np.ndarray, params: CarFollowingParams) -> np.ndarray:
    """V(s) = -(Δs - g)² / V_max² (docs/method.md eq. (2)); without a leader in view V = 0, or the
    value at Δs = o_smax with ``params.no_leader_at_view_edge``."""
    obs = np.atleast_2d(obs)
    gap = obs[:, 0] * params.view_m
    v = -((gap - params.target_gap_m) ** 2) / params.value_scale_m**2
    free = -((params.view_m - params.target_gap_m) ** 2) / params.value_scale_m**2 if params.no_leader_at_view_edge \
        else 0.0
    return np.where(obs[:, 3] > 0.5, v, free)


def car_following_reward(obs: np.ndarray, next_obs: np.ndarray, collided: np.ndarray,
                         params: CarFollowingParams) -> np.ndarray:
    """r = -C on collision, else μ V(s') + k (V(s') - V(s)) (docs/method.md eq. (1))."""
    v0 = gap_value(obs, params)
    v1 = gap_value(next_obs, params)
    return np.where(np.asarray(collided, bool), -params.collision_penalty, params.mu * v1 + params.k * (v1 - v0))


def speed_cap_throttle(speed: np.ndarray, desired_speed: np.ndarray, params: CarFollowingParams,
                       max_accel: float, max_brake: float) -> np.ndarray:
    """The free-road speed term k_v (v_des - v), as a throttle/brake command in [-1, 1]."""
    acc = params.speed_gain * (np.asarray(desired_speed) - np.asarray(speed))
    return np.clip(np.where(acc >= 0.0, acc / max_accel, acc / max_brake), -1.0, 1.0)


def leaders(view, idx: np.ndarray, params: CarFollowingParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The leaders a learned BV follows: ``(gap, speed, accel)``, each ``(m, 2)``.

    A vehicle *occupies* a lane when its centre is in it, when it is changing lanes into it
    (its target lane), or when its body reaches into it (the lateral extent
    ½(W cos ψ + L |sin ψ|) around its centre crosses the lane's border by more than
    ``OCCUPY_TOLERANCE_M``: a vehicle straddling two lanes, mid-change or just after).
    Column 0: the nearest vehicle ahead occupying the BV's lane; on the merge lane, the
    lane's standing end when nearer (not while changing lanes: a vehicle that stopped at the line
    mid-change would stand across two lanes).
    Column 1: the same for the BV's second lane — its target lane while changing lanes,
    else the neighbouring lane its own body reaches into, else column 0 again. "Ahead":
    larger ``s``, or equal ``s`` and a larger index (as the neighbourhood's). No leader: gap
    ``inf``, speed and acceleration ``nan``.
    """
    lk = view.lane_lookup()
    return _leaders_kernel(np.asarray(idx, dtype=np.int64), view.s, view.d, view.psi, view.v, view.accel, view.lane,
                           view.lane_change, view.target_lane, view.length, view.width,
                           lk.d_right, lk.d_left, lk.present,
                           float(view.road.lane_end_s[0]) - params.merge_stop_margin_m)


OCCUPY_TOLERANCE_M = 0.1
"""A body must cross a lane's border by more than this to occupy the lane (m)."""


@kernel
def _occupancy(s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left, present, no_intent):
    """occ[j, q]: vehicle ``j`` occupies lane ``q`` (see :func:`leaders`; one pass, no sub-calls:
    numba reference-counts every array handed to a sub-function, which cost more than the test).

    ``no_intent``: the vehicle whose lane-change *intent* does not count (-1: none): while it
    changes lanes it occupies its target lane only once its body reaches into it (the geometric
    rule), not from its request on. With the SUT: what a BV that does not yield early sees
    (``models.learned.competitive_cut_in``, docs/learned-bvs.md "Competitive BVs and a SUT cutting
    in"; :func:`_late_occupancy`)."""
    n, num_lanes = present.shape
    occ = np.zeros((n, num_lanes), dtype=np.bool_)
    for j in range(n):
        occ[j, lane[j]] = True
        if lane_change[j] != 0 and j != no_intent:
            occ[j, target_lane[j]] = True
        e = 0.5 * (width[j] * np.cos(psi[j]) + length[j] * abs(np.sin(psi[j])))
        for q in (lane[j] - 1, lane[j] + 1):
            if 0 <= q < num_lanes and present[j, q] and d[j] + e > d_right[j, q] + OCCUPY_TOLERANCE_M \
                    and d[j] - e < d_left[j, q] - OCCUPY_TOLERANCE_M:
                occ[j, q] = True
    return occ


@kernel
def _late_occupancy(occ, sut, late, s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left,
                    present):
    """The occupancy the vehicles with ``late[k]`` read: ``occ`` with the SUT's lane-change intent
    not counted (:func:`_occupancy` with ``no_intent = sut``), computed only when it differs from
    ``occ`` and is read (the SUT changes lanes and a vehicle does not yield on it); else ``occ``."""
    if sut < 0 or lane_change[sut] == 0 or not late.any():
        return occ
    return _occupancy(s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left, present, sut)


@kernel
def _leaders_kernel(idx, s, d, psi, v, a, lane, lane_change, target_lane, length, width,
                    d_right, d_left, present, merge_stop_s):
    occ = _occupancy(s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left, present, -1)
    return _nearest_leaders(idx, s, v, a, lane, lane_change, target_lane, length, present, merge_stop_s, occ,
                            _ALL_SEEN, 0, occ, np.zeros(idx.shape[0], dtype=np.bool_))


_ALL_SEEN = np.zeros((0, 0, 0), dtype=np.int64)
"""``seen`` of :func:`_nearest_leaders` when every vehicle is perceived (``full = 0``: never read)."""


@kernel
def _nearest_leaders(idx, s, v, a, lane, lane_change, target_lane, length, present,
                     merge_stop_s, occ, seen, full, occ_late, late):
    """:func:`leaders` from the occupancy ``occ`` (:func:`_occupancy`), over the perceived vehicles
    only (``seen[k, j, q] >= full``) when ``full > 0`` (the ``driver`` profile), over all when 0.
    Hosted vehicles with ``late[k]`` read ``occ_late`` instead (:func:`_late_occupancy`: the SUT's
    lane-change intent not counted) while they keep their lane: one changing lanes itself watches
    its target lane as every BV does."""
    m = idx.shape[0]
    n, num_lanes = present.shape
    gap = np.full((m, 2), np.inf)
    vl = np.full((m, 2), np.nan)
    al = np.full((m, 2), np.nan)
    for k in range(m):
        i = idx[k]
        second = lane[i]
        if lane_change[i] != 0:
            second = target_lane[i]
        else:
            for q in (lane[i] - 1, lane[i] + 1):
                if 0 <= q < num_lanes and occ[i, q]:
                    second = q
        for slot in range(2):
            q = lane[i] if slot == 0 else second
            if slot == 1 and q == lane[i]:  # one lane: column 1 = column 0
                gap[k, 1], vl[k, 1], al[k, 1] = gap[k, 0], vl[k, 0], al[k, 0]
                break
            best = -1
            best_ds = np.inf
            o = occ_late if late[k] and lane_change[i] == 0 else occ
            for j in range(n):  # the nearest (perceived) vehicle ahead occupying lane q
                if j == i or not o[j, q] or (full > 0 and seen[k, j, q] < full):
                    continue
                ds = s[j] - s[i]
                if ds < 0.0 or (ds == 0.0 and j < i) or ds >= best_ds:
                    continue
                best_ds = ds
                best = j
            if best >= 0:
                gap[k, slot] = best_ds - 0.5 * (length[i] + length[best])
                vl[k, slot] = v[best]
                al[k, slot] = a[best]
            if slot == 0 and lane[i] == 0 and lane_change[i] == 0:  # the merge lane's end is a standing leader
                end_gap = merge_stop_s - (s[i] + 0.5 * length[i])
                if end_gap < gap[k, 0]:
                    gap[k, 0], vl[k, 0], al[k, 0] = end_gap, 0.0, 0.0
    return gap, vl, al


def controller_observations(world, idx: np.ndarray, params: CarFollowingParams) -> tuple[np.ndarray, np.ndarray]:
    """Controller observations of vehicles ``idx``: own lane (with the merge end) and target lane.

    Returns ``(own, target)``, each ``(m, 4)``, of the leaders of :func:`leaders`; ``target``
    equals ``own`` for vehicles not changing lanes. While a vehicle changes lanes its throttle
    is the smaller of the two commands (it follows the nearer-braking leader, as level-0
    traffic does).
    """
    gap, vl, al = leaders(world, idx, params)
    v, a = world.v[idx], world.accel[idx]
    own = leader_state(gap[:, 0], vl[:, 0], al[:, 0], v, a, params)
    target = leader_state(gap[:, 1], vl[:, 1], al[:, 1], v, a, params)
    return own, target


def emergency_brake_throttle(gap_m: np.ndarray, leader_speed: np.ndarray, speed: np.ndarray,
                             params: CarFollowingParams, max_brake: float,
                             leader_accel: np.ndarray | float = 0.0) -> np.ndarray:
    """The emergency-brake bound on the throttle (1 where it does not act), see the module docstring."""
    gap, vl, v, al = np.broadcast_arrays(np.asarray(gap_m, float), np.asarray(leader_speed, float),
                                         np.asarray(speed, float), np.asarray(leader_accel, float))
    out = np.ones(gap.shape)
    for k in np.ndindex(out.shape):
        out[k] = _emergency_one(float(gap[k]), float(vl[k]), float(al[k]), float(v[k]),
                                params.emergency_decel_mps2, params.emergency_margin_m, max_brake)
    return out


@kernel
def _emergency_need(gap, vl, al, v, margin):
    """The constant deceleration the emergency brake asks for (0: none), scalars only."""
    room = max(gap - margin, 0.05)
    need = 0.0
    if v > vl:  # match the leader's speed before the margin
        need = (v - vl) * (v - vl) / (2.0 * room)
    if al < 0.0 and v > 0.0:  # a braking leader: stop behind the point where it stops
        need = max(need, v * v / (2.0 * (room + vl * vl / (2.0 * -al))))
    return need


@kernel
def _emergency_one(gap, vl, al, v, trigger, margin, max_brake):
    """Throttle bound of the emergency brake for one leader (1.0: not acting)."""
    if np.isnan(vl):
        return 1.0
    need = _emergency_need(gap, vl, 0.0 if np.isnan(al) else al, v, margin)
    if need < trigger:
        return 1.0
    return -min(need / max_brake, 1.0)


def compose_throttle(policy_own: np.ndarray, policy_target: np.ndarray, own_obs: np.ndarray,
                     target_obs: np.ndarray, cap: np.ndarray, changing: np.ndarray | None = None) -> np.ndarray:
    """Throttle = min over the leaders in view of the policy's command, and the speed cap
    (pass the emergency-brake bound folded into ``cap``); where ``changing``, the own (old)
    lane's leader is not regulated to (see the module docstring)."""
    big = np.inf
    own_seen = own_obs[:, 3] > 0.5
    if changing is not None:
        own_seen = own_seen & ~np.asarray(changing, bool)
    u_own = np.where(own_seen, policy_own, big)
    u_tgt = np.where(target_obs[:, 3] > 0.5, policy_target, big)
    return np.clip(np.minimum(np.minimum(u_own, u_tgt), cap), -1.0, 1.0)


def throttle_constants(bank, params: CarFollowingParams, road, max_accel: float, max_brake: float) -> tuple:
    """The run-time throttle's per-driver constants (computed once per driver, see :func:`learned_throttle`)."""
    return (float(road.lane_end_s[0]) - params.merge_stop_margin_m,
            params.view_m, params.v_max_mps, params.a_max_mps2, params.own_accel_weight, params.speed_gain,
            params.emergency_decel_mps2, params.emergency_margin_m, float(max_accel), float(max_brake),
            bank.W1[0], bank.b1[0], bank.W2[0], bank.b2[0], bank.W3[0], float(bank.b3[0]), float(bank.max_action[0]))


class ReactionState:
    """The ``driver`` profile's memory of one driver (docs/bv-profiles.md, "reaction time").

    Args:
        hosted: number of hosted vehicles.
        reaction_steps: N = round(τ / dt); a situation must hold at steps t - N … t.
        cap_frac: bound on braking as a fraction of the full brake (max_decel / max_brake;
            1.0: no bound).
        standing_at_once: the emergency brake acts without waiting for the alert for a
            perceived leader that stands still.
    """

    def __init__(self, hosted: int, reaction_steps: int, cap_frac: float, standing_at_once: bool = False) -> None:
        self.n_react = int(reaction_steps)
        self.cap_frac = float(cap_frac)
        self.standing_at_once = bool(standing_at_once)
        """The emergency brake acts at once for a perceived leader standing still (R2)."""
        self.hosted = int(hosted)
        self.seen: np.ndarray | None = None
        self.em_count = np.full(self.hosted, -1, dtype=np.int64)
        """-1 until the first step; there every situation already present counts as having
        persisted (nothing is new at the start of a run)."""
        self.last_step: int | None = None

    def advance(self, view) -> bool:
        """True once per simulation step (the first call at a new ``step_index``)."""
        n, lanes = view.lane_lookup().present.shape
        if self.seen is None or self.seen.shape[1] != n:
            self.seen = np.full((self.hosted, n, lanes), self.n_react, dtype=np.int64)
        step = int(view.step_index)
        if step == self.last_step:
            return False
        self.last_step = step
        return True


def learned_throttle(view, idx: np.ndarray, desired_speed: np.ndarray, bank, params: CarFollowingParams,
                     max_accel: float, max_brake: float, constants: tuple | None = None,
                     reaction: ReactionState | None = None, late: np.ndarray | None = None,
                     sut: int = -1, max_speed: np.ndarray | None = None) -> np.ndarray:
    """The run-time throttle of vehicles ``idx``, fused into one compiled pass.

    The same quantities as :func:`controller_observations`, the controller's forward pass
    (``bank``: a one-actor :class:`evoscen_bv.learned.PolicyBank`), :func:`speed_cap_throttle`,
    :func:`emergency_brake_throttle` and :func:`compose_throttle` (a test checks they agree);
    fused because for ~20 vehicles numpy's per-call overhead, not arithmetic, would dominate
    the step. ``constants``: :func:`throttle_constants` of these arguments, if the caller keeps them.
    ``reaction``: the ``driver`` profile's state (:class:`ReactionState`; docs/bv-profiles.md);
    ``None``: the ``safety_net`` profile (instant reaction, braking up to the full brake).
    ``late``: per vehicle of ``idx``, True where it does not yield to the SUT's lane-change intent
    (:func:`_late_occupancy`; ``sut``: the SUT's row, -1 none); ``None``: every vehicle yields on it.
    ``max_speed``: the lane limits that cap the desired speed, as the lane look-up's ``max_speed_mps``
    (None: the lane look-up's; all NaN: no cap, the kernels' "no limit").
    """
    idx = np.asarray(idx, dtype=np.int64)
    late = np.zeros(idx.shape[0], dtype=np.bool_) if late is None else np.asarray(late, dtype=np.bool_)
    if constants is None:
        constants = throttle_constants(bank, params, view.road, max_accel, max_brake)
    lk = view.lane_lookup()
    args = (np.asarray(idx, dtype=np.int64), view.s, view.d, view.psi, view.v, view.accel, view.lane, view.lane_change,
            view.target_lane, view.length, view.width, lk.d_right, lk.d_left, lk.present,
            lk.max_speed_mps if max_speed is None else max_speed,
            np.asarray(desired_speed, dtype=float), *constants)
    if reaction is None:  # the safety_net profile
        return _learned_throttle_kernel(*args, late, np.int64(sut))
    update = reaction.advance(view)
    return _driver_throttle_kernel(*args, np.int64(reaction.n_react), reaction.seen, reaction.em_count, update,
                                   reaction.cap_frac, reaction.standing_at_once, late, np.int64(sut))


@kernel
def _learned_throttle_kernel(idx, s, d, psi, v, a, lane, lane_change, target_lane, length, width,
                             d_right, d_left, present, max_speed, desired, merge_stop_s, view, v_max, a_max, own_w,
                             speed_gain, em_trigger, em_margin, max_accel, max_brake, W1, b1, W2, b2, W3, b3, max_action,
                             late, sut):
    """The ``safety_net`` profile: every leader at once, the emergency brake at once and uncapped."""
    occ = _occupancy(s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left, present, -1)
    occ_late = _late_occupancy(occ, sut, late, s, d, psi, lane, lane_change, target_lane, length, width, d_right,
                               d_left, present)
    gap_all, vl_all, al_all = _nearest_leaders(idx, s, v, a, lane, lane_change, target_lane, length, present,
                                               merge_stop_s, occ, _ALL_SEEN, 0, occ_late, late)
    em_on = np.ones(idx.shape[0], dtype=np.bool_)
    return _throttle_from_leaders(idx, gap_all, vl_all, al_all, v, a, lane, lane_change, max_speed, desired, view,
                                  v_max, a_max, own_w, speed_gain, em_trigger, em_margin, max_accel, max_brake,
                                  W1, b1, W2, b2, W3, b3, max_action, em_on, False, 1.0)


@kernel
def _driver_throttle_kernel(idx, s, d, psi, v, a, lane, lane_change, target_lane, length, width,
                            d_right, d_left, present, max_speed, desired, merge_stop_s, view, v_max, a_max, own_w,
                            speed_gain, em_trigger, em_margin, max_accel, max_brake, W1, b1, W2, b2, W3, b3, max_action,
                            n_react, seen, em_count, update, cap_frac, standing_at_once, late, sut):
    """The ``driver`` profile (docs/bv-profiles.md): reaction time and bounded braking.

    ``seen[k, j, q]``: consecutive steps (capped at N + 1) vehicle ``j`` has occupied lane
    ``q`` ahead of hosted vehicle ``k``; ``j`` is perceived in lane ``q`` when it reaches
    N + 1 (it occupied the lane ahead at steps t - N … t). ``em_count[k]``: steps since the
    driver was alerted — the emergency brake's trigger held on the leaders actually there —
    counting on while it still closes in on one of them (need > 0) and reset to 0 when it no
    longer does; the brake acts (with its usual trigger, on the perceived leaders) once the
    count reaches N + 1. Both advance only when ``update`` (once per simulation step).
    With ``standing_at_once`` the brake also acts, unalerted, on a perceived leader at rest.
    """
    m = idx.shape[0]
    n, num_lanes = present.shape
    full = n_react + 1
    occ = _occupancy(s, d, psi, lane, lane_change, target_lane, length, width, d_right, d_left, present, -1)
    occ_late = _late_occupancy(occ, sut, late, s, d, psi, lane, lane_change, target_lane, length, width, d_right,
                               d_left, present)
    if update:
        for k in range(m):
            i = idx[k]
            o = occ_late if late[k] and lane_change[i] == 0 else occ
            for j in range(n):
                ahead = j != i and (s[j] > s[i] or (s[j] == s[i] and j > i))
                for q in range(num_lanes):
                    if ahead and o[j, q]:
                        seen[k, j, q] = min(seen[k, j, q] + 1, full)
                    else:
                        seen[k, j, q] = 0
        gap_a, vl_a, al_a = _nearest_leaders(idx, s, v, a, lane, lane_change, target_lane, length, present,
                                             merge_stop_s, occ, _ALL_SEEN, 0, occ_late, late)
        for k in range(m):
            need = 0.0
            for slot in range(2):
                if not np.isnan(vl_a[k, slot]):
                    al = 0.0 if np.isnan(al_a[k, slot]) else al_a[k, slot]
                    need = max(need, _emergency_need(gap_a[k, slot], vl_a[k, slot], al, v[idx[k]], em_margin))
            if em_count[k] < 0:  # the first step: a situation already there has persisted
                em_count[k] = full if need >= em_trigger else 0
            elif need >= em_trigger or (em_count[k] > 0 and need > 0.0):  # alerted, and still closing in
                em_count[k] = min(em_count[k] + 1, full)
            else:
                em_count[k] = 0
    gap_all, vl_all, al_all = _nearest_leaders(idx, s, v, a, lane, lane_change, target_lane, length, present,
                                               merge_stop_s, occ, seen, full, occ_late, late)
    em_on = np.empty(m, dtype=np.bool_)
    for k in range(m):
        em_on[k] = em_count[k] >= full
    return _throttle_from_leaders(idx, gap_all, vl_all, al_all, v, a, lane, lane_change, max_speed, desired, view,
                                  v_max, a_max, own_w, speed_gain, em_trigger, em_margin, max_accel, max_brake,
                                  W1, b1, W2, b2, W3, b3, max_action, em_on, standing_at_once, cap_frac)


@kernel
def _throttle_from_leaders(idx, gap_all, vl_all, al_all, v, a, lane, lane_change, max_speed, desired,
                           view, v_max, a_max, own_w, speed_gain, em_trigger, em_margin, max_accel, max_brake,
                           W1, b1, W2, b2, W3, b3, max_action, em_on, em_standing, cap_frac):
    m = idx.shape[0]
    out = np.empty(m)
    h = W1.shape[1]
    h1 = np.empty(h)
    h2 = np.empty(h)
    x = np.zeros(4)
    for k in range(m):
        i = idx[k]
        # free-road speed term, capped by the lane's limit (none past a lane's end: NaN)
        limit = max_speed[i, lane[i]]
        v_des = desired[k] if np.isnan(limit) else min(desired[k], limit)
        acc = speed_gain * (v_des - v[i])
        u = acc / max_accel if acc >= 0.0 else acc / max_brake
        u = min(max(u, -1.0), 1.0)
        for slot in range(2):
            gap, vl, al = gap_all[k, slot], vl_all[k, slot], al_all[k, slot]
            if slot == 1 and gap == gap_all[k, 0] and vl == vl_all[k, 0] and al == al_all[k, 0]:
                break  # one lane, or the same leader twice
            regulate = slot == 1 or lane_change[i] == 0  # changing lanes: the old lane's leader only bounds (see leaders)
            if regulate and gap <= view and not np.isnan(vl):  # a leader in view: the controller's command
                x[0] = gap / view
                x[1] = (vl - v[i]) / v_max
                x[2] = (al - own_w * a[i]) / a_max  # own_w = 1: the method's Δs̈
                x[3] = 1.0
                # max_action · tanh(W3 relu(W2 relu(W1 x + b1) + b2) + b3), inline (as PolicyBank's kernel)
                for q in range(h):
                    h1[q] = b1[q]
                for c in range(4):
                    if x[c] != 0.0:
                        for q in range(h):
                            h1[q] += x[c] * W1[c, q]
                for q in range(h):
                    h2[q] = b2[q]
                for c in range(h):
                    hc = max(h1[c], 0.0)
                    if hc != 0.0:
                        for q in range(h):
                            h2[q] += hc * W2[c, q]
                z = b3
                for q in range(h):
                    z += max(h2[q], 0.0) * W3[q]
                u = min(u, max_action * np.tanh(z))
            if em_on[k] or (em_standing and vl == 0.0):  # em_standing: a perceived leader at rest, at once
                u = min(u, _emergency_one(gap, vl, al, v[i], em_trigger, em_margin, max_brake))  # scalars only
        if cap_frac < 1.0:  # the driver profile's bounded braking
            u = max(u, -cap_frac)
        out[k] = min(max(u, -1.0), 1.0)
    return out
