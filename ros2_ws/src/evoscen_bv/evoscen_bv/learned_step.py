"""A learned driver's per-step work under the ``driver`` profile in one compiled call.

:meth:`evoscen_bv.learned.LearnedDriver.act` asks, every step, for the controller's throttle
(:func:`evoscen_bv.car_following.learned_throttle`), the road's forced merges
(:func:`evoscen_bv.lane_change_decision.forced_merge_targets`), the hard-braking scan
(:meth:`evoscen_bv.learned.HardBrakeState.bound`) and the lane hold's step. None of them reads what another
writes, so :func:`driver_step` makes the four compiled calls as one (:func:`_driver_step_kernel`): the same
kernels on the same arguments, so the same bits, at a quarter of the calls (docs/performance.md
"Per-step work of the world and of the BV drivers"). What follows them — the merge's speed adaptation, the
hard-braking odometers and their draws, the bounds — stays with the driver, in the order it had.
"""

from __future__ import annotations

import numpy as np

from evoscen_contract.contract import POLICY_CODES, ROLE_SUT
from evoscen_sim.danger.safety import sut_leader_ttc_state
from evoscen_sim.jit import kernel
from evoscen_sim.physics.window import NEW_TRIP_MAX_SPEED_MPS, common_shift_kernel, new_trips_kernel

from .car_following import _driver_throttle_kernel
from .lane_change_decision import _forced_merge_kernel

_NO_STEPS = np.zeros(0, dtype=np.int64)

HARD_BRAKE_VIEW_M = 100.0
"""A hard-braking episode starts only for a BV that is the SUT's leader (the nearest vehicle ahead
whose body overlaps the SUT's path, :func:`evoscen_sim.danger.safety.sut_leader`) with a bumper-to-bumper
gap of at most this many metres. [choice] 100 m: the vehicle a driver follows at highway speed
(3.3 s at 30 m/s); a leader farther away braking hard is no challenge."""


def driver_step(drv, view) -> tuple[np.ndarray, np.ndarray | None, tuple | None]:
    """For a :class:`~evoscen_bv.learned.LearnedDriver` ``drv`` with a reaction profile (not ``safety_net``):
    the controller's throttle of its vehicles, the forced-merge targets when it adapts its speed to merge
    (else None) and the hard-braking scan ``(braking, position)`` when it brakes hard (else None); the lane
    hold advanced when it holds lanes."""
    drv.prepare_throttle(view)
    reaction = drv.reaction
    update = reaction.advance(view)
    lk = view.lane_lookup()
    hb = drv.hard_brake
    hold = drv.lane_hold_s > 0.0
    merge = drv.forced_merge and drv.merge_seek
    dt = float(view.dt_s)
    throttle, targets, braking, k, changing, s_hosted = _driver_step_kernel(
        drv.vehicles, view.s, view.d, view.psi, view.v, view.accel, view.lane, view.lane_change, view.target_lane,
        view.length, view.width, lk.d_right, lk.d_left, lk.present,
        lk.max_speed_mps if drv.speed_cap else drv._no_limits(view), np.asarray(drv.desired_speed_mps, dtype=float),
        *drv._throttle_constants, np.int64(reaction.n_react), reaction.seen, reaction.em_count, update,
        reaction.cap_frac, reaction.standing_at_once,
        np.asarray(view.role, dtype=np.int64), np.asarray(view.policy, dtype=np.int64), drv.compete_with_sut,
        POLICY_CODES["competitive"], ROLE_SUT,
        merge, np.asarray(view.road.lane_end_s, dtype=np.float64), float(drv.forced_merge_m),
        hb is not None, _NO_STEPS if hb is None else hb.until_step,
        0.0 if hb is None else float(hb.params.min_speed_mps), int(view.step_index), HARD_BRAKE_VIEW_M,
        hold, drv._changing, drv.hold_until_step, drv._last_s, int(round(drv.lane_hold_s / dt)) if hold else 0,
        drv.hold_on_entry, NEW_TRIP_MAX_SPEED_MPS * dt + 10.0)
    if hold:
        drv._changing, drv._last_s = changing, s_hosted
    return throttle, (targets if merge else None), ((braking, k) if hb is not None else None)


@kernel
def _driver_step_kernel(idx, s, d, psi, v, a, lane, lane_change, target_lane, length, width, d_right, d_left, present,
                        max_speed, desired, merge_stop_s, view_m, v_max, a_max, own_w, speed_gain, em_trigger,
                        em_margin, max_accel, max_brake, W1, b1, W2, b2, W3, b3, max_action,
                        n_react, seen, em_count, update, cap_frac, standing_at_once,
                        role, policy, compete, competitive_code, role_sut,
                        merge, lane_end_s, merge_within_m,
                        brake, until_step, brake_min_speed, step, brake_view_m,
                        hold, changing_before, hold_until, last_s, n_hold, hold_on_entry, forward_m):
    """:func:`driver_step`'s compiled part: the competitive vehicles that do not yield to the SUT's intent (as
    :meth:`~evoscen_bv.learned.LearnedDriver.throttle` finds them), then the throttle kernel, the forced-merge
    kernel, the hard-braking scan and the lane hold's step (each only when its flag is set)."""
    m = idx.shape[0]
    late = np.zeros(m, dtype=np.bool_)
    sut = -1
    if compete:
        for j in range(role.shape[0]):
            if role[j] == role_sut:
                sut = j
                break
        if sut >= 0:
            for k in range(m):
                late[k] = policy[idx[k]] == competitive_code
    throttle = _driver_throttle_kernel(idx, s, d, psi, v, a, lane, lane_change, target_lane, length, width, d_right,
                                       d_left, present, max_speed, desired, merge_stop_s, view_m, v_max, a_max, own_w,
                                       speed_gain, em_trigger, em_margin, max_accel, max_brake, W1, b1, W2, b2, W3, b3,
                                       max_action, n_react, seen, em_count, update, cap_frac, standing_at_once, late,
                                       np.int64(sut))
    targets = np.zeros(0, dtype=np.int64)
    if merge:
        targets = _forced_merge_kernel(idx, lane, s, lane_end_s, merge_within_m)
    braking = np.zeros(m, dtype=np.bool_)
    position = -1
    if brake:
        braking, position = _hard_brake_scan(idx, until_step, v, role, s, d, length, width, lane_change,
                                             brake_min_speed, step, brake_view_m, role_sut)
    changing = np.zeros(0, dtype=np.bool_)
    s_hosted = np.zeros(0)
    if hold:
        changing, s_hosted = _lane_hold_step(idx, lane_change, s, changing_before, hold_until, last_s, step, n_hold,
                                             hold_on_entry, forward_m)
    return throttle, targets, braking, position, changing, s_hosted


@kernel
def _hard_brake_scan(vehicles, until_step, v, role, s, d, length, width, lane_change, min_speed, step, view_m,
                     role_sut):
    """One step of :meth:`HardBrakeState.bound` up to its random draws (compiled: called on every
    step): ends the episodes of hosted vehicles at ``min_speed`` or slower (``until_step`` in place)
    and returns (which hosted vehicles brake, the hosted position whose odometer runs this step or
    -1): the SUT's leader (:func:`~evoscen_sim.danger.safety.sut_leader_ttc_state`) when it is
    hosted, not braking, within ``view_m`` (bumper gap), faster than ``min_speed``, not changing lanes."""
    m = vehicles.shape[0]
    braking = np.empty(m, dtype=np.bool_)
    for k in range(m):
        if v[vehicles[k]] <= min_speed:  # never into a standstill
            until_step[k] = -1
        braking[k] = until_step[k] > step
    sut = -1
    for j in range(role.shape[0]):
        if role[j] == role_sut:
            sut = j
            break
    if sut < 0:
        return braking, -1
    leader, _ttc = sut_leader_ttc_state(s, d, v, length, width, sut)
    if leader < 0:
        return braking, -1
    for k in range(m):
        if vehicles[k] == leader:
            gap = (s[leader] - s[sut]) - 0.5 * (length[leader] + length[sut])
            if not braking[k] and gap <= view_m and v[leader] > min_speed and lane_change[leader] == 0:
                return braking, k
            return braking, -1
    return braking, -1


@kernel
def _lane_hold_step(vehicles, lane_change, s_all, changing_before, hold_until, last_s, step, n_hold, hold_on_entry,
                    forward_m):
    """One step of the lane hold (compiled: every step): a hosted vehicle whose lane change ended is
    held ``n_hold`` steps (``hold_until`` in place); then one that began a new trip since the last
    step (:func:`evoscen_sim.physics.window.new_trips`, ``last_s`` None on the first step) is held
    (``hold_on_entry``) or freed. Returns (which hosted vehicles change lanes, their ``s``)."""
    m = vehicles.shape[0]
    changing = np.empty(m, dtype=np.bool_)
    s = np.empty(m)
    for k in range(m):
        changing[k] = lane_change[vehicles[k]] != 0
        s[k] = s_all[vehicles[k]]
        if changing_before[k] and not changing[k]:
            hold_until[k] = step + n_hold
    if last_s is not None:
        entered = new_trips_kernel(last_s, s, common_shift_kernel(last_s, s), forward_m)
        for k in range(m):
            if entered[k]:
                hold_until[k] = step + n_hold if hold_on_entry else -1
    return changing, s
