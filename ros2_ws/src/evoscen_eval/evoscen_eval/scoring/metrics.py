"""Scores of a run (docs/method.md §5.1-5.2).

Input: the run's states in one pass (:class:`~evoscen_eval.scoring.streaming.ScoreStream`, which holds
no ``[K, V]`` array; :func:`evaluate` streams a :class:`~evoscen_eval.scoring.rundata.RunData` through
it) and the scenario's :class:`~evoscen_sim.config.scenario_config.EvaluationConfig`. Output: the
``report.json`` dict (:func:`report_of_stream`) — every score with the inputs of its formula,
so the arithmetic can be checked by hand.

The **[choice]** points the method leaves open, as implemented (all configurable under
``evaluation.*``; docs/evaluation.md states them with their reasons):

* **Dangerous state / exposure** — :mod:`evoscen_sim.danger.safety`: TTC to the vehicle ahead in the
  SUT's path < ``ttc_threshold_s`` or SUT acceleration < ``-hard_brake_mps2``, or a rear
  conflict attributed to the SUT (``rear_conflicts`` [after_lane_change]: the follower in its
  path with TTC < ``ttc_threshold_s`` or braking below ``-hard_brake_mps2`` within
  ``rear_braking_headway_s`` [2 s] of time headway (``rear_braking`` [within_headway]), from the
  start of a SUT lane change to ``rear_attribution_s`` [5 s] after it), or a cut-in (the SUT
  changing lanes with its new follower less than ``cut_in_gap_m`` [10 m] behind), or a lane change
  beside a vehicle (``beside_lane_change`` [true]: a vehicle in the SUT's target lane overlapping
  it longitudinally while it changes lanes); an exposure is a maximal run of dangerous states; one still
  open at the end of the run counts (flagged ``open_at_end``).
* **Conflicts** (``safety.conflicts``, reported only) — follower TTC, DRAC of the SUT and of
  its follower (SUMO SSM's definitions; states above ``drac_threshold_mps2`` [3 m/s²]), and
  a lane-change PET per SUT lane change (:func:`lane_change_pet`).
* **Surrogate safety** (``surrogate_safety``, reported only, :func:`surrogate_safety_of_stream`)
  — on the SUT's front and rear: episodes of TTC < ``ssm_ttc_threshold_s`` [3 s] and of DRAC >
  ``drac_threshold_mps2`` [3 m/s²], SUT lane changes with PET < ``ssm_pet_threshold_s`` [2 s]
  (rear: the new follower), TET and TIT (Minderhoud & Bovy 2001), each also per SUT-km.
* **Undefined terms** (``undefined_terms`` [exclude]) — without a completed SUT lane change
  T̄_l is undefined and I_e is the density-speed term alone; without any SUT lane change I_i
  is undefined (``null``) and I renormalises the remaining weights. ``literal``: the old
  arithmetic (T̄_l = ``no_lane_change_time_s``, I_i = 1).
* **Comparative score** (``comparative``, docs/evaluation.md §10; :func:`comparative_of_stream`) —
  D = P·(i_s·S + i_e·L + i_i·X) with the method's weights, never renormalised: P = min(1, the SUT's
  distance / the distance at the mean speed of the vehicles in its view), S = 1/(1 + r/r0) with r =
  (E + κ·C) per SUT-km, L and X the lane-change time and interaction terms or
  ``no_lane_change_value`` without a SUT lane change. ``score_form`` says which score experiments
  compare (:func:`compared_scores`); I is reported unchanged.
* **Collisions C** — the ``evoscen/collision`` events involving the SUT (the simulation
  emits one per contact, not one per overlapping step); ``collisions_all`` counts every pair.
* **Counts in I_s** (``count_normalisation`` [method_length]) — C and E are counted per run;
  they enter I_s scaled to the method's run length, C·N_ref/N and E·N_ref/N (N = the steps
  scored, states − 1; N_ref = ``count_reference_steps`` [3000]), so a 3,000-step run scores its
  counts as they are and a run's length does not move its expected I_s; ``literal``: as counted
  (a longer run of the same SUT scores lower). The report gives the raw counts, N, the factor
  and the counts used.
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

Beside the scores, read by none: the **traffic around the SUT** (:func:`traffic_of_stream`, docs/evaluation.md
§8: BVs within 100 m, any lane, per 30-s window); a challenge run's **challenge** section (docs/challenges.md).
"""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Any

import numpy as np
from evoscen_contract import contract as C
from evoscen_sim.danger.safety import attribution_steps

from evoscen_eval.scoring.challenge_section import challenge_of_events
from evoscen_eval.scoring.rundata import RunData, run_info_of
from evoscen_eval.scoring.streaming import SSM_SIDES, TRAFFIC_RANGE_M, TRAFFIC_WINDOW_S, ScoreStream, activity_accel, traffic_window_states  # noqa: F401 - activity_accel: AD's definition, here with the scores
from evoscen_eval.scoring.sut_collisions import COLLISION_KINDS

# ---------------------------------------------------------------------- formulas (scalars)


def safety_score(collisions: float, exposures: float, collision_cap: int) -> float:
    """I_s = 0.7·(1 − min(C, C_max)/C_max) + 0.3·e^(−E)  (docs/method.md eq. (21)); C and E as
    they enter the score (:func:`scored_counts`)."""
    return 0.7 * (1.0 - min(collisions, collision_cap) / collision_cap) + 0.3 * math.exp(-exposures)


def scored_counts(collisions: int, exposures: int, steps: int, normalisation: str,
                  reference_steps: int) -> tuple[float, float, float, str | None]:
    """C and E as they enter I_s (``evaluation.count_normalisation``): ``method_length`` scales the
    run's counts to ``reference_steps`` steps, C·N_ref/N and E·N_ref/N with N = ``steps`` (the
    steps scored: states − 1), so a run of N_ref steps gives its counts unchanged (to the bit);
    ``literal`` gives the counts as counted. Returns (C, E, the factor N_ref/N, a warning or None):
    a run of 0 steps (a single state) has no length to scale by, its counts enter as counted."""
    if normalisation == "literal":
        return collisions, exposures, 1.0, None
    if normalisation != "method_length":
        raise ValueError(f"count normalisation {normalisation!r}: expected 'method_length' or 'literal'")
    if steps < 1:
        return collisions, exposures, 1.0, ("a run of 0 steps has no length to scale the safety counts by "
                                             "(count_normalisation: method_length): C and E enter I_s as counted")
    return collisions * reference_steps / steps, exposures * reference_steps / steps, reference_steps / steps, None


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


def progress_score(sut_distance_m: float, reference_distance_m: float) -> float:
    """P = min(1, d_SUT / d_ref): the SUT's distance over the distance the traffic around it
    covered in the same time (docs/evaluation.md §10.2); 1 where the reference is 0 (the traffic
    allowed no progress, none is owed)."""
    if reference_distance_m <= 0.0:
        return 1.0
    return min(1.0, max(sut_distance_m, 0.0) / reference_distance_m)


def comparative_safety_score(collisions: float, exposures: float, sut_km: float, scale_per_km: float,
                             collision_exposures: float) -> tuple[float, float]:
    """S = 1/(1 + r/r0), r = (E + κ·C)/km the SUT's exposure rate per SUT-km with a collision
    counting κ exposures, r0 = ``scale_per_km`` (docs/evaluation.md §10.1). Returns (S, r): no
    count gives S = 1 however far the SUT drove; counts over 0 km give r = ∞, S = 0."""
    count = exposures + collision_exposures * collisions
    if count <= 0.0:
        return 1.0, 0.0
    if sut_km <= 0.0:
        return 0.0, math.inf
    rate = count / sut_km
    return 1.0 / (1.0 + rate / scale_per_km), rate


def comparative_score(progress: float, safety: float, lane_change_time: float, interaction: float,
                      weights: tuple[float, float, float]) -> float:
    """D = P·(i_s·S + i_e·L + i_i·X)  (docs/evaluation.md §10): every term defined in every run,
    the weights never renormalised."""
    w_s, w_e, w_i = weights
    return progress * (w_s * safety + w_e * lane_change_time + w_i * interaction)


def max_in_view(ev) -> int:  # EvaluationConfig
    """H: the most vehicles that fit in the view at minimum spacing."""
    return ev.view_lanes * max(1, math.floor((ev.view_behind_m + ev.view_ahead_m) / ev.min_spacing_m))


# ---------------------------------------------------------------------- per-state quantities


# ---------------------------------------------------------------------- the report


def _finite(x: float) -> float | None:
    """JSON has no infinity: ``None`` for a non-finite number."""
    return float(x) if math.isfinite(x) else None


def evaluate(run: RunData, ev) -> dict[str, Any]:  # EvaluationConfig
    """The scores of ``run`` as the ``report.json`` dict (see the module docstring): its states
    streamed through :class:`~evoscen_eval.scoring.streaming.ScoreStream`, as every runner scores."""
    return report_of_stream(stream_run(run, ev), run_info(run), list(run.warnings))


def stream_run(run: RunData, ev) -> ScoreStream:  # EvaluationConfig
    """A finished :class:`~evoscen_eval.scoring.streaming.ScoreStream` fed the states and events of ``run``."""
    stream = ScoreStream(ev, run.dt_s)
    stream.add_events(run.events)
    order = [run.columns[f] for f in C.WORLD_FIELDS]
    for k in range(run.states):
        stream.add_state(np.stack([col[k] for col in order], axis=-1), int(round(float(run.time_s[k]) * 1e9)),
                         float(run.time_s[k]))
    stream.finish()
    return stream


def report_of_stream(st: ScoreStream, info: dict[str, Any], warnings: list[str]) -> dict[str, Any]:
    """The ``report.json`` dict from a finished stream, ``run_info`` and the run's warnings."""
    st.finish()
    ev = st.ev
    warnings_extra: list[str] = []
    safety, i_s, sut_collisions, n_exp = _safety_of_stream(st, warnings_extra)
    safety["conflicts"], pets = _conflicts_of_stream(st)
    efficiency, i_e, durations = _efficiency_of_stream(st)
    interaction, i_i, per_change = _interaction_of_stream(st)
    intelligence = _intelligence_of_scores(ev, i_s, i_e, i_i, warnings_extra)
    comparative = comparative_of_stream(st, len(sut_collisions), n_exp, durations, per_change)
    warnings = list(warnings) + warnings_extra
    complexity = _complexity_of_stream(st, warnings)
    return {  # a reader meets D first, then the method's I, then their inputs (docs/evaluation.md, "Symbols")
        "run": info,
        "warnings": warnings,
        "comparative": comparative,
        "intelligence": intelligence,
        "settings": asdict(ev),
        "safety": safety,
        "efficiency": efficiency,
        "interaction": interaction,
        "complexity": complexity,
        "traffic": traffic_of_stream(st),
        "surrogate_safety": surrogate_safety_of_stream(st, [p["pet_s"] for p in pets]),
        **({"challenge": challenge_of_events(st.challenges)} if st.challenges else {}),  # a run with the layer only
    }


def _safety_of_stream(st: ScoreStream, warnings_extra: list[str]) -> tuple[dict[str, Any], float, list, int]:
    """The report's ``safety`` section (without ``conflicts``), I_s, the SUT's collisions and the
    number of exposures; a count-normalisation warning goes to ``warnings_extra``."""
    ev = st.ev
    K = st.states
    exposures = st.exposures
    n_exp = len(exposures)
    sut_collisions = st.sut_collisions
    n_steps = max(K - 1, 0)  # the steps scored: state 0 is the initial one
    c_used, e_used, factor, count_warning = scored_counts(len(sut_collisions), n_exp, n_steps, ev.count_normalisation,
                                                          ev.count_reference_steps)
    if count_warning:
        warnings_extra.append(count_warning)
    i_s = safety_score(c_used, e_used, ev.collision_cap)
    safety = {
        "score": i_s,
        "collisions": len(sut_collisions),
        "collisions_all": st.collisions_all,
        "collision_cap": ev.collision_cap,
        "exposures": n_exp,
        "count_normalisation": ev.count_normalisation,
        "count_reference_steps": ev.count_reference_steps,
        "steps": n_steps,
        "count_factor": factor,
        "collisions_used": c_used,
        "exposures_used": e_used,
        "exposures_open_at_end": sum(e["open_at_end"] for e in exposures),
        "dangerous_states": st.n["danger"],
        "min_ttc_s": _finite(st.min_ttc),
        "min_accel_mps2": st.min_accel,
        "ttc_threshold_s": ev.ttc_threshold_s,
        "hard_brake_mps2": ev.hard_brake_mps2,
        "collision_list": [{"state": int(e["step"]), "time_s": float(e["time_s"]), "ids": list(e["ids"]),
                            "kind": st.collision_kinds.get(i, "unknown")}
                           for i, e in enumerate(sut_collisions)],
        "collisions_by_kind": {kind: sum(st.collision_kinds.get(i, "unknown") == kind
                                         for i in range(len(sut_collisions)))
                               for kind in (*COLLISION_KINDS, "unknown")},
        "exposure_list": exposures,
    }

    return safety, i_s, sut_collisions, n_exp


def _conflicts_of_stream(st: ScoreStream) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The ``safety.conflicts`` section (conflicts on either side of the SUT, docs/evaluation.md,
    reported on their own) and each SUT lane change's PET record."""
    ev = st.ev
    K = st.states
    changes = st.finished_changes
    after = attribution_steps(ev.rear_attribution_s, st.dt_s if st.dt_s is not None else 0.1)
    pets = [{"start_state": ch.k0, "end_state": ch.k1, "window_end_state": min(ch.k1 + after, K),
             "target_lane": ch.target, "pet_s": _finite(ch.pet) if ch.pet_any else None,
             "state": ch.pet_state if ch.pet_any else None, "follower_id": ch.pet_follower if ch.pet_any else None}
            for ch in changes]
    pet_values = [p["pet_s"] for p in pets if p["pet_s"] is not None]
    thr = ev.drac_threshold_mps2
    conflicts = {
        "rear_conflicts": ev.rear_conflicts,
        "rear_attribution_s": ev.rear_attribution_s,
        "rear_braking": ev.rear_braking,
        "rear_braking_headway_s": ev.rear_braking_headway_s,
        "attribution_states": st.n["attributed"],
        "front_dangerous_states": st.n["front"],
        "rear_conflict_states": st.n["rear_conflict"],
        "rear_conflict_states_attributed": st.n["rear_danger"],
        "rear_only_dangerous_states": st.n["rear_only"],
        "cut_in_gap_m": ev.cut_in_gap_m,
        "cut_in_states": st.n["cut_in"],
        "cut_in_only_dangerous_states": st.n["cut_in_only"],
        "min_cut_in_gap_m": _finite(st.min_cut_in_gap),
        "beside_lane_change": ev.beside_lane_change,
        "beside_states": st.n["beside"],
        "beside_only_dangerous_states": st.n["beside_only"],
        "min_beside_gap_m": _finite(st.min_beside_gap),
        "headway_threshold_s": ev.headway_threshold_s,
        "headway_states": st.n["headway"],
        "headway_only_dangerous_states": st.n["headway_only"],
        "min_follower_ttc_s": _finite(st.min_f_ttc),
        "min_follower_ttc_attributed_s": _finite(st.min_f_ttc_att) if st.any_att else None,
        "min_follower_accel_mps2": st.min_f_accel if st.any_follower else None,
        "drac_threshold_mps2": thr,
        "max_drac_sut_mps2": _finite(st.max_drac_sut),
        "max_drac_follower_mps2": _finite(st.max_drac_f),
        "drac_sut_states": st.n["drac_sut"],
        "drac_follower_states": st.n["drac_follower"],
        "drac_follower_states_attributed": st.n["drac_follower_att"],
        "lane_change_pet": pets,
        "min_pet_s": min(pet_values) if pet_values else None,
    }

    return conflicts, pets


def _efficiency_of_stream(st: ScoreStream) -> tuple[dict[str, Any], float, list[float]]:
    """The report's ``efficiency`` section, I_e and the completed SUT lane changes' durations (s)."""
    ev = st.ev
    K = st.states
    H = max_in_view(ev)
    h_mean = st.n["in_view"] / K
    v_mean = st.speed_sum / K
    sut_changes = st.sut_lane_changes
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
    return efficiency, i_e, durations


def _interaction_of_stream(st: ScoreStream) -> tuple[dict[str, Any], float | None, list[tuple[float, float, float, int]]]:
    """The report's ``interaction`` section, I_i (None when undefined and left out) and each SUT lane
    change's (|v~|, |a~|, L̄, BVs in view)."""
    ev = st.ev
    changes = st.finished_changes
    exclude = ev.undefined_terms == "exclude"
    intervals = [(ch.k0, ch.k1) for ch in changes]
    per_change = []
    for ch in changes:
        if ch.samples:
            seen = ch.seen
            per_change.append((ch.dv_sum / ch.samples, ch.da_sum / ch.samples, float(ch.starts[seen].mean()),
                               int(seen.sum())))
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
    return interaction, i_i, per_change


def _intelligence_of_scores(ev, i_s: float, i_e: float, i_i: float | None, warnings_extra: list[str]) -> dict[str, Any]:
    """The report's ``intelligence`` section: the weighted sum of the defined terms (the weights of an
    undefined one renormalised over the others); a warning goes to ``warnings_extra`` when none is left."""
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
    return intelligence


def _complexity_of_stream(st: ScoreStream, warnings: list[str]) -> dict[str, Any]:
    """The report's ``complexity`` section, over the run's whole windows (a warning goes to
    ``warnings`` when the run is shorter than one)."""
    ev = st.ev
    K = st.states
    W = ev.window_steps
    n_win = K // W
    complexity: dict[str, Any] = {"window_steps": W, "windows": n_win, "accel_activity_mps2": ev.accel_activity_mps2,
                                  "accel_activity_form": ev.accel_activity_form,
                                  "accel_activity_window_s": ev.accel_activity_window_s,
                                  "k": [ev.k_exposure, ev.k_lane_change, ev.k_accel]}
    if n_win:
        lc_w, ad_w, e_w = (np.asarray(st.windows[key][:n_win], dtype=np.int64)
                           for key in ("lane_changes", "accel_decel", "exposures"))
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

    return complexity


def comparative_of_stream(st: ScoreStream, collisions: int, exposures: int, durations: list[float],
                          per_change: list[tuple[float, float, float, int]]) -> dict[str, Any]:
    """The report's ``comparative`` section: the comparative score D and its terms with their
    inputs (docs/evaluation.md §10). ``durations``: the completed SUT lane changes' times (s);
    ``per_change``: each SUT lane change's (|v~|, |a~|, L̄, BVs in view), as I_i reads them."""
    ev = st.ev
    dt = st.dt_s if st.dt_s is not None else 0.1
    d_sut = dt * st.speed_sum
    d_ref = dt * st.ref_speed_sum
    p = progress_score(d_sut, d_ref)
    km = d_sut / 1000.0
    s, rate = comparative_safety_score(collisions, exposures, km, ev.safety_rate_scale_per_km,
                                       ev.collision_exposures)
    neutral = ev.no_lane_change_value
    t_l = float(np.mean(durations)) if durations else None
    lct = math.exp(-t_l / ev.lane_change_time_scale_s) if durations else neutral
    if per_change:
        x = interaction_score(float(np.mean([c[0] for c in per_change])), float(np.mean([c[1] for c in per_change])),
                              float(np.mean([c[2] for c in per_change])), ev.dv_max_mps, ev.da_max_mps2)
    else:
        x = neutral
    weights = {"safety": ev.weight_safety, "lane_change_time": ev.weight_efficiency,
               "interaction": ev.weight_interaction}
    terms = {"safety": s, "lane_change_time": lct, "interaction": x}
    return {
        "name": D_NAME, "formula": "D = P·({:g}·S + {:g}·L + {:g}·X)".format(*weights.values()),
        "score": comparative_score(p, s, lct, x, (weights["safety"], weights["lane_change_time"],
                                                  weights["interaction"])),
        "score_form": ev.score_form,
        "progress": {"score": p, "sut_distance_m": d_sut, "reference_distance_m": d_ref,
                     "reference_mean_speed_mps": st.ref_speed_sum / st.states,
                     "states_without_vehicle_in_view": st.ref_empty_states, "v_max_mps": ev.v_max_mps},
        "safety": {"score": s, "collisions": collisions, "exposures": exposures,
                   "collision_exposures": ev.collision_exposures, "sut_km": km, "rate_per_km": _finite(rate),
                   "rate_scale_per_km": ev.safety_rate_scale_per_km},
        "lane_change_time": {"score": lct, "defined": bool(durations), "mean_lane_change_time_s": t_l,
                             "lane_change_time_scale_s": ev.lane_change_time_scale_s},
        "interaction": {"score": x, "defined": bool(per_change)},
        "no_lane_change_value": neutral,
        "weights": weights,
        "weighted": {k: p * weights[k] * terms[k] for k in weights},
    }


D_NAME = "D, the comparative score"  # what D is called wherever it is shown (report.json, report.md, lines)
#: The scores an experiment compares, by the names of the method's sections (:func:`compared_scores`).
COMPARED_SCORES = ("intelligence", "safety", "efficiency", "interaction")


def compared_scores(report: dict[str, Any]) -> dict[str, float | None]:
    """The scores evoscen's experiments compare SUTs with, from a ``report.json`` dict, under the
    names of the method's sections (:data:`COMPARED_SCORES`), as ``evaluation.score_form`` selects
    (docs/evaluation.md §10): ``comparative`` -> D as ``intelligence``, its S as ``safety``, its
    progress P as ``efficiency`` and its X as ``interaction``; ``method`` (or a report from before
    the comparative score) -> the method's I, I_s, I_e, I_i as they are (``None`` where undefined)."""
    comp = report.get("comparative")
    form = (report.get("settings") or {}).get("score_form", "method")
    if form == "comparative" and comp:
        return {"intelligence": comp["score"], "safety": comp["safety"]["score"],
                "efficiency": comp["progress"]["score"], "interaction": comp["interaction"]["score"]}
    return {name: report[name]["score"] for name in COMPARED_SCORES}


def compared_weighted(report: dict[str, Any]) -> dict[str, float | None]:
    """The weighted terms of the compared score (:func:`compared_scores`), summing to it: ``comparative``
    -> P·i_s·S as ``safety``, P·i_e·L (the lane-change time term) as ``efficiency``, P·i_i·X as
    ``interaction``; ``method`` -> the method's ``intelligence.weighted``."""
    comp = report.get("comparative")
    form = (report.get("settings") or {}).get("score_form", "method")
    if form == "comparative" and comp:
        w = comp["weighted"]
        return {"safety": w["safety"], "efficiency": w["lane_change_time"], "interaction": w["interaction"]}
    return dict(report["intelligence"]["weighted"])


def surrogate_safety_of_stream(st: ScoreStream, pets: list[float | None]) -> dict[str, Any]:
    """The report's ``surrogate_safety`` section (docs/evaluation.md, "Surrogate safety"): per side
    of the SUT (front: the SUT behind the vehicle ahead in its path; rear: the vehicle behind in
    its path behind the SUT) the episodes of TTC below ``ssm_ttc_threshold_s`` and of DRAC above
    ``drac_threshold_mps2`` (an episode: a maximal run of such states with the same counterpart),
    TET = dt · (states with TTC below the threshold) (s) and TIT = dt · Σ (threshold − TTC) over
    them (s²); on the rear the SUT lane changes whose PET (``pets``: each change's, None without a
    new follower) is below ``ssm_pet_threshold_s`` (the front has no PET: ``null``). Each count
    and sum also per SUT-km (distance = dt · Σ speed over the states; ``null`` at 0 km).
    Reported only: no score reads it."""
    st.finish()
    ev = st.ev
    dt = st.dt_s if st.dt_s is not None else 0.1
    km = dt * st.speed_sum / 1000.0
    pet_events = sum(1 for p in pets if p is not None and p < ev.ssm_pet_threshold_s)
    out: dict[str, Any] = {
        "ttc_threshold_s": ev.ssm_ttc_threshold_s,
        "drac_threshold_mps2": ev.drac_threshold_mps2,
        "pet_threshold_s": ev.ssm_pet_threshold_s,
        "sut_km": km,
    }
    for side in SSM_SIDES:
        acc = st.ssm[side]
        counts = {"ttc_episodes": acc["ttc_episodes"], "drac_episodes": acc["drac_episodes"],
                  "pet_events": pet_events if side == "rear" else None,
                  "tet_s": dt * acc["ttc_states"], "tit_s2": dt * acc["tit_sum_s"]}
        out[side] = {**counts, "ttc_states": acc["ttc_states"],
                     "per_km": {k: (None if v is None or km <= 0.0 else v / km) for k, v in counts.items()}}
    return out


def traffic_of_stream(st: ScoreStream) -> dict[str, Any]:
    """The report's ``traffic`` section: how many BVs were within ``range_m`` of the SUT along the
    road (|s_BV − s_SUT|, same state, any lane), per state, averaged per window of
    ``window_states`` states from state 0. A last partial window is reported (``partial``) when
    it holds at least half a window; a shorter tail counts in ``mean_bvs`` and ``empty_share``
    only (``tail_states_left_out``). Reported only: no score reads it."""
    st.finish()
    K = st.states
    W = st.traffic_window_states or traffic_window_states(st.dt_s if st.dt_s is not None else 0.1)
    windows = []
    for w, (total, t0) in enumerate(zip(st.traffic_window_sums, st.traffic_window_t0)):
        n = min(W, K - w * W)
        if 2 * n < W:  # a tail under half a window: left out of the windows
            continue
        windows.append({"start_state": w * W, "states": n, "start_time_s": t0, "mean_bvs": total / n,
                        "partial": n < W})
    means = [x["mean_bvs"] for x in windows]
    return {
        "range_m": TRAFFIC_RANGE_M,
        "window_s": TRAFFIC_WINDOW_S,
        "window_states": W,
        "mean_bvs": st.traffic_sum / K,
        "min_window_mean_bvs": min(means) if means else None,
        "empty_states": st.traffic_empty,
        "empty_share": st.traffic_empty / K,
        "per_window_mean_bvs": means,
        "last_window_partial": bool(windows) and windows[-1]["partial"],
        "tail_states_left_out": K - sum(x["states"] for x in windows),
        "windows": windows,
    }


def run_info(run: RunData) -> dict[str, Any]:
    """What run the report is about."""
    return run_info_of(run.scenario, run.external_sut, run.ids, run.sut_index, run.states, run.dt_s,
                       float(run.time_s[-1] - run.time_s[0]), run.complete, run.columns["length"][0])
