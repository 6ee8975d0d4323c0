"""What happened in a step, as the event dicts of ``/evoscen/events`` (no ROS here).

Each dict has ``name`` (``evoscen/<kind>``), optional ``level`` and ``message``, and typed
key/values (see ``evoscen_contract.contract.EVENT_KEY_TYPES``; names and kinds are the contract's). Order within a step is fixed:
collisions, completed lane changes, aborted lane changes, re-entries (and window entries), off-road,
the traffic window's shift, then the
SUT's exposures (:class:`ExposureMonitor`).
"""

from __future__ import annotations

import math

import numpy as np

from evoscen_contract.contract import (EVENT_CHALLENGE, EVENT_COLLISION, EVENT_EXPOSURE, EVENT_FAULT, EVENT_LANE_CHANGE, EVENT_OFF_ROAD,
                                       EVENT_REENTRY, EVENT_RUN_END, EVENT_SHIFT, KIND_ABORTED, KIND_COMPLETED, KIND_DEADLINE,
                                       KIND_END, KIND_START, ROLE_SUT)

from .safety import (RearAttribution, attribution_steps, beside_gap_state, cut_in_gap_state, danger_terms, drac_one,
                     follower_headway, sut_follower_ttc_state, sut_leader_ttc_state)


def step_events(world, result) -> list[dict]:
    """The events of one :meth:`evoscen_sim.physics.world.World.step` result."""
    ids = world.ids
    common = {"step": result.step, "time_s": result.time_s}
    events: list[dict] = []
    for i, j in result.collisions:
        events.append({"name": EVENT_COLLISION, "message": f"vehicles {ids[i]} and {ids[j]} collide",
                       **common, "ids": [int(ids[i]), int(ids[j])]})
    for i, from_lane, to_lane, duration in result.lane_changes_completed:
        events.append({"name": EVENT_LANE_CHANGE, "message": f"vehicle {ids[i]}: lane {from_lane} -> {to_lane}",
                       **common, "ids": [int(ids[i])], "duration_s": duration,
                       "direction": 1 if to_lane > from_lane else -1, "from_lane": from_lane, "to_lane": to_lane,
                       "kind": KIND_COMPLETED})
    for i, from_lane, to_lane in result.lane_changes_aborted:
        events.append({"name": EVENT_LANE_CHANGE, "level": 1,
                       "message": f"vehicle {ids[i]}: lane change {from_lane} -> {to_lane} aborted, lane {to_lane} ended",
                       **common, "ids": [int(ids[i])], "direction": 1 if to_lane > from_lane else -1,
                       "from_lane": from_lane, "to_lane": to_lane, "kind": KIND_ABORTED})
    for i, lane, s in result.reentries:
        events.append({"name": EVENT_REENTRY, "message": f"vehicle {ids[i]} re-entered lane {lane} at s = {s:.1f} m",
                       **common, "ids": [int(ids[i])], "to_lane": lane})
    for i in result.off_road:
        events.append({"name": EVENT_OFF_ROAD, "message": f"vehicle {ids[i]} left the road",
                       **common, "ids": [int(ids[i])]})
    if result.shift_m:
        events.append({"name": EVENT_SHIFT, "message": f"every vehicle moved back by {result.shift_m:.1f} m "
                       "(the traffic window; relative positions kept)", **common, "shift_m": float(result.shift_m)})
    sut = ids[int(np.flatnonzero(world.role == ROLE_SUT)[0])] if result.challenges else 0
    for o in result.challenges:  # the step's onsets, stamped as its other events (the state after it)
        events.append({"name": EVENT_CHALLENGE, "message": f"vehicle {ids[o.vehicle]}, the SUT's leader at "
                       f"{o.headway_s:.2f} s, brakes at {o.decel_mps2:.1f} m/s² for {o.duration_s:.1f} s "
                       f"(q/p {o.multiplier:g})", **common, "ids": [int(ids[o.vehicle]), int(sut)],
                       "accel_mps2": -o.decel_mps2, "duration_s": o.duration_s, "multiplier": o.multiplier,
                       "log_weight": -math.log(o.multiplier), "kind": KIND_START})
    return events


def challenge_end_event(world) -> dict | None:
    """The challenge layer's summary before ``run_end`` (None without a layer): the run's log likelihood
    ratio p/q and the distance its SUT's leaders drove under the onset process."""
    ch = getattr(world, "challenge", None)
    if ch is None:
        return None
    return {"name": EVENT_CHALLENGE, "message": f"{len(ch.onsets)} challenge(s); the run's weight p/q = "
            f"{ch.weight:.6g}", "step": world.step_index, "time_s": world.time_s, "log_weight": ch.log_weight,
            "distance_m": ch.distance_m, "steps": len(ch.onsets), "kind": KIND_END}


def has_events(result) -> bool:
    """Whether a step result produces any event."""
    return bool(result.collisions or result.lane_changes_completed or result.lane_changes_aborted
                or result.reentries or result.off_road or result.shift_m or result.challenges)


def run_end_event(world, kind: str, message: str) -> dict:
    """The last event of every run: ``kind`` is completed, aborted or interrupted."""
    return {"name": EVENT_RUN_END, "level": 0 if kind == KIND_COMPLETED else 2, "message": message,
            "step": world.step_index, "time_s": world.time_s, "steps": world.step_index, "kind": kind}


def fault_event(world, kind: str, controller: str, misses: int, message: str) -> dict:
    """A controller fault: ``kind`` deadline (command held) or abort."""
    return {"name": EVENT_FAULT, "level": 1 if kind == KIND_DEADLINE else 2, "message": message,
            "step": world.step_index, "time_s": world.time_s, "controller": controller, "misses": misses,
            "kind": kind}


class ExposureMonitor:
    """``evoscen/exposure`` events: the SUT's dangerous states as they happen (docs/method.md §5.1).

    :meth:`observe` is called on every state, the initial one included; it returns a
    ``kind: start`` event when an exposure begins (``step``/``time_s`` of the first dangerous
    state, ``ttc_s``, ``accel_mps2``, ``ids`` = the SUT, the vehicle ahead in its path if any,
    the follower in its path when a rear conflict attributed to the SUT makes the state
    dangerous, the new follower when a cut-in does, and the vehicle beside when a lane change
    beside one does) and a ``kind: end`` event when it is over (``steps`` = its length in states).
    A state is dangerous as :func:`evoscen_sim.danger.safety.danger_terms` says, the evaluator's
    definition (this monitor gathers its inputs for one state); the rear-conflict
    attribution window (``evaluation.rear_conflicts``, docs/evaluation.md) is the one state
    this monitor keeps besides the open exposure, fed the SUT's ``lane_change`` column of
    every state as the evaluator reads it from the recorded world table.
    """

    def __init__(self, evaluation, role: np.ndarray) -> None:  # an EvaluationConfig
        self.evaluation = evaluation
        self._headway_run = 0
        self.sut = int(np.flatnonzero(np.asarray(role) == ROLE_SUT)[0])
        self.start_step: int | None = None
        self._rear: RearAttribution | None = None

    def observe(self, world) -> list[dict]:
        """The exposure events of the world's current state."""
        w, sut = world, self.sut
        if self._rear is None:
            self._rear = RearAttribution(self.evaluation.rear_conflicts,
                                          attribution_steps(self.evaluation.rear_attribution_s, w.dt_s))
        leader, ttc = sut_leader_ttc_state(w.s, w.d, w.v, w.length, w.width, sut)  # = sut_leader, sut_ttc
        ttc = float(ttc)
        accel = float(w.accel[sut])
        k, common = w.step_index, {"step": w.step_index, "time_s": w.time_s}
        lane_change = int(w.lane_change[sut])  # an int64 column: int, not numpy's mixed int/float comparison (~1.7 µs)
        attributed = self._rear.observe(k, lane_change)
        follower, f_ttc, f_thw, f_accel = -1, math.inf, math.inf, 0.0
        conflict_rule = self.evaluation.hard_braking == "conflict"
        if attributed or (conflict_rule and accel < -self.evaluation.hard_brake_mps2):
            follower, f_ttc = sut_follower_ttc_state(w.s, w.d, w.v, w.length, w.width, sut)  # = follower_ttc
            f_ttc, follower = float(f_ttc), int(follower)
            if follower >= 0:  # the arithmetic of safety.sut_follower and follower_headway, bit for bit
                f_gap = (w.s[sut] - w.s[follower]) - 0.5 * (w.length[follower] + w.length[sut])
                f_thw = float(follower_headway(np.float64(f_gap), np.float64(w.v[follower])))
                f_accel = float(w.accel[follower])
        speed, drac_sut, gap, l_speed = float(w.v[sut]), 0.0, math.inf, math.nan
        if leader >= 0:  # the arithmetic of safety.sut_leader and drac, bit for bit
            gap = float((w.s[leader] - w.s[sut]) - 0.5 * (w.length[leader] + w.length[sut]))
            l_speed = float(w.v[leader])
            if conflict_rule:
                drac_sut = drac_one(gap, speed, l_speed)
        new_follower, cut_gap, beside_j, beside_g = -1, math.inf, -1, math.inf
        if lane_change != 0:  # both gaps are inf while the SUT keeps its lane
            if self.evaluation.cut_in_gap_m > 0.0:
                new_follower, cut_gap = cut_in_gap_state(w.s, w.d, w.length, w.width, w.lane, w.target_lane,
                                                         w.lane_change, sut)  # = safety.cut_in_gap
            if self.evaluation.beside_lane_change:
                beside_j, beside_g = beside_gap_state(w.s, w.length, w.lane, w.target_lane, w.lane_change,
                                                      sut)  # = safety.beside_gap
        terms, self._headway_run = danger_terms(
            self.evaluation, w.dt_s, ttc=ttc, sut_accel=accel, drac_sut=drac_sut, follower_ttc_s=f_ttc,
            follower_accel=f_accel, follower_thw_s=f_thw, attributed=attributed, leader_gap_m=gap, sut_speed=speed,
            leader_speed=l_speed, cut_in_gap_m=float(cut_gap), beside_gap_m=float(beside_g),
            headway_run=self._headway_run)
        danger, braking, tailgating = bool(terms.danger), bool(terms.braking), bool(terms.tailgating)
        rear, cut_in, beside = bool(terms.rear), bool(terms.cut_in), bool(terms.beside)
        if danger and self.start_step is None:
            self.start_step = k
            leader = int(leader)
            ids = [int(w.ids[sut])] + ([int(w.ids[leader])] if leader >= 0 else [])
            if terms.low_ttc:
                cause = f"TTC {ttc:.2f} s"
            elif braking:
                cause = (f"acceleration {accel:.2f} m/s^2" if drac_sut <= self.evaluation.hard_brake_mps2
                         else f"needed deceleration (DRAC) {drac_sut:.2f} m/s^2")
            elif tailgating:
                cause = f"time headway {gap / speed:.2f} s to vehicle {int(w.ids[leader])}"
            elif cut_in and not rear:
                cause = f"cut-in: new follower {int(w.ids[new_follower])} {float(cut_gap):.2f} m behind"
            elif beside and not rear:
                cause = f"lane change beside vehicle {int(w.ids[beside_j])} (overlap {-float(beside_g):.2f} m)"
            else:
                cause = f"follower {int(w.ids[follower])}: TTC {f_ttc:.2f} s, acceleration {f_accel:.2f} m/s^2"
            if rear:
                ids.append(int(w.ids[follower]))
            if cut_in and int(w.ids[new_follower]) not in ids:
                ids.append(int(w.ids[new_follower]))
            if beside and int(w.ids[beside_j]) not in ids:
                ids.append(int(w.ids[beside_j]))
            return [{"name": EVENT_EXPOSURE, "level": 1, "message": f"SUT dangerous state: {cause}",
                     **common, "ids": ids, "kind": KIND_START, "ttc_s": ttc, "accel_mps2": accel}]
        if not danger and self.start_step is not None:
            steps, self.start_step = k - self.start_step, None
            return [{"name": EVENT_EXPOSURE, "level": 0, "message": f"SUT exposure over after {steps} states",
                     **common, "ids": [int(w.ids[sut])], "kind": KIND_END, "steps": steps}]
        return []
