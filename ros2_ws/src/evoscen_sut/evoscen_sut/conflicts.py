"""Conflicting lane-change requests of one driver's vehicles, resolved [choice] (docs/method.md §4).

A driver that drives several vehicles (the BV role) decides all of them from the same state,
so two vehicles can each find a gap safe and move into it together from both sides. Of two
vehicles requesting the same target lane at the same step whose pair is unsafe, the one
ahead keeps its request (the lower world index when level) and the other keeps its lane.
"Unsafe" is the deciding model's own test (:class:`ConflictRule`):

* MOBIL (:mod:`evoscen_sut.mobil`): the rear vehicle of the pair would brake harder than
  ``b_safe`` behind the front one (its IDM acceleration with MOBIL's IDM parameters and the
  desired speed ``v0``, bumper gap);
* Nilsson (:mod:`evoscen_sut.nilsson`): the two are closer (centre distance) than the safety
  distance ``safety_length_factor · L + safety_closing_headway_s · max(closing speed, 0)``,
  ``L`` the length of the vehicle that yields.
"""

from __future__ import annotations

from typing import NamedTuple

from evoscen_sim.jit import kernel
from evoscen_sim.physics.idm import idm_scalar


class ConflictRule(NamedTuple):
    """The pair test of :func:`resolve_conflicts` (one type for both models, so one compiled
    kernel serves both; the other model's fields are NaN)."""

    safety_distance: bool
    """True: Nilsson's safety-distance test; False: MOBIL's IDM-braking test."""
    desired_speed_mps: float
    """MOBIL: the IDM desired speed ``v0`` (m/s)."""
    safe_decel_mps2: float
    """MOBIL: ``b_safe`` (m/s²)."""
    time_headway_s: float
    """MOBIL: IDM ``T`` (s)."""
    min_gap_m: float
    """MOBIL: IDM ``s0`` (m)."""
    accel_mps2: float
    """MOBIL: IDM ``a`` (m/s²)."""
    comfort_decel_mps2: float
    """MOBIL: IDM ``b`` (m/s²)."""
    delta: float
    """MOBIL: IDM ``δ`` (-)."""
    max_decel_mps2: float
    """MOBIL: the lower clip of the IDM acceleration (m/s²)."""
    length_factor: float
    """Nilsson: ``safety_length_factor`` (-)."""
    closing_headway_s: float
    """Nilsson: ``safety_closing_headway_s`` (s)."""


@kernel
def unsafe_pair(s, v, length, a, b, rule):
    """The pair test of the row vehicle ``a`` and the column vehicle ``b`` (world indices; module docstring)."""
    ds = s[b] - s[a]
    if rule.safety_distance:
        closing = v[a] - v[b] if ds > 0.0 else v[b] - v[a]
        need = rule.length_factor * length[a] + rule.closing_headway_s * max(closing, 0.0)
        return abs(ds) < need
    gap = abs(ds) - 0.5 * (length[b] + length[a])
    if ds > 0.0:
        acc = idm_scalar(v[a], rule.desired_speed_mps, gap, v[b], rule.time_headway_s, rule.min_gap_m,
                         rule.accel_mps2, rule.comfort_decel_mps2, rule.delta, rule.max_decel_mps2)
    else:
        acc = idm_scalar(v[b], rule.desired_speed_mps, gap, v[a], rule.time_headway_s, rule.min_gap_m,
                         rule.accel_mps2, rule.comfort_decel_mps2, rule.delta, rule.max_decel_mps2)
    return acc < -rule.safe_decel_mps2


@kernel
def resolve_conflicts(idx, request, lane, s, v, length, rule):
    """The requests (+1 left, −1 right, 0 keep) of the vehicles ``idx``, conflicts resolved (module
    docstring): a vehicle yields (request 0) to the first vehicle ahead of it (or level with a
    lower index) that requests the same target lane and fails :func:`unsafe_pair` with it."""
    k = idx.shape[0]
    out = request.copy()
    cnt = 0
    for a in range(k):
        if request[a] != 0:
            cnt += 1
    if cnt < 2:
        return out
    for a in range(k):
        if request[a] == 0:
            continue
        ia = idx[a]
        ta = lane[ia] + request[a]
        for b in range(k):
            if b == a or request[b] == 0:
                continue
            ib = idx[b]
            if lane[ib] + request[b] != ta:
                continue
            ds = s[ib] - s[ia]
            if not (ds > 0.0 or (ds == 0.0 and ib < ia)):
                continue
            if unsafe_pair(s, v, length, ia, ib, rule):
                out[a] = 0
                break
    return out
