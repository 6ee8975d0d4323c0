"""The SUT's dangerous states (docs/method.md §5.1): one definition for the live events and the scores.

Definitions, choices and their reasons: docs/evaluation.md. A state is **dangerous** when

* the SUT's time to collision with the vehicle ahead *in its path* is below
  ``evaluation.ttc_threshold_s`` [2 s], or
* the SUT brakes hard: **[choice]** (``evaluation.hard_braking``) ``conflict`` [default]: the
  deceleration it needs to avoid its leader (DRAC) exceeds ``evaluation.hard_brake_mps2``
  [6 m/s²], or it brakes harder than that with the follower in its path within
  ``rear_braking_headway_s`` [2 s] of headway; ``own``: its acceleration is below
  ``-hard_brake_mps2`` (the method's words), or
* **[choice]** (``evaluation.rear_conflicts``) there is a *rear conflict attributed to the
  SUT*: the follower in the SUT's path (:func:`sut_follower`) closes on it with TTC below the
  threshold or brakes harder than ``hard_brake_mps2`` within ``rear_braking_headway_s`` [2 s]
  of time headway behind it (**[choice]** ``evaluation.rear_braking``), in a state from the start of a SUT
  lane change until ``rear_attribution_s`` [5 s] after it ends (``after_lane_change``,
  default; :func:`rear_attributed`), in every state (``all``) or never (``none``: the
  definition before rear conflicts, exactly), or
* **[choice]** (``evaluation.cut_in_gap_m`` [10 m], 0 = off) the SUT *cuts in*: it is changing
  lanes and its new follower — the nearest vehicle in the SUT's target lane whose centre is
  behind the SUT's and whose body overlaps the SUT's laterally — is less than
  ``cut_in_gap_m`` behind it, bumper to bumper (:func:`cut_in_gap`): the SUT made the change the
  method's rule constraint forbids every BV (no change with a vehicle within 10 m), or
* **[choice]** (``evaluation.beside_lane_change`` [true], false = off) the SUT changes lanes
  *beside* a vehicle: it is changing lanes while a vehicle in its target lane (or changing into
  it; not one leaving it on the far side) overlaps its body longitudinally (:func:`beside_gap`): it steers towards the side of a
  vehicle, a collision that only that vehicle's braking or the speed difference averts.

* **[choice]** (``evaluation.headway_threshold_s`` [1 s], 0 = off) the SUT *tailgates*: it
  follows the leader in its path with a time headway (bumper-to-bumper gap / its own speed)
  below the threshold without falling back (its speed at least the leader's)
  (:func:`headway_dangerous`): following that close leaves no time to react to a leader that
  brakes, whether or not the two close in (TTC is infinite at equal speeds). The state is
  dangerous once the condition has held for more than ``evaluation.headway_grace_s`` [2 s]
  without a break (:func:`held_longer_than`): a SUT that finds itself too close after a vehicle
  cut in ahead and restores the gap within it is not tailgating.

**[choice]** "in its path": another vehicle whose body overlaps the SUT's laterally
(|d_j - d_sut| < (w_j + w_sut)/2 in road coordinates) and whose centre is ahead
(s_j > s_sut) — behind (s_j < s_sut) for the follower. The nearest such vehicle is the
leader (follower); TTC = bumper-to-bumper gap / closing speed while closing, else infinite
(:func:`evoscen_sim.physics.neighbors.time_to_collision`). Lateral overlap rather than lane
membership makes a cut-in count from the moment the other body enters the SUT's path, not
when its centre crosses the lane line, and follows the SUT through its own lane changes.
DRAC (:func:`drac`) is reported, not part of the definition.

:func:`danger_terms` combines the terms: the one place the definition is written, called by
the live monitor (:class:`evoscen_sim.danger.events.ExposureMonitor`) and by the scorer
(:class:`evoscen_eval.scoring.streaming.ScoreStream`).

An **exposure** is a maximal run of consecutive dangerous states (events are counted, not
steps). The simulation node publishes an ``evoscen/exposure`` event when one starts; the
evaluator recomputes the same states from the recorded world table with the same functions,
so the live events and the scores cannot disagree.

Every function broadcasts over leading axes: one state (``[V]`` arrays) in the simulation,
a whole run (``[K, V]``) in the evaluator, with identical floating-point results; the
compiled one-state kernels are bit-identical to them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from evoscen_sim.config.scenario_config import HARD_BRAKING_RULES, REAR_BRAKING_RULES, REAR_CONFLICT_MODES
from evoscen_sim.jit import kernel
from evoscen_sim.physics.neighbors import time_to_collision


def _nearest_in_path(ahead: np.ndarray, d: np.ndarray, length: np.ndarray, width: np.ndarray, sut: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The nearest vehicle in the SUT's path on the side where ``ahead`` (centre distance from
    the SUT, ``[..., V]``) is positive, and its bumper-to-bumper gap: ``(-1, inf)`` if none.

    In the path: lateral body overlap (|d_j - d_sut| < (w_j + w_sut)/2); :func:`sut_leader`
    passes ``s - s_sut``, :func:`sut_follower` ``s_sut - s``.
    """
    half_widths = 0.5 * (width + width[..., sut:sut + 1])
    in_path = (ahead > 0.0) & (np.abs(d - d[..., sut:sut + 1]) < half_widths)
    in_path[..., sut] = False
    gaps = np.where(in_path, ahead - 0.5 * (length + length[..., sut:sut + 1]), np.inf)
    nearest = np.argmin(np.where(in_path, ahead, np.inf), axis=-1)
    gap = np.take_along_axis(gaps, nearest[..., None], axis=-1)[..., 0]
    nearest = np.where(np.isfinite(gap), nearest, -1)
    return nearest, gap


def sut_leader(s: np.ndarray, d: np.ndarray, length: np.ndarray, width: np.ndarray, sut: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Index and bumper-to-bumper gap of the vehicle ahead in the SUT's path.

    Args:
        s, d, length, width: ``[..., V]`` arrays of every vehicle (the SUT included).
        sut: the SUT's index on the last axis.

    Returns:
        ``(leader, gap)``, shape ``[...]``: the leader's index (-1 if none) and the gap (m;
        ``inf`` if none, negative if the bodies overlap longitudinally).
    """
    return _nearest_in_path(s - s[..., sut:sut + 1], d, length, width, sut)


def sut_ttc(s: np.ndarray, d: np.ndarray, speed: np.ndarray, length: np.ndarray, width: np.ndarray,
            sut: int) -> np.ndarray:
    """The SUT's time to collision with the vehicle ahead in its path (s; ``inf`` if none or opening)."""
    leader, gap = sut_leader(s, d, length, width, sut)
    lead_speed = np.take_along_axis(speed, np.maximum(leader, 0)[..., None], axis=-1)[..., 0]
    return time_to_collision(gap, speed[..., sut], np.where(leader >= 0, lead_speed, np.nan))


@kernel
def sut_leader_ttc_state(s: np.ndarray, d: np.ndarray, speed: np.ndarray, length: np.ndarray, width: np.ndarray,
                         sut: int) -> tuple[int, float]:
    """:func:`sut_leader`'s leader and :func:`sut_ttc` of ONE state (``[V]`` arrays), compiled.

    The simulation node observes every state (:class:`evoscen_sim.danger.events.ExposureMonitor`):
    the broadcasting numpy definitions above cost ~50 µs per state for 21 vehicles, this
    ~2 µs. The same IEEE operations in the same order (fastmath off), the first of equal
    distances as ``argmin`` takes it, so the results are bit-identical (a test compares them
    on many states); the evaluator keeps the numpy definitions for whole runs.

    Returns:
        ``(leader, ttc)``: the leader's index (-1 if none) and the TTC (s; ``inf`` if none or
        opening).
    """
    s0, d0, w0, l0 = s[sut], d[sut], width[sut], length[sut]
    leader, best = -1, np.inf
    for j in range(s.shape[0]):
        ds = s[j] - s0
        if j != sut and ds > 0.0 and abs(d[j] - d0) < 0.5 * (width[j] + w0) and ds < best:
            leader, best = j, ds
    if leader < 0:
        return -1, np.inf
    gap = (s[leader] - s0) - 0.5 * (length[leader] + l0)
    if not np.isfinite(gap):
        return -1, np.inf
    closing = speed[sut] - speed[leader]
    if closing > 0.0:
        return leader, (gap if gap >= 0.0 else 0.0) / closing
    return leader, np.inf


_SCALAR_TYPES = frozenset((float, int, bool, np.float64, np.int64, np.bool_))


def _one(x) -> bool:
    """Whether ``x`` is one value (``np.ndim(x) == 0``), answered without numpy for the plain and numpy
    scalars the live monitor passes: ``np.ndim`` of a Python float costs ~1.5 µs (it tries ``.ndim``
    and catches the AttributeError), the type test ~50 ns (docs/performance.md "Per-step work of the scores")."""
    return type(x) in _SCALAR_TYPES or np.ndim(x) == 0


def headway_dangerous(gap_m: np.ndarray | float, sut_speed: np.ndarray | float, leader_speed: np.ndarray | float,
                      threshold_s: float) -> np.ndarray:
    """Whether the SUT follows its leader too closely (docs/evaluation.md §2, "tailgating"):
    time headway gap / v_SUT below ``threshold_s`` while v_SUT >= v_leader and v_SUT > 0.

    ``gap_m``: bumper-to-bumper gap to the leader in the SUT's path (``inf`` without one; negative
    when the bodies overlap); ``leader_speed``: ``nan`` without a leader. ``threshold_s`` 0: never.
    A SUT that has dropped below the threshold and is falling back (slower than its leader, as
    after a vehicle cut in ahead of it) is not tailgating. Scalars give a numpy bool.
    """
    if _one(gap_m) and _one(sut_speed) and _one(leader_speed):
        # one state in plain floats: the same IEEE operations, at a fraction of numpy's per-call cost
        g, v, vl = float(gap_m), float(sut_speed), float(leader_speed)
        return np.bool_(threshold_s > 0.0 and math.isfinite(g) and v > 0.0 and g / v < threshold_s and v >= vl)
    gap = np.asarray(gap_m, dtype=float)
    v = np.asarray(sut_speed, dtype=float)
    vl = np.asarray(leader_speed, dtype=float)
    if threshold_s <= 0.0:
        return np.zeros(np.broadcast(gap, v, vl).shape, dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        thw = np.where(v > 0.0, gap / np.where(v > 0.0, v, 1.0), np.inf)
    return np.isfinite(gap) & (v > 0.0) & (thw < threshold_s) & (v >= vl)


def grace_steps(grace_s: float, dt_s: float) -> int:
    """The tailgating grace in states: round(grace / dt)."""
    return int(round(grace_s / dt_s)) if grace_s > 0.0 else 0


def held_longer_than(condition: np.ndarray, steps: int, carry: int = 0) -> tuple[np.ndarray, int]:
    """Whether each state's ``condition`` has held for more than ``steps`` consecutive states up to
    and including it, counting ``carry`` states of an unbroken run before the first (a block of a
    longer run); returns (that, the run length at the last state: the next block's carry).
    A scalar ``condition`` is one state: a bool and the run length at it."""
    if _one(condition):  # one state (the live monitor)
        r = int(carry) + 1 if condition else 0
        return r > steps, r
    cond = np.asarray(condition, dtype=bool)
    run = np.empty(cond.shape[0], dtype=np.int64)
    r = int(carry)
    for k, c in enumerate(cond.tolist()):
        r = r + 1 if c else 0
        run[k] = r
    return run > steps, r


def hard_braking_dangerous(sut_accel: np.ndarray, drac_sut: np.ndarray | float, follower_thw_s: np.ndarray | float,
                           hard_brake_mps2: float, mode: str = "own", headway_s: float = 2.0) -> np.ndarray:
    """The method's "SUT deceleration < -6 m/s²" as ``evaluation.hard_braking`` reads it (docs/evaluation.md §3.6).

    * ``own``: the SUT's acceleration below ``-hard_brake_mps2`` (the method's words);
    * ``conflict``: a hard braking that belongs to a conflict — *needed*: the SUT's DRAC to its
      leader (:func:`drac`) above ``hard_brake_mps2``, whatever the SUT did; or *imposed*: the
      SUT braking harder than ``hard_brake_mps2`` while the follower in its path is within
      ``headway_s`` of time headway (it must brake as hard).
    """
    braking = sut_accel < -hard_brake_mps2
    if mode == "own":
        return braking
    if mode == "conflict":
        return (drac_sut > hard_brake_mps2) | (braking & (follower_thw_s < headway_s))
    raise ValueError(f"evaluation.hard_braking = {mode!r}: expected one of {', '.join(HARD_BRAKING_RULES)}")


# ---------------------------------------------------------------------- the SUT's rear


def sut_follower(s: np.ndarray, d: np.ndarray, length: np.ndarray, width: np.ndarray, sut: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Index and bumper-to-bumper gap of the vehicle behind in the SUT's path (mirror of :func:`sut_leader`).

    "In the path, behind": lateral body overlap (|d_j - d_sut| < (w_j + w_sut)/2) and centre
    behind (s_j < s_sut); the nearest such vehicle is the follower. Returns ``(follower,
    gap)``, shape ``[...]``: -1 / ``inf`` if none; the gap is negative if the bodies overlap
    longitudinally.
    """
    return _nearest_in_path(s[..., sut:sut + 1] - s, d, length, width, sut)


def follower_ttc(s: np.ndarray, d: np.ndarray, speed: np.ndarray, length: np.ndarray, width: np.ndarray,
                 sut: int) -> tuple[np.ndarray, np.ndarray]:
    """``(follower, ttc)``: the follower in the SUT's path and its TTC onto the SUT (s; ``inf``
    if none or not closing), the same :func:`~evoscen_sim.physics.neighbors.time_to_collision` as ahead."""
    follower, gap = sut_follower(s, d, length, width, sut)
    f_speed = np.take_along_axis(speed, np.maximum(follower, 0)[..., None], axis=-1)[..., 0]
    ttc = time_to_collision(gap, np.where(follower >= 0, f_speed, np.nan), speed[..., sut])
    return follower, ttc


@kernel
def sut_follower_ttc_state(s: np.ndarray, d: np.ndarray, speed: np.ndarray, length: np.ndarray, width: np.ndarray,
                           sut: int) -> tuple[int, float]:
    """:func:`follower_ttc` of ONE state (``[V]`` arrays), compiled; bit-identical to it as
    :func:`sut_leader_ttc_state` is to :func:`sut_ttc` (a test compares them on many states).

    Returns:
        ``(follower, ttc)``: the follower's index (-1 if none) and its TTC onto the SUT (s;
        ``inf`` if none or not closing).
    """
    follower, gap = _behind_in_path_state(s, d, length, width, s, np.inf, sut)  # any lane
    if follower < 0:
        return -1, np.inf
    closing = speed[follower] - speed[sut]
    if closing > 0.0:
        return follower, (gap if gap >= 0.0 else 0.0) / closing
    return follower, np.inf


def cut_in_gap(s: np.ndarray, d: np.ndarray, length: np.ndarray, width: np.ndarray, lane: np.ndarray,
               target_lane: np.ndarray, lane_change: np.ndarray, sut: int) -> tuple[np.ndarray, np.ndarray]:
    """``(follower, gap)`` of the SUT's *new follower* while the SUT changes lanes (docs/evaluation.md §3).

    While the SUT's ``lane_change`` is non-zero, the new follower is the nearest vehicle j ≠ SUT
    with ``lane_j`` = the SUT's ``target_lane``, centre behind the SUT's (s_j < s_SUT) and body
    overlapping the SUT's laterally (|d_j - d_SUT| < (w_j + w_SUT)/2; so only once the SUT's body
    has entered the target lane); gap = bumper-to-bumper distance (negative if the bodies overlap
    longitudinally). ``-1`` / ``inf`` when the SUT keeps its lane or no such vehicle exists. The
    lane-change PET's follower is the same vehicle (``evoscen_eval.scoring.streaming``).
    """
    back = s[..., sut:sut + 1] - s
    half_widths = 0.5 * (width + width[..., sut:sut + 1])
    cand = (back > 0.0) & (np.abs(d - d[..., sut:sut + 1]) < half_widths) & (lane == target_lane[..., sut:sut + 1])
    cand[..., sut] = False
    gaps = np.where(cand, back - 0.5 * (length + length[..., sut:sut + 1]), np.inf)
    follower = np.argmin(np.where(cand, back, np.inf), axis=-1)
    gap = np.take_along_axis(gaps, follower[..., None], axis=-1)[..., 0]
    gap = np.where(lane_change[..., sut] != 0.0, gap, np.inf)
    follower = np.where(np.isfinite(gap), follower, -1)
    return follower, gap


@kernel
def cut_in_gap_state(s: np.ndarray, d: np.ndarray, length: np.ndarray, width: np.ndarray, lane: np.ndarray,
                     target_lane: np.ndarray, lane_change: np.ndarray, sut: int) -> tuple[int, float]:
    """:func:`cut_in_gap` of ONE state (``[V]`` arrays), compiled; bit-identical to it (a test
    compares them on many states)."""
    if lane_change[sut] == 0.0:
        return -1, np.inf
    return _behind_in_path_state(s, d, length, width, lane, target_lane[sut], sut)


@kernel
def _behind_in_path_state(s: np.ndarray, d: np.ndarray, length: np.ndarray, width: np.ndarray, lane: np.ndarray,
                          lane_wanted: float, sut: int) -> tuple[int, float]:
    """The nearest vehicle behind the SUT whose body overlaps the SUT's laterally and whose
    ``lane`` equals ``lane_wanted`` (pass ``lane = s`` and ``lane_wanted = inf`` for any lane),
    and its bumper-to-bumper gap; ``(-1, inf)`` if none or the gap is not finite. One state,
    compiled: :func:`sut_follower_ttc_state` and :func:`cut_in_gap_state`."""
    s0, d0, w0, l0 = s[sut], d[sut], width[sut], length[sut]
    any_lane = lane_wanted == np.inf
    follower, best = -1, np.inf
    for j in range(s.shape[0]):
        back = s0 - s[j]
        if (j != sut and back > 0.0 and abs(d[j] - d0) < 0.5 * (width[j] + w0) and (any_lane or lane[j] == lane_wanted)
                and back < best):
            follower, best = j, back
    if follower < 0:
        return -1, np.inf
    gap = (s0 - s[follower]) - 0.5 * (length[follower] + l0)
    if not np.isfinite(gap):
        return -1, np.inf
    return follower, gap


def beside_gap(s: np.ndarray, length: np.ndarray, lane: np.ndarray, target_lane: np.ndarray,
               lane_change: np.ndarray, sut: int) -> tuple[np.ndarray, np.ndarray]:
    """``(vehicle, gap)``: the vehicle *beside* the SUT in its target lane while it changes lanes
    (docs/evaluation.md §3.7).

    While the SUT's ``lane_change`` is non-zero, the candidates are the vehicles j ≠ SUT whose
    ``lane`` or ``target_lane`` is the SUT's ``target_lane`` t, except one in t leaving it on the far
    side (``target_lane`` t + the SUT's direction: it moves away sideways as the SUT moves in);
    gap = |s_j − s_SUT| − (l_j + l_SUT)/2,
    the longitudinal bumper distance, negative while the bodies overlap longitudinally (j is
    beside the SUT). Returns the candidate with the smallest gap (the first of equals, as
    ``argmin``), ``-1`` / ``inf`` when the SUT keeps its lane or there is no candidate.
    """
    tgt = target_lane[..., sut:sut + 1]
    away = tgt + lane_change[..., sut:sut + 1]  # the lane beyond the target, on the far side
    cand = ((lane == tgt) | (target_lane == tgt)) & ~((lane == tgt) & (target_lane == away))
    cand[..., sut] = False
    gaps = np.where(cand, np.abs(s - s[..., sut:sut + 1]) - 0.5 * (length + length[..., sut:sut + 1]), np.inf)
    vehicle = np.argmin(gaps, axis=-1)
    gap = np.take_along_axis(gaps, vehicle[..., None], axis=-1)[..., 0]
    gap = np.where(lane_change[..., sut] != 0.0, gap, np.inf)
    vehicle = np.where(np.isfinite(gap), vehicle, -1)
    return vehicle, gap


@kernel
def enters_or_holds_lane(lane_j, target_lane_j, tgt, away) -> bool:
    """Whether a vehicle in ``lane_j`` with target ``target_lane_j`` counts as in lane ``tgt`` for a vehicle
    changing into it: in it or changing into it, except one in it leaving it on the far side (towards
    ``away``). The candidates of :func:`beside_gap` (docs/evaluation.md §3.7) and of Stackelberg's target
    lane (:mod:`evoscen_sut.stackelberg`, ``target_gap_rule: d_min_now``)."""
    return (lane_j == tgt or target_lane_j == tgt) and not (lane_j == tgt and target_lane_j == away)


@kernel
def beside_gap_state(s: np.ndarray, length: np.ndarray, lane: np.ndarray, target_lane: np.ndarray,
                     lane_change: np.ndarray, sut: int) -> tuple[int, float]:
    """:func:`beside_gap` of ONE state (``[V]`` arrays), compiled; bit-identical to it (a test
    compares them on many states)."""
    if lane_change[sut] == 0.0:
        return -1, np.inf
    tgt, s0, l0 = target_lane[sut], s[sut], length[sut]
    away = tgt + lane_change[sut]
    vehicle, best = -1, np.inf
    for j in range(s.shape[0]):
        if j == sut or not enters_or_holds_lane(lane[j], target_lane[j], tgt, away):
            continue
        gap = abs(s[j] - s0) - 0.5 * (length[j] + l0)
        if gap < best:
            vehicle, best = j, gap
    return vehicle, best


def beside_dangerous(gap_m: np.ndarray, enabled: bool) -> np.ndarray:
    """Whether each state is a dangerous lane change beside a vehicle: :func:`beside_gap` below 0."""
    return (gap_m < 0.0) & bool(enabled)


def beside_severity(gap_m: np.ndarray, length_sum_m: np.ndarray) -> np.ndarray:
    """An exposure's severity in a beside state (ranks exposures, docs/evaluation.md §3.7):
    1 + the longitudinal overlap over the half sum of the two lengths — 1 as the bodies begin to
    overlap, 2 side by side (the thresholds' 1 and 2 of TTC's threshold/TTC)."""
    return 1.0 - gap_m / (0.5 * length_sum_m)


def cut_in_dangerous(gap_m: np.ndarray, cut_in_gap_m: float) -> np.ndarray:
    """Whether each state is a dangerous cut-in: the new follower's gap below ``cut_in_gap_m`` (0: never)."""
    return (gap_m < cut_in_gap_m) & (cut_in_gap_m > 0.0)


def drac(gap_m: np.ndarray, speed_mps: np.ndarray, leader_speed_mps: np.ndarray) -> np.ndarray:
    """Deceleration rate to avoid a crash (m/s^2), SUMO SSM's DRAC (docs/evaluation.md):
    (v - v_leader)^2 / (2 gap) while closing, else 0; ``inf`` while closing at a gap <= 0;
    0 without a leader (``nan`` speed or ``inf`` gap)."""
    closing = speed_mps - leader_speed_mps
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(closing > 0.0, np.where(gap_m > 0.0, closing * closing / (2.0 * gap_m), np.inf), 0.0)
    return np.where(np.isfinite(gap_m), out, 0.0)


def drac_one(gap_m: float, speed_mps: float, leader_speed_mps: float) -> float:
    """:func:`drac` of one finite gap in plain Python floats: the same IEEE operations, so the
    same bits, at ~1 µs instead of numpy's ~20 µs per scalar call (the live monitor, every state)."""
    closing = speed_mps - leader_speed_mps
    if closing > 0.0:
        return closing * closing / (2.0 * gap_m) if gap_m > 0.0 else math.inf
    return 0.0


def follower_headway(gap_m: np.ndarray, follower_speed_mps: np.ndarray) -> np.ndarray:
    """The follower's time headway to the SUT (s): gap / its speed while it moves, else ``inf``
    (also ``inf`` without a follower: ``inf`` gap or ``nan`` speed); negative while the bodies
    overlap longitudinally. Scalars give a numpy float."""
    if _one(gap_m) and _one(follower_speed_mps):
        # one state in plain floats (the live monitor): the same IEEE operations, at a fraction of
        # numpy's per-call cost (docs/performance.md "Per-step work of the scores")
        g, v = float(gap_m), float(follower_speed_mps)
        return np.float64((g / v if v > 0.0 else math.inf) if math.isfinite(g) else math.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        thw = np.where(follower_speed_mps > 0.0, gap_m / follower_speed_mps, np.inf)
    return np.where(np.isfinite(gap_m), thw, np.inf)


def rear_dangerous(follower_ttc_s: np.ndarray, follower_accel: np.ndarray, follower_thw_s: np.ndarray,
                   ttc_threshold_s: float, hard_brake_mps2: float, rear_braking: str = "within_headway",
                   braking_headway_s: float = 2.0) -> np.ndarray:
    """A conflict at the SUT's rear: the follower in its path closes with TTC below the
    threshold, or brakes harder than ``hard_brake_mps2`` (``follower_accel`` 0 without one) —
    with ``rear_braking`` ``within_headway`` only while its time headway ``follower_thw_s`` to the
    SUT is below ``braking_headway_s``, with ``any`` whatever its distance (docs/evaluation.md §2)."""
    braking = follower_accel < -hard_brake_mps2
    if rear_braking == "within_headway":
        braking = braking & (follower_thw_s < braking_headway_s)
    elif rear_braking != "any":
        raise ValueError(f"rear_braking {rear_braking!r}: expected one of {', '.join(REAR_BRAKING_RULES)}")
    return (follower_ttc_s < ttc_threshold_s) | braking




class DangerTerms(NamedTuple):
    """The terms of the definition (module docstring) for each state, and their union: ``[n]``
    boolean arrays for ``[n]`` states given to :func:`danger_terms`, bools for one state."""

    low_ttc: np.ndarray
    """TTC to the leader in the SUT's path below ``ttc_threshold_s``."""
    braking: np.ndarray
    """Hard braking as ``evaluation.hard_braking`` reads it (:func:`hard_braking_dangerous`)."""
    front: np.ndarray
    """``low_ttc | braking``: dangerous at the SUT's front."""
    rear_conflict: np.ndarray
    """A conflict at the SUT's rear (:func:`rear_dangerous`), attributed to the SUT or not."""
    rear: np.ndarray
    """``rear_conflict`` in a state attributed to the SUT (``evaluation.rear_conflicts``)."""
    cut_in: np.ndarray
    """A cut-in closer than ``cut_in_gap_m`` (:func:`cut_in_dangerous`)."""
    beside: np.ndarray
    """A lane change beside a vehicle (:func:`beside_dangerous`)."""
    tailgating: np.ndarray
    """The headway condition (:func:`headway_dangerous`) held longer than the grace (:func:`held_longer_than`)."""
    danger: np.ndarray
    """The state is dangerous: ``front | rear | cut_in | beside | tailgating``."""


def danger_terms(evaluation, dt_s: float, *, ttc: np.ndarray | float, sut_accel: np.ndarray | float,
                 drac_sut: np.ndarray | float = 0.0, follower_ttc_s: np.ndarray | float = np.inf,
                 follower_accel: np.ndarray | float = 0.0, follower_thw_s: np.ndarray | float = np.inf,
                 attributed: np.ndarray | bool = False, leader_gap_m: np.ndarray | float = np.inf,
                 sut_speed: np.ndarray | float = 0.0, leader_speed: np.ndarray | float = np.nan,
                 cut_in_gap_m: np.ndarray | float = np.inf, beside_gap_m: np.ndarray | float = np.inf,
                 headway_run: int = 0) -> tuple[DangerTerms, int]:
    """Whether each state is dangerous for the SUT, term by term: the one definition the live
    monitor (:class:`evoscen_sim.danger.events.ExposureMonitor`, one state at a time) and the scores
    (:class:`evoscen_eval.scoring.streaming.ScoreStream`, a block of states at a time) both apply.

    ``evaluation``: an :class:`~evoscen_sim.config.scenario_config.EvaluationConfig`; ``dt_s``: the step (the
    tailgating grace in states, :func:`grace_steps`). The per-state quantities, floats for one
    state (the terms are then bools) or ``[n]`` arrays for consecutive states: ``ttc``
    (:func:`sut_ttc`), ``sut_accel``, ``drac_sut`` (:func:`drac` to the leader; read by the
    ``conflict`` rule only), the follower's
    ``follower_ttc_s`` (:func:`follower_ttc`), ``follower_accel`` (0 without one) and
    ``follower_thw_s`` (:func:`follower_headway`), ``attributed`` (:func:`rear_attributed`), the
    leader's ``leader_gap_m`` (``inf`` without one) and ``leader_speed`` (``nan`` without one),
    ``sut_speed``, ``cut_in_gap_m`` (:func:`cut_in_gap`) and ``beside_gap_m`` (:func:`beside_gap`).
    The defaults are the values without the vehicle in question. ``headway_run``: the states of
    the tailgating condition held unbroken before the first state given.

    Returns the terms and the headway run at the last state (the next call's ``headway_run``).
    """
    ev = evaluation
    low_ttc = ttc < ev.ttc_threshold_s
    braking = hard_braking_dangerous(sut_accel, drac_sut, follower_thw_s, ev.hard_brake_mps2, ev.hard_braking,
                                     ev.rear_braking_headway_s)
    front = low_ttc | braking
    rear_conflict = rear_dangerous(follower_ttc_s, follower_accel, follower_thw_s, ev.ttc_threshold_s,
                                   ev.hard_brake_mps2, ev.rear_braking, ev.rear_braking_headway_s)
    rear = rear_conflict & attributed
    cut_in = cut_in_dangerous(cut_in_gap_m, ev.cut_in_gap_m)
    beside = beside_dangerous(beside_gap_m, ev.beside_lane_change)
    headway = headway_dangerous(leader_gap_m, sut_speed, leader_speed, ev.headway_threshold_s)
    tailgating, headway_run = held_longer_than(headway, grace_steps(ev.headway_grace_s, dt_s), headway_run)
    danger = front | rear | cut_in | beside | tailgating
    return DangerTerms(low_ttc, braking, front, rear_conflict, rear, cut_in, beside, tailgating, danger), headway_run


def attribution_steps(rear_attribution_s: float, dt_s: float) -> int:
    """The attribution window after a SUT lane change in states: floor(rear_attribution_s / dt + 1e-9)."""
    return int(np.floor(rear_attribution_s / dt_s + 1e-9))


def rear_attributed(sut_lane_change: np.ndarray, mode: str, after_steps: int) -> np.ndarray:
    """Whether a rear conflict in each state is the SUT's (1-D, one entry per state from state 0).

    ``after_lane_change``: from the first state of a SUT lane change (its ``lane_change``
    column non-zero) until ``after_steps`` states after the last one (the column back to 0:
    completed or aborted), both ends included: k - k_last <= after_steps, k_last the latest
    state <= k with the column non-zero. ``all``: every state. ``none``: no state.
    """
    lc = np.asarray(sut_lane_change)
    k = np.arange(lc.shape[0])
    if mode == "all":
        return np.ones(lc.shape[0], dtype=bool)
    if mode == "none":
        return np.zeros(lc.shape[0], dtype=bool)
    if mode != "after_lane_change":
        raise ValueError(f"rear_conflicts {mode!r}: expected one of {', '.join(REAR_CONFLICT_MODES)}")
    last = np.maximum.accumulate(np.where(lc != 0, k, -1)) if lc.size else np.zeros(0, dtype=np.int64)
    return (last >= 0) & (k - last <= after_steps)


class RearAttribution:
    """:func:`rear_attributed` one state at a time (the live monitor): feed every state in order."""

    def __init__(self, mode: str, after_steps: int) -> None:
        if mode not in REAR_CONFLICT_MODES:
            raise ValueError(f"rear_conflicts {mode!r}: expected one of {', '.join(REAR_CONFLICT_MODES)}")
        self.mode, self.after_steps = mode, int(after_steps)
        self.last: int | None = None

    def observe(self, k: int, sut_lane_change: int) -> bool:
        """Whether state ``k`` is attributed, given the SUT's ``lane_change`` column there."""
        if self.mode == "all":
            return True
        if self.mode == "none":
            return False
        if sut_lane_change != 0:
            self.last = k
        return self.last is not None and k - self.last <= self.after_steps


def exposure_runs(danger: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Maximal runs of ``True`` in a 1-D boolean array: ``(starts, ends)``, ``ends`` exclusive.

    A run still open at the end of the array ends at ``len(danger)``.
    """
    x = np.concatenate(([False], np.asarray(danger, dtype=bool), [False]))
    edges = np.flatnonzero(x[1:] != x[:-1])
    return edges[0::2], edges[1::2]
