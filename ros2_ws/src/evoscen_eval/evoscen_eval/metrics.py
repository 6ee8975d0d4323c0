"""Scores of a run (docs/method.md §5.1-5.2), vectorized over the recorded states.

Input: a :class:`~evoscen_eval.rundata.RunData` (``[K, V]`` arrays, K world states) and the
scenario's :class:`~evoscen_sim.config.EvaluationConfig`. Output: the ``report.json`` dict
(:func:`evaluate`) — every score with the inputs of its formula, so the arithmetic can be
checked by hand.

The **[choice]** points the method leaves open, as implemented (all configurable under
``evaluation.*``; docs/evaluation.md states them with their reasons):

* **Dangerous state / exposure** — :mod:`evoscen_sim.safety`: TTC to the vehicle ahead in the
  SUT's path < ``ttc_threshold_s`` or SUT acceleration < ``-hard_brake_mps2``, or a rear
  conflict attributed to the SUT (``rear_conflicts`` [after_lane_change]: the follower in its
  path with TTC < ``ttc_threshold_s`` or braking below ``-hard_brake_mps2`` within
  ``rear_braking_headway_s`` [2 s] of time headway (``rear_braking`` [within_headway]), from the
  start of a SUT lane change to ``rear_attribution_s`` [5 s] after it); an exposure is a maximal run of
  dangerous states; one still open at the end of the run counts (flagged ``open_at_end``).
* **Conflicts** (``safety.conflicts``, reported only) — follower TTC, DRAC of the SUT and of
  its follower (SUMO SSM's definitions; states above ``drac_threshold_mps2`` [3 m/s²]), and
  a lane-change PET per SUT lane change (:func:`lane_change_pet`).
* **Undefined terms** (``undefined_terms`` [exclude]) — without a completed SUT lane change
  T̄_l is undefined and I_e is the density-speed term alone; without any SUT lane change I_i
  is undefined (``null``) and I renormalises the remaining weights. ``literal``: the old
  arithmetic (T̄_l = ``no_lane_change_time_s``, I_i = 1).
* **Collisions C** — the ``evoscen/collision`` events involving the SUT (the simulation
  emits one per contact, not one per overlapping step); ``collisions_all`` counts every pair.
* **View** — every other vehicle whose reference point is from ``view_behind_m`` [20 m]
  behind to ``view_ahead_m`` [100 m] ahead of the SUT's, all lanes.
  h̄ = mean number of vehicles in view over the states;
  H = ``view_lanes`` × floor((behind + ahead) / ``min_spacing_m``) [5 × floor(120/6.8) = 85].
* **Efficiency** — v̄ = mean SUT speed over the states; T̄_l = mean duration of the SUT's
  completed lane changes (decision → centre of mass in the new lane, from the
  ``evoscen/lane_change`` events); without any, undefined (above; ``literal``: T̄_l =
  ``no_lane_change_time_s`` [0 s]). Density-speed term ``literal`` [default]: √h̄·v̄/(H·v_max), as the
  method writes it; ``normalised``: √(h̄/H)·v̄/v_max.
* **Interaction** — over the SUT's lane changes (maximal runs of states with the SUT's
  ``lane_change`` column at one non-zero value; a change still in progress at the end
  counts): for each change starting at state k0, the samples are (state k, BV j in view at
  k) for k in the change; |v~| = mean |v_j(k) − v_j(k0)|, |a~| = mean |a_j(k) − a_j(k0)|;
  L̄ = mean, over the BVs in view at any state of the change, of their lane-change starts
  during it. Each change weighs equally (mean of the per-change values). A change with no
  BV in view contributes 0 to all three; without any SUT lane change I_i is undefined
  (``literal``: |v~| = |a~| = L̄ = 0, so I_i = 1).
* **Complexity** — windows of ``window_steps`` [100] consecutive states from state 0, whole
  windows only; per window LC = lane-change starts of all vehicles (a vehicle's
  ``lane_change`` becoming non-zero or switching direction), AD = vehicle-states with
  |acceleration| > ``accel_activity_mps2`` [0.1 m/s²] — by default the acceleration averaged
  over the trailing ``accel_activity_window_s`` [1 s] (``accel_activity_form: smoothed``,
  manoeuvres rather than per-step noise; ``literal``: per step), E = SUT exposures starting in it;
  LC, AD, E are averaged over the windows (and over rounds by the experiment) before C is
  computed. A run shorter than one window has no complexity (``null`` and a warning).
"""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Any

import numpy as np

from evoscen_contract import contract as C
from evoscen_sim.safety import (attribution_steps, dangerous, drac, exposure_runs, follower_headway, follower_ttc,
                                rear_attributed, rear_dangerous, sut_follower, sut_leader, sut_ttc)

from .rundata import EXTERNAL_SUT, RunData


# ---------------------------------------------------------------------- formulas (scalars)


def safety_score(collisions: int, exposures: int, collision_cap: int) -> float:
    """I_s = 0.7·(1 − min(C, C_max)/C_max) + 0.3·e^(−E)  (docs/method.md eq. (21))."""
    return 0.7 * (1.0 - min(collisions, collision_cap) / collision_cap) + 0.3 * math.exp(-exposures)


def efficiency_score(mean_in_view: float, max_in_view: int, mean_speed: float, v_max: float,
                     lane_change_time: float, time_scale: float, density: str = "literal") -> tuple[float, float, float]:
    """I_e = 0.5·(density-speed term + e^(−T̄_l/3))  (docs/method.md eq. (22)); returns (I_e, term 1, term 2)."""
    if density == "literal":
        term1 = math.sqrt(mean_in_view) * mean_speed / (max_in_view * v_max)
    elif density == "normalised":
        term1 = math.sqrt(mean_in_view / max_in_view) * mean_speed / v_max
    else:
        raise ValueError(f"efficiency density form {density!r}: expected 'literal' or 'normalised'")
    term2 = math.exp(-lane_change_time / time_scale)
    return 0.5 * (term1 + term2), term1, term2


def interaction_score(speed_fluct: float, accel_fluct: float, bv_lane_changes: float,
                      dv_max: float, da_max: float) -> float:
    """I_i = (1/3)·(2 − clip(|v~|)/Δv_max − clip(|a~|)/Δa_max + e^(−√L̄))  (docs/method.md eq. (23))."""
    v_term = min(max(speed_fluct, 0.0), dv_max) / dv_max
    a_term = min(max(accel_fluct, 0.0), da_max) / da_max
    return (2.0 - v_term - a_term + math.exp(-math.sqrt(bv_lane_changes))) / 3.0


def complexity_score(exposures: float, lane_changes: float, accel_decel: float,
                     k1: float, k2: float, k3: float) -> float:
    """C = 0.4·(1 − e^(−E/k1)) + 0.3·(2 − e^(−LC/k2) − e^(−AD/k3))  (docs/method.md §5.2)."""
    return 0.4 * (1.0 - math.exp(-exposures / k1)) + 0.3 * (2.0 - math.exp(-lane_changes / k2)
                                                            - math.exp(-accel_decel / k3))


def max_in_view(ev) -> int:  # noqa: ANN001 - EvaluationConfig
    """H: the most vehicles that fit in the view at minimum spacing."""
    return ev.view_lanes * max(1, math.floor((ev.view_behind_m + ev.view_ahead_m) / ev.min_spacing_m))


# ---------------------------------------------------------------------- per-state quantities


def lane_change_starts(lane_change: np.ndarray) -> np.ndarray:
    """``[K, V]`` bool: a lane change starts at state k (the column becomes non-zero or switches sign)."""
    lc = np.asarray(lane_change)
    prev = np.vstack([np.zeros((1,) + lc.shape[1:], dtype=lc.dtype), lc[:-1]])
    return (lc != 0) & (lc != prev)


def change_intervals(lane_change: np.ndarray) -> list[tuple[int, int]]:
    """The ``[k0, k1)`` state intervals of one vehicle's lane changes (1-D column)."""
    lc = np.asarray(lane_change)
    starts = np.flatnonzero(lane_change_starts(lc[:, None])[:, 0])
    out = []
    for k0 in starts:
        k1 = k0 + 1
        while k1 < len(lc) and lc[k1] == lc[k0]:
            k1 += 1
        out.append((int(k0), int(k1)))
    return out


def activity_accel(accel: np.ndarray, dt_s: float, form: str, window_s: float) -> np.ndarray:
    """The ``[K, V]`` acceleration AD compares with its threshold (docs/evaluation.md, "AD").

    ``literal``: the per-state acceleration as recorded. ``smoothed``: at state k the mean of
    the last ``n = max(1, round(window_s / dt_s))`` states' accelerations (k−n+1..k; fewer at
    the start of the run) — the speed change over the window divided by its length, so
    per-step noise that averages out (Krauss dawdling: i.i.d. speed draws just below the
    desired speed) is not counted as activity, while a manoeuvre (braking or accelerating
    for a second or more) is.
    """
    a = np.asarray(accel, dtype=float)
    if form == "literal":
        return a
    if form != "smoothed":
        raise ValueError(f"accel_activity_form {form!r}: expected 'smoothed' or 'literal'")
    n = max(1, int(round(window_s / dt_s)))
    csum = np.cumsum(np.vstack([np.zeros((1,) + a.shape[1:]), a]), axis=0)
    k = np.arange(1, a.shape[0] + 1)
    lo = np.maximum(k - n, 0)
    count = (k - lo).reshape((-1,) + (1,) * (a.ndim - 1))
    return (csum[k] - csum[lo]) / count


def lane_change_pet(run: RunData, intervals: list[tuple[int, int]], after_steps: int) -> list[dict[str, Any]]:
    """The lane-change PET equivalent of each SUT lane change (docs/evaluation.md).

    For a change over states ``[k0, k1)`` into target lane T (the SUT's ``target_lane`` at
    k0), over the states k0 <= k < k1 + ``after_steps`` (and < K): the *new follower* at k is
    the nearest vehicle j != SUT with lane_j(k) = T, centre behind the SUT's and body
    overlapping the SUT's laterally (in its path: the SUT's body has entered lane T);
    PET(k) = max(gap, 0) / v_j, gap = s_sut − s_j − (l_sut + l_j)/2 (bumper to bumper), the
    time until the follower's front reaches the point the SUT's rear occupies, at its
    current speed (``inf`` when v_j <= 0). The change's PET is the minimum over those
    states; ``None`` when no state has a new follower.
    """
    c, sut, K = run.columns, run.sut_index, run.states
    out = []
    for k0, k1 in intervals:
        k_end = min(k1 + after_steps, K)
        target = int(c["target_lane"][k0, sut])
        s, d, v = c["s"][k0:k_end], c["d"][k0:k_end], c["speed"][k0:k_end]
        length, width, lane = c["length"][k0:k_end], c["width"][k0:k_end], c["lane"][k0:k_end]
        back = s[:, sut:sut + 1] - s
        cand = (back > 0.0) & (np.abs(d - d[:, sut:sut + 1]) < 0.5 * (width + width[:, sut:sut + 1])) \
            & (lane == target)
        cand[:, sut] = False
        j = np.argmin(np.where(cand, back, np.inf), axis=1)
        rows = np.arange(k_end - k0)
        has = cand[rows, j]
        gap = back[rows, j] - 0.5 * (length[rows, j] + length[:, sut])
        vj = v[rows, j]
        with np.errstate(divide="ignore", invalid="ignore"):
            pet = np.where(has & (vj > 0.0), np.maximum(gap, 0.0) / vj, np.inf)
        entry: dict[str, Any] = {"start_state": k0, "end_state": k1, "window_end_state": k_end,
                                 "target_lane": target, "pet_s": None, "state": None, "follower_id": None}
        if has.any():
            m = int(np.argmin(pet))
            entry.update({"pet_s": _finite(float(pet[m])), "state": k0 + m, "follower_id": int(run.ids[j[m]])})
        out.append(entry)
    return out


class Series:
    """Per-state series of a run, for the scores and the plots."""

    def __init__(self, run: RunData, ev) -> None:  # noqa: ANN001
        c, sut = run.columns, run.sut_index
        self.sut = sut
        self.ttc = sut_ttc(c["s"], c["d"], c["speed"], c["length"], c["width"], sut)
        self.speed = c["speed"][:, sut]
        self.accel = c["accel"][:, sut]
        self.lane = c["lane"][:, sut]
        self.front_danger = dangerous(self.ttc, self.accel, ev.ttc_threshold_s, ev.hard_brake_mps2)
        # the rear (docs/evaluation.md): follower in the SUT's path, attribution window
        self.follower, self.follower_ttc = follower_ttc(c["s"], c["d"], c["speed"], c["length"], c["width"], sut)
        has_f = self.follower >= 0
        rows = np.arange(run.states)
        self.follower_accel = np.where(has_f, c["accel"][rows, np.maximum(self.follower, 0)], 0.0)
        self.after_steps = attribution_steps(ev.rear_attribution_s, run.dt_s)
        self.attributed = rear_attributed(c["lane_change"][:, sut], ev.rear_conflicts, self.after_steps)
        _, f_gap = sut_follower(c["s"], c["d"], c["length"], c["width"], sut)
        f_speed = np.where(has_f, c["speed"][rows, np.maximum(self.follower, 0)], np.nan)
        self.follower_thw = follower_headway(f_gap, f_speed)
        self.rear_conflict = rear_dangerous(self.follower_ttc, self.follower_accel, self.follower_thw,
                                            ev.ttc_threshold_s, ev.hard_brake_mps2, ev.rear_braking,
                                            ev.rear_braking_headway_s)
        self.rear_danger = self.rear_conflict & self.attributed
        self.danger = self.front_danger | self.rear_danger
        # DRAC of the SUT behind its leader and of the follower behind the SUT (reported only)
        leader, gap = sut_leader(c["s"], c["d"], c["length"], c["width"], sut)
        l_speed = np.where(leader >= 0, c["speed"][rows, np.maximum(leader, 0)], np.nan)
        self.drac_sut = drac(gap, self.speed, l_speed)
        self.drac_follower = drac(f_gap, f_speed, self.speed)
        ds = c["s"] - c["s"][:, sut:sut + 1]
        in_view = (ds >= -ev.view_behind_m) & (ds <= ev.view_ahead_m)
        in_view[:, sut] = False
        self.in_view = in_view
        self.starts, self.ends = exposure_runs(self.danger)
        self.time_s = run.time_s


# ---------------------------------------------------------------------- the report


def _finite(x: float) -> float | None:
    """JSON has no infinity: ``None`` for a non-finite number."""
    return float(x) if math.isfinite(x) else None


def evaluate(run: RunData, ev) -> dict[str, Any]:  # noqa: ANN001 - EvaluationConfig
    """The scores of ``run`` as the ``report.json`` dict (see the module docstring)."""
    K = run.states
    warnings_extra: list[str] = []
    series = Series(run, ev)
    c, sut = run.columns, run.sut_index
    sut_id = int(run.ids[sut])

    # --- safety
    collisions = run.events_named(C.EVENT_COLLISION)
    sut_collisions = [e for e in collisions if sut_id in e.get("ids", [])]
    exposures = []
    for k0, k1 in zip(series.starts, series.ends):
        ttc = series.ttc[k0:k1]
        acc = series.accel[k0:k1]
        severity = np.maximum(ev.ttc_threshold_s / np.maximum(ttc, 1e-3), -acc / ev.hard_brake_mps2)
        rear = series.rear_danger[k0:k1]
        if rear.any():  # an attributed rear conflict is as severe as the same TTC/braking ahead
            f_sev = np.maximum(ev.ttc_threshold_s / np.maximum(series.follower_ttc[k0:k1], 1e-3),
                               -series.follower_accel[k0:k1] / ev.hard_brake_mps2)
            severity = np.where(rear, np.maximum(severity, f_sev), severity)
        worst = int(k0 + np.argmax(severity))
        exposures.append({
            "start_state": int(k0), "end_state": int(k1), "states": int(k1 - k0),
            "start_time_s": float(run.time_s[k0]), "open_at_end": bool(k1 == K),
            "min_ttc_s": _finite(float(ttc.min())), "min_accel_mps2": float(acc.min()),
            "worst_state": worst, "severity": float(severity.max()),
            "rear_states": int(rear.sum()),
        })
    n_exp = len(exposures)
    i_s = safety_score(len(sut_collisions), n_exp, ev.collision_cap)
    safety = {
        "score": i_s,
        "collisions": len(sut_collisions),
        "collisions_all": len(collisions),
        "collision_cap": ev.collision_cap,
        "exposures": n_exp,
        "exposures_open_at_end": sum(e["open_at_end"] for e in exposures),
        "dangerous_states": int(series.danger.sum()),
        "min_ttc_s": _finite(float(series.ttc.min())),
        "min_accel_mps2": float(series.accel.min()),
        "ttc_threshold_s": ev.ttc_threshold_s,
        "hard_brake_mps2": ev.hard_brake_mps2,
        "collision_list": [{"state": int(e["step"]), "time_s": float(e["time_s"]), "ids": list(e["ids"])}
                           for e in sut_collisions],
        "exposure_list": exposures,
    }

    # --- conflicts on either side of the SUT (docs/evaluation.md), reported on their own
    intervals = change_intervals(c["lane_change"][:, sut])
    pets = lane_change_pet(run, intervals, series.after_steps)
    pet_values = [p["pet_s"] for p in pets if p["pet_s"] is not None]
    att = series.attributed
    thr = ev.drac_threshold_mps2
    safety["conflicts"] = {
        "rear_conflicts": ev.rear_conflicts,
        "rear_attribution_s": ev.rear_attribution_s,
        "rear_braking": ev.rear_braking,
        "rear_braking_headway_s": ev.rear_braking_headway_s,
        "attribution_states": int(att.sum()),
        "front_dangerous_states": int(series.front_danger.sum()),
        "rear_conflict_states": int(series.rear_conflict.sum()),
        "rear_conflict_states_attributed": int(series.rear_danger.sum()),
        "rear_only_dangerous_states": int((series.rear_danger & ~series.front_danger).sum()),
        "min_follower_ttc_s": _finite(float(series.follower_ttc.min())),
        "min_follower_ttc_attributed_s": (_finite(float(series.follower_ttc[att].min())) if att.any() else None),
        "min_follower_accel_mps2": (float(series.follower_accel[series.follower >= 0].min())
                                    if (series.follower >= 0).any() else None),
        "drac_threshold_mps2": thr,
        "max_drac_sut_mps2": _finite(float(series.drac_sut.max())),
        "max_drac_follower_mps2": _finite(float(series.drac_follower.max())),
        "drac_sut_states": int((series.drac_sut > thr).sum()),
        "drac_follower_states": int((series.drac_follower > thr).sum()),
        "drac_follower_states_attributed": int(((series.drac_follower > thr) & att).sum()),
        "lane_change_pet": pets,
        "min_pet_s": min(pet_values) if pet_values else None,
    }

    # --- efficiency
    H = max_in_view(ev)
    h_mean = float(series.in_view.sum(axis=1).mean())
    v_mean = float(series.speed.mean())
    sut_changes = [e for e in run.events_named(C.EVENT_LANE_CHANGE) if e.get("ids", [None])[0] == sut_id]
    durations = [float(e["duration_s"]) for e in sut_changes if e.get("kind") == C.KIND_COMPLETED]
    exclude = ev.undefined_terms == "exclude"
    t_l = float(np.mean(durations)) if durations else ev.no_lane_change_time_s
    i_e, term1, term2 = efficiency_score(h_mean, H, v_mean, ev.v_max_mps, t_l,
                                         ev.lane_change_time_scale_s, ev.efficiency_density)
    lc_term_used = bool(durations) or not exclude
    if not lc_term_used:  # T̄_l undefined: I_e is the density-speed term alone (its weight renormalised)
        i_e, t_l, term2 = term1, None, None
    efficiency = {
        "score": i_e,
        "mean_speed_mps": v_mean,
        "mean_vehicles_in_view": h_mean,
        "max_vehicles_in_view": H,
        "v_max_mps": ev.v_max_mps,
        "density_form": ev.efficiency_density,
        "density_speed_term": term1,
        "lane_changes": len(durations),
        "lane_changes_aborted": sum(1 for e in sut_changes if e.get("kind") == C.KIND_ABORTED),
        "mean_lane_change_time_s": t_l,
        "lane_change_time_defined": bool(durations),
        "lane_change_term": term2,
        "lane_change_term_used": lc_term_used,
    }

    # --- interaction
    starts_all = lane_change_starts(c["lane_change"])
    bv = np.ones(run.ids.shape[0], dtype=bool)
    bv[sut] = False
    per_change = []
    for k0, k1 in intervals:
        view = series.in_view[k0:k1] & bv
        if view.any():
            dv = np.abs(c["speed"][k0:k1] - c["speed"][k0])[view]
            da = np.abs(c["accel"][k0:k1] - c["accel"][k0])[view]
            seen = view.any(axis=0)
            lcs = starts_all[k0:k1][:, seen].sum(axis=0)
            per_change.append((float(dv.mean()), float(da.mean()), float(lcs.mean()), int(seen.sum())))
        else:
            per_change.append((0.0, 0.0, 0.0, 0))
    v_f = float(np.mean([p[0] for p in per_change])) if per_change else 0.0
    a_f = float(np.mean([p[1] for p in per_change])) if per_change else 0.0
    l_bar = float(np.mean([p[2] for p in per_change])) if per_change else 0.0
    i_i = interaction_score(v_f, a_f, l_bar, ev.dv_max_mps, ev.da_max_mps2)
    i_i_defined = bool(intervals) or not exclude
    if not i_i_defined:  # no SUT lane change: nothing to measure, left out of I
        i_i = None
    interaction = {
        "score": i_i,
        "defined": i_i_defined,
        "sut_lane_changes": len(intervals),
        "speed_fluctuation_mps": v_f,
        "accel_fluctuation_mps2": a_f,
        "bv_lane_changes": l_bar,
        "dv_max_mps": ev.dv_max_mps,
        "da_max_mps2": ev.da_max_mps2,
        "changes": [{"start_state": k0, "end_state": k1, "speed_fluctuation_mps": p[0],
                     "accel_fluctuation_mps2": p[1], "bv_lane_changes": p[2], "bvs_in_view": p[3]}
                    for (k0, k1), p in zip(intervals, per_change)],
    }

    # --- intelligence
    weights = {"safety": ev.weight_safety, "efficiency": ev.weight_efficiency, "interaction": ev.weight_interaction}
    scores = {"safety": i_s, "efficiency": i_e, "interaction": i_i}
    defined = {k: v is not None for k, v in scores.items()}
    total_w = sum(w for k, w in weights.items() if defined[k])
    if all(defined.values()):  # the method's arithmetic, unchanged
        effective = dict(weights)
        weighted = {k: weights[k] * scores[k] for k in weights}
        score: float | None = weighted["safety"] + weighted["efficiency"] + weighted["interaction"]
    elif total_w > 0:
        effective = {k: (weights[k] / total_w if defined[k] else 0.0) for k in weights}
        weighted = {k: (effective[k] * scores[k] if defined[k] else 0.0) for k in weights}
        score = weighted["safety"] + weighted["efficiency"] + weighted["interaction"]
    else:
        effective = {k: 0.0 for k in weights}
        weighted = {k: 0.0 for k in weights}
        score = None
        warnings_extra.append("no defined intelligence term has a non-zero weight: no intelligence score")
    intelligence = {"score": score, "weights": weights, "weighted": weighted,
                    "undefined_terms": ev.undefined_terms, "defined": defined, "effective_weights": effective}

    # --- complexity
    W = ev.window_steps
    n_win = K // W
    complexity: dict[str, Any] = {"window_steps": W, "windows": n_win, "accel_activity_mps2": ev.accel_activity_mps2,
                                  "accel_activity_form": ev.accel_activity_form,
                                  "accel_activity_window_s": ev.accel_activity_window_s,
                                  "k": [ev.k_exposure, ev.k_lane_change, ev.k_accel]}
    warnings = list(run.warnings) + warnings_extra
    if n_win:
        lc_w = starts_all[: n_win * W].reshape(n_win, W, -1).sum(axis=(1, 2))
        ad_acc = activity_accel(c["accel"], run.dt_s, ev.accel_activity_form, ev.accel_activity_window_s)
        ad_w = (np.abs(ad_acc[: n_win * W]) > ev.accel_activity_mps2).reshape(n_win, W, -1).sum(axis=(1, 2))
        e_w = np.bincount(series.starts[series.starts < n_win * W] // W, minlength=n_win)
        lc, ad, e = float(lc_w.mean()), float(ad_w.mean()), float(e_w.mean())
        complexity.update({
            "score": complexity_score(e, lc, ad, ev.k_exposure, ev.k_lane_change, ev.k_accel),
            "lane_changes": lc, "accel_decel": ad, "exposures": e,
            "per_window": {"lane_changes": lc_w.tolist(), "accel_decel": ad_w.tolist(), "exposures": e_w.tolist()},
        })
    else:
        complexity.update({"score": None, "lane_changes": None, "accel_decel": None, "exposures": None,
                           "per_window": {"lane_changes": [], "accel_decel": [], "exposures": []}})
        warnings.append(f"{K} states is shorter than one complexity window ({W} states): no complexity score")

    return {
        "run": run_info(run),
        "settings": asdict(ev),
        "warnings": warnings,
        "safety": safety,
        "efficiency": efficiency,
        "interaction": interaction,
        "intelligence": intelligence,
        "complexity": complexity,
    }


def run_info(run: RunData) -> dict[str, Any]:
    """What run the report is about."""
    sc = run.scenario or {}
    return {
        "scenario": sc.get("name"),
        "seed": sc.get("seed"),
        "sut_model": EXTERNAL_SUT if run.external_sut else (sc.get("sut") or {}).get("model"),
        "bv_driver": (sc.get("bvs") or {}).get("driver"),
        "bv_count": int(run.ids.shape[0] - 1),
        "sut_id": int(run.ids[run.sut_index]),
        "states": run.states,
        "steps": run.states - 1,
        "dt_s": run.dt_s,
        "duration_s": float(run.time_s[-1] - run.time_s[0]),
        "complete": run.complete,
    }
