"""The learned car-following controller (SPEC §3.1): observation, reward, throttle.

Observation of vehicle ``i`` (method §3.1), relative to the nearest vehicle ahead in its
lane within the view ``o_smax``::

    s = [Δs / o_smax, Δṡ / v_max, Δs̈ / a_max, λ]

with Δs the bumper-to-bumper gap (m), Δṡ = v_leader - v_i, Δs̈ = a_leader - a_i, λ = 1 when
such a leader is in view, else 0 and the three differences are 0.

Reward (method eqs. 6-7)::

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


def leader_state(gap_m: np.ndarray, leader_speed: np.ndarray, leader_accel: np.ndarray,
                 speed: np.ndarray, accel: np.ndarray, params: CarFollowingParams) -> np.ndarray:
    """Observations (m, 4) of vehicles with speeds/accels ``speed``/``accel`` behind their leaders.

    ``gap_m`` is ``inf`` (and the leader's speed/accel ``nan``) without a leader.
    """
    return _obs_kernel(np.asarray(gap_m, float), np.asarray(leader_speed, float), np.asarray(leader_accel, float),
                       np.asarray(speed, float), np.asarray(accel, float),
                       params.view_m, params.v_max_mps, params.a_max_mps2)


@kernel
def _obs_kernel(gap, v_lead, a_lead, v, a, view, v_max, a_max):  # noqa: ANN001, ANN202
    m = gap.shape[0]
    obs = np.zeros((m, 4))
    for k in range(m):
        if gap[k] <= view and not np.isnan(v_lead[k]):  # method §3.1: a leader in view
            obs[k, 0] = gap[k] / view
            obs[k, 1] = (v_lead[k] - v[k]) / v_max
            obs[k, 2] = (a_lead[k] - a[k]) / a_max
            obs[k, 3] = 1.0
    return obs


def gap_value(obs: np.ndarray, params: CarFollowingParams) -> np.ndarray:
    """V(s) = -(Δs - g)² / V_max² (method eq. 7); 0 without a leader in view."""
    obs = np.atleast_2d(obs)
    gap = obs[:, 0] * params.view_m
    v = -((gap - params.target_gap_m) ** 2) / params.value_scale_m**2
    return np.where(obs[:, 3] > 0.5, v, 0.0)


def car_following_reward(obs: np.ndarray, next_obs: np.ndarray, collided: np.ndarray,
                         params: CarFollowingParams) -> np.ndarray:
    """r = -C on collision, else μ V(s') + k (V(s') - V(s)) (method eq. 6)."""
    v0 = gap_value(obs, params)
    v1 = gap_value(next_obs, params)
    return np.where(np.asarray(collided, bool), -params.collision_penalty, params.mu * v1 + params.k * (v1 - v0))


def speed_cap_throttle(speed: np.ndarray, desired_speed: np.ndarray, params: CarFollowingParams,
                       max_accel: float, max_brake: float) -> np.ndarray:
    """The free-road speed term k_v (v_des - v), as a throttle/brake command in [-1, 1]."""
    acc = params.speed_gain * (np.asarray(desired_speed) - np.asarray(speed))
    return np.clip(np.where(acc >= 0.0, acc / max_accel, acc / max_brake), -1.0, 1.0)


def merge_end_gap(world, idx: np.ndarray, params: CarFollowingParams) -> np.ndarray:  # noqa: ANN001
    """Gap (m) of vehicles ``idx`` to the merge lane's standing end; ``inf`` off the merge lane and
    while changing lanes (as for level-0 traffic: a vehicle that stopped at the line mid-change
    would stand across two lanes, since a vehicle at rest cannot move sideways)."""
    end_s = float(world.road.lane_end_s[0])
    gap = end_s - params.merge_stop_margin_m - (world.s[idx] + 0.5 * world.length[idx])
    return np.where((world.lane[idx] == 0) & (world.lane_change[idx] == 0), gap, np.inf)


def controller_observations(world, idx: np.ndarray, params: CarFollowingParams) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """Controller observations of vehicles ``idx``: own lane (with the merge end) and target lane.

    Returns ``(own, target)``, each ``(m, 4)``; ``target`` equals ``own`` for vehicles not
    changing lanes. While a vehicle changes lanes its throttle is the smaller of the two
    commands (it follows the nearer-braking leader, as level-0 traffic does).
    """
    nb = world.neighborhood()
    own_gap = nb.gap_front_m[idx, 2]
    end_gap = merge_end_gap(world, idx, params)
    use_end = end_gap < own_gap
    gap = np.where(use_end, end_gap, own_gap)
    v_lead = np.where(use_end, 0.0, nb.leader_speed_mps[idx, 2])
    a_lead = np.where(use_end, 0.0, nb.leader_accel_mps2[idx, 2])
    v, a = world.v[idx], world.accel[idx]
    own = leader_state(gap, v_lead, a_lead, v, a, params)
    col = 2 + world.lane_change[idx]
    rows = idx
    target = leader_state(nb.gap_front_m[rows, col], nb.leader_speed_mps[rows, col], nb.leader_accel_mps2[rows, col],
                          v, a, params)
    changing = world.lane_change[idx] != 0
    target[~changing] = own[~changing]
    return own, target


def compose_throttle(policy_own: np.ndarray, policy_target: np.ndarray, own_obs: np.ndarray,
                     target_obs: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """Throttle = min over the leaders in view of the policy's command, and the speed cap."""
    big = np.inf
    u_own = np.where(own_obs[:, 3] > 0.5, policy_own, big)
    u_tgt = np.where(target_obs[:, 3] > 0.5, policy_target, big)
    return np.clip(np.minimum(np.minimum(u_own, u_tgt), cap), -1.0, 1.0)


def learned_throttle(view, idx: np.ndarray, desired_speed: np.ndarray, bank, params: CarFollowingParams,  # noqa: ANN001
                     max_accel: float, max_brake: float) -> np.ndarray:
    """The run-time throttle of vehicles ``idx``, fused into one compiled pass.

    The same quantities as :func:`controller_observations`, the controller's forward pass
    (``bank``: a one-actor :class:`evoscen_bv.learned.PolicyBank`), :func:`speed_cap_throttle`
    and :func:`compose_throttle` (a test checks they agree); fused because for ~20 vehicles
    numpy's per-call overhead, not arithmetic, would dominate the step.
    """
    nb = view.neighborhood()
    return _learned_throttle_kernel(
        np.asarray(idx, dtype=np.int64), view.s, view.v, view.accel, view.lane, view.lane_change, view.length,
        view.speed_limit_mps, np.asarray(desired_speed, dtype=float),
        nb.gap_front_m, nb.leader_speed_mps, nb.leader_accel_mps2,
        float(view.road.lane_end_s[0]) - params.merge_stop_margin_m,
        params.view_m, params.v_max_mps, params.a_max_mps2, params.speed_gain, max_accel, max_brake,
        bank.W1[0], bank.b1[0], bank.W2[0], bank.b2[0], bank.W3[0], float(bank.b3[0]), float(bank.max_action[0]),
    )


@kernel
def _mlp_one(x, W1, b1, W2, b2, W3, b3, max_action):  # noqa: ANN001, ANN202
    """max_action · tanh(W3 relu(W2 relu(W1 x + b1) + b2) + b3) for one input vector."""
    h = W1.shape[1]
    h1 = b1.copy()
    for k in range(x.shape[0]):
        if x[k] != 0.0:
            for u in range(h):
                h1[u] += x[k] * W1[k, u]
    h2 = b2.copy()
    for k in range(h):
        hk = max(h1[k], 0.0)
        if hk != 0.0:
            for u in range(h):
                h2[u] += hk * W2[k, u]
    z = b3
    for u in range(h):
        z += max(h2[u], 0.0) * W3[u]
    return max_action * np.tanh(z)


@kernel
def _learned_throttle_kernel(idx, s, v, a, lane, lane_change, length, speed_limit, desired,  # noqa: ANN001, ANN202, PLR0913
                             gap_front, v_front, a_front, merge_stop_s, view, v_max, a_max, speed_gain,
                             max_accel, max_brake, W1, b1, W2, b2, W3, b3, max_action):
    m = idx.shape[0]
    out = np.empty(m)
    x = np.zeros(4)
    for k in range(m):
        i = idx[k]
        # free-road speed term, capped by the lane's limit (none past a lane's end: NaN)
        v_des = desired[k] if np.isnan(speed_limit[i]) else min(desired[k], speed_limit[i])
        acc = speed_gain * (v_des - v[i])
        u = acc / max_accel if acc >= 0.0 else acc / max_brake
        u = min(max(u, -1.0), 1.0)
        for which in range(2):
            if which == 0:
                gap, vl, al = gap_front[i, 2], v_front[i, 2], a_front[i, 2]
                if lane[i] == 0 and lane_change[i] == 0:  # the merge lane's end is a standing leader
                    end_gap = merge_stop_s - (s[i] + 0.5 * length[i])
                    if end_gap < gap:
                        gap, vl, al = end_gap, 0.0, 0.0
            else:
                if lane_change[i] == 0:
                    break
                c = 2 + lane_change[i]
                gap, vl, al = gap_front[i, c], v_front[i, c], a_front[i, c]
            if gap <= view and not np.isnan(vl):  # a leader in view: the controller's command
                x[0] = gap / view
                x[1] = (vl - v[i]) / v_max
                x[2] = (al - a[i]) / a_max
                x[3] = 1.0
                u = min(u, _mlp_one(x, W1, b1, W2, b2, W3, b3, max_action))
        out[k] = min(max(u, -1.0), 1.0)
    return out
