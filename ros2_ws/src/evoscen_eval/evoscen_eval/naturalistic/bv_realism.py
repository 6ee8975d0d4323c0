"""Realism figures of a run's background vehicles, to set beside naturalistic (HighD) data.

:func:`bv_realism` reads a :class:`evoscen_eval.scoring.rundata.RunData` (a recorded bag, or an
in-process run's ``RunSummary.run``) and reports, over the background vehicles (role BV):

* ``bv_vehicle_hours``: Σ over recorded states k < K-1 and BVs of dt (each state stands for
  the step that follows it);
* ``bv_vehicle_km``: Σ over the same of speed·dt / 1000 (distance driven);
* ``bv_bv_collisions`` and ``bv_bv_collisions_per_vehicle_hour``: collision events between
  two BVs (``evoscen/collision``), per BV vehicle-hour;
* ``sut_collisions``: collision events involving the SUT;
* ``bv_lane_changes`` and ``bv_lane_changes_per_vehicle_km``: completed lane changes
  (``evoscen/lane_change``, kind ``completed``) of BVs, per BV vehicle-km (HighD: about
  0.12 per vehicle-km);
* ``by_policy``: per social type present (the ``policy`` column: mutual, competitive,
  cooperative), its BVs' completed lane changes and vehicle-km
  (:func:`lane_changes_per_km_by_policy`: the method's order is competitive > mutual >
  cooperative);
* ``thw_samples``, ``thw_median_s``, ``thw_share_below_1s``, ``thw_share_below_0_5s``:
  the BVs' time headway THW = bumper-to-bumper gap to the nearest vehicle ahead in the
  same lane (any role) / own speed, over the states where the BV drives at least
  ``min_speed_mps`` (5 m/s, as :class:`evoscen_eval.naturalistic.behaviour.BehaviourConfig`) and the
  gap is at most ``leader_range_m`` (100 m). HighD's ``thw`` is likewise gap / speed.
* how the BVs drive (:func:`driving_figures`; docs/learned-bvs.md, "Phantom braking"), over
  the states k < K-1 of the BVs: ``main_line_states`` (on a lane >= 1, not changing into the
  merge lane, at least ``min_speed_mps``), ``hard_braking_share`` (of those, accel < -3 m/s²),
  ``phantom_braking_share`` (of those, accel < -3 m/s² with no vehicle within
  ``PHANTOM_RANGE_M`` = 60 m ahead, bumper to bumper, in its lane or its target lane, by the
  ``lane`` and ``target_lane`` columns of both), ``standstill_share_main_line`` and
  ``standstill_share_merge_lane`` (of all BV states, speed < 2 m/s on a lane >= 1 / on lane 0),
  ``accel_flip_share`` (of the pairs of consecutive states of a BV, k and k + 1 < K, those
  where |accel| > 1 m/s² in both and the sign differs: a controller alternating between
  braking and accelerating every step).

Under the traffic window (``traffic.mode: window``, :mod:`evoscen_sim.physics.window`) the arc length
``s`` jumps: a shift moves every vehicle back by ``shift_from_m - shift_to_m`` (1,700 m) in one
step, and an entry moves one vehicle by up to a few hundred metres, often into another lane. None
of the figures reads a step of ``s`` or of the ``lane`` column: vehicle-km is speed·dt (the
distance driven, whatever the jumps), lane changes are completed lane-change events (an entry
into another lane is none), and THW and the driving figures are read state by state (a shift
keeps every relative position). ``test_bv_realism.py`` checks this on a hand-built run with a
shift and an entry and on a short window run (vehicle-km against the distance driven with the
shifts undone and the entries left out).

:data:`HIGHD_REFERENCE` holds the highD figures these can be set beside, with their source
(:data:`HIGHD_SOURCE`). ``scripts/bv_realism.py`` runs a few seeds in process and prints these
for each BV profile, with the highD figure beside each one that has one.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from evoscen_contract.contract import (EVENT_COLLISION, EVENT_LANE_CHANGE, KIND_COMPLETED, POLICY_CODES, ROLE_BV,
                                       SOCIAL_POLICIES)

POLICY_NAMES = {POLICY_CODES[name]: name for name in SOCIAL_POLICIES}
"""The world table's ``policy`` codes of the learned BVs' social types (code -> name)."""

def _shipped_lane_change_rate() -> float:
    """highD's lane changes per vehicle-km at 120 km/h, from the shipped aggregates (docs/fidelity.md)."""
    from evoscen_eval.naturalistic.fidelity_highd import load_reference

    return float(load_reference()["speed_limit_120_kmh"]["lane_changes_per_vehicle_km"])


HIGHD_REFERENCE: dict[str, float] = {"bv_lane_changes_per_vehicle_km": _shipped_lane_change_rate()}
"""highD figures, by the key of the figure they stand beside: lane changes per vehicle-km of the
recordings with a 120 km/h limit (the road's), each vehicle's lane changes summed over the distance
driven (0.295; shipped aggregates, ``evoscen_eval/data/highd_aggregates.json``). The paper's "5,600
complete lane changes in 45,000 km" (0.124) counts only manoeuvres seen whole inside the ~420-m
recorded section and undercounts. THW has no reference here: highD's aggregate is each vehicle's
*minimum* THW over 420 m, not a per-state sample; ``scripts/fidelity_highd.py`` compares that."""
HIGHD_SOURCE = ("Krajewski, Bock, Kloeker, Eckstein: The highD Dataset, IEEE ITSC 2018, doi:10.1109/ITSC.2018.8569552 "
                "(per-vehicle summaries of the 120 km/h recordings, aggregated: evoscen_eval/data/highd_aggregates.json)")


def time_headways(s: np.ndarray, lane: np.ndarray, speed: np.ndarray, length: np.ndarray, bv: np.ndarray,
                  min_speed_mps: float = 5.0, leader_range_m: float = 100.0) -> np.ndarray:
    """THW samples (s) of the BVs (``bv``: bool ``[V]``) over states ``[K, V]`` (see module docstring)."""
    out = []
    for k in range(s.shape[0]):
        for i in np.flatnonzero(bv):
            if speed[k, i] < min_speed_mps:
                continue
            ahead = (lane[k] == lane[k, i]) & (s[k] > s[k, i])
            ahead[i] = False
            if not ahead.any():
                continue
            j = np.flatnonzero(ahead)[np.argmin(s[k, ahead])]
            gap = s[k, j] - s[k, i] - 0.5 * (length[k, i] + length[k, j])
            if gap <= leader_range_m:
                out.append(max(gap, 0.0) / speed[k, i])
    return np.asarray(out, dtype=float)


PHANTOM_RANGE_M = 60.0
"""Hard braking with no vehicle within this far ahead (m) counts as phantom braking."""
HARD_BRAKING_MPS2 = 3.0
"""Braking harder than this (m/s²) is hard braking."""
STANDSTILL_MPS = 2.0
"""Below this speed (m/s) a BV is at standstill."""
FLIP_ACCEL_MPS2 = 1.0
"""|accel| above this in two consecutive states of opposite sign is a flip (m/s²)."""


def driving_figures(s: np.ndarray, lane: np.ndarray, target_lane: np.ndarray, speed: np.ndarray, accel: np.ndarray,
                    length: np.ndarray, bv: np.ndarray, min_speed_mps: float = 5.0) -> dict[str, Any]:
    """The driving figures of the BVs (``bv``: bool ``[V]``) over states ``[K, V]`` (module docstring)."""
    body = max(s.shape[0] - 1, 0)
    cols = np.flatnonzero(bv)
    main = hard = phantom = 0
    for k in range(body):
        for i in cols:
            if lane[k, i] < 1 or target_lane[k, i] < 1 or speed[k, i] < min_speed_mps:
                continue
            main += 1
            if accel[k, i] >= -HARD_BRAKING_MPS2:
                continue
            hard += 1
            mine = (lane[k, i], target_lane[k, i])
            ahead = (s[k] > s[k, i]) & (np.isin(lane[k], mine) | np.isin(target_lane[k], mine))
            ahead[i] = False
            gaps = s[k, ahead] - s[k, i] - 0.5 * (length[k, ahead] + length[k, i])
            if not (gaps <= PHANTOM_RANGE_M).any():
                phantom += 1
    n = body * cols.size
    v, ln = speed[:body][:, cols], lane[:body][:, cols]
    a = accel[:, cols]
    flips = (np.abs(a[1:]) > FLIP_ACCEL_MPS2) & (np.abs(a[:-1]) > FLIP_ACCEL_MPS2) & (np.sign(a[1:]) != np.sign(a[:-1]))
    return {
        "bv_states": n,
        "main_line_states": main,
        "hard_braking_share": hard / main if main else float("nan"),
        "phantom_braking_share": phantom / main if main else float("nan"),
        "standstill_share_main_line": float(np.sum((v < STANDSTILL_MPS) & (ln >= 1))) / n if n else float("nan"),
        "standstill_share_merge_lane": float(np.sum((v < STANDSTILL_MPS) & (ln == 0))) / n if n else float("nan"),
        "flip_pairs": int(flips.size),
        "accel_flip_share": float(flips.mean()) if flips.size else float("nan"),
    }


def bv_realism(run, min_speed_mps: float = 5.0, leader_range_m: float = 100.0) -> dict[str, Any]:
    """The BV realism figures of ``run`` (a RunData; see the module docstring)."""
    c = run.columns
    role = c["role"]
    bv = role[0] == ROLE_BV
    ids = c["id"][0].astype(np.int64)
    bv_ids = set(ids[bv].tolist())
    sut_ids = set(ids[~bv].tolist())
    dt = float(run.dt_s)
    body = slice(0, max(run.states - 1, 0))
    hours = float(bv.sum()) * (run.states - 1) * dt / 3600.0 if run.states > 1 else 0.0
    km = float(np.sum(c["speed"][body][:, bv]) * dt / 1000.0)
    bvbv = sut_coll = 0
    for e in run.events_named(EVENT_COLLISION):
        pair = [int(x) for x in e.get("ids", [])]
        if pair and all(x in bv_ids for x in pair):
            bvbv += 1
        if any(x in sut_ids for x in pair):
            sut_coll += 1
    lcs = sum(1 for e in run.events_named(EVENT_LANE_CHANGE, KIND_COMPLETED)
              if int(e.get("ids", [-1])[0]) in bv_ids)
    thw = time_headways(c["s"], c["lane"], c["speed"], c["length"], bv, min_speed_mps, leader_range_m)
    # per social type (the policy column): completed lane changes and km of the BVs of that type
    policy = c["policy"][0].astype(np.int64)
    code_of = dict(zip(ids.tolist(), policy.tolist()))
    by_type: dict[str, dict[str, float]] = {}
    for code, name in POLICY_NAMES.items():
        cols = bv & (policy == code)
        if cols.any():
            n = sum(1 for e in run.events_named(EVENT_LANE_CHANGE, KIND_COMPLETED)
                    if int(e.get("ids", [-1])[0]) in bv_ids and code_of.get(int(e["ids"][0])) == code)
            by_type[name] = {"lane_changes": n, "vehicle_km": float(np.sum(c["speed"][body][:, cols]) * dt / 1000.0)}
    return {
        "bv_vehicle_hours": hours,
        "bv_vehicle_km": km,
        "bv_bv_collisions": bvbv,
        "bv_bv_collisions_per_vehicle_hour": bvbv / hours if hours > 0 else float("nan"),
        "sut_collisions": sut_coll,
        "bv_lane_changes": lcs,
        "bv_lane_changes_per_vehicle_km": lcs / km if km > 0 else float("nan"),
        "thw_samples": int(thw.size),
        "thw_median_s": float(np.median(thw)) if thw.size else float("nan"),
        "thw_share_below_1s": float(np.mean(thw < 1.0)) if thw.size else float("nan"),
        "thw_share_below_0_5s": float(np.mean(thw < 0.5)) if thw.size else float("nan"),
        "by_policy": by_type,
        **driving_figures(c["s"], c["lane"], c["target_lane"], c["speed"], c["accel"], c["length"], bv, min_speed_mps),
    }


def lane_changes_per_km_by_policy(figures: dict[str, Any]) -> dict[str, float]:
    """Completed lane changes per vehicle-km of each social type present (pooled figures or one run's)."""
    return {name: (f["lane_changes"] / f["vehicle_km"] if f["vehicle_km"] > 0 else float("nan"))
            for name, f in figures.get("by_policy", {}).items()}


def combine(figures: list[dict[str, Any]]) -> dict[str, Any]:
    """Pool the figures of several runs: counts and exposures summed, rates recomputed;
    THW statistics are sample-weighted means of the runs' (the median: of the runs' medians)."""
    hours = sum(f["bv_vehicle_hours"] for f in figures)
    km = sum(f["bv_vehicle_km"] for f in figures)
    bvbv = sum(f["bv_bv_collisions"] for f in figures)
    lcs = sum(f["bv_lane_changes"] for f in figures)
    n = sum(f["thw_samples"] for f in figures)
    by_type: dict[str, dict[str, float]] = {}
    for f in figures:
        for name, t in f.get("by_policy", {}).items():
            acc = by_type.setdefault(name, {"lane_changes": 0, "vehicle_km": 0.0})
            acc["lane_changes"] += t["lane_changes"]
            acc["vehicle_km"] += t["vehicle_km"]

    def wmean(key: str) -> float:
        return sum(f[key] * f["thw_samples"] for f in figures if f["thw_samples"]) / n if n else float("nan")

    return {
        "runs": len(figures),
        "bv_vehicle_hours": hours,
        "bv_vehicle_km": km,
        "bv_bv_collisions": bvbv,
        "bv_bv_collisions_per_vehicle_hour": bvbv / hours if hours > 0 else float("nan"),
        "sut_collisions": sum(f["sut_collisions"] for f in figures),
        "bv_lane_changes": lcs,
        "bv_lane_changes_per_vehicle_km": lcs / km if km > 0 else float("nan"),
        "thw_samples": n,
        "thw_median_s": float(np.median([f["thw_median_s"] for f in figures if f["thw_samples"]])) if n else float("nan"),
        "thw_share_below_1s": wmean("thw_share_below_1s"),
        "thw_share_below_0_5s": wmean("thw_share_below_0_5s"),
        "by_policy": by_type,
        **_pool_driving(figures),
    }


def _pool_driving(figures: list[dict[str, Any]]) -> dict[str, Any]:
    """The driving figures of several runs, each share weighted by its denominator."""
    out: dict[str, Any] = {}
    for key, weight in (("bv_states", None), ("main_line_states", None), ("flip_pairs", None),
                        ("hard_braking_share", "main_line_states"), ("phantom_braking_share", "main_line_states"),
                        ("standstill_share_main_line", "bv_states"), ("standstill_share_merge_lane", "bv_states"),
                        ("accel_flip_share", "flip_pairs")):
        if weight is None:
            out[key] = sum(f[key] for f in figures)
        else:
            w = sum(f[weight] for f in figures)
            out[key] = sum(f[key] * f[weight] for f in figures if f[weight]) / w if w else float("nan")
    return out


TABLE_ROWS = (("bv_lane_changes_per_vehicle_km", "BV lane changes / veh-km", "{:.3f}"),
              ("bv_bv_collisions_per_vehicle_hour", "BV-BV collisions / veh-h", "{:.3f}"),
              ("bv_bv_collisions", "BV-BV collisions", "{}"),
              ("sut_collisions", "SUT collisions (all runs)", "{}"),
              ("thw_median_s", "THW median (s)", "{:.2f}"),
              ("thw_share_below_1s", "share THW < 1 s", "{:.3f}"),
              ("thw_share_below_0_5s", "share THW < 0.5 s", "{:.3f}"),
              ("hard_braking_share", "share braking < -3 m/s2 (main line)", "{:.4f}"),
              ("phantom_braking_share", "  with nobody within 60 m ahead", "{:.4f}"),
              ("standstill_share_main_line", "share at standstill, main line", "{:.4f}"),
              ("standstill_share_merge_lane", "share at standstill, merge lane", "{:.4f}"),
              ("accel_flip_share", "share of accel flips (|a| > 1)", "{:.4f}"),
              ("bv_vehicle_hours", "BV vehicle-hours", "{:.2f}"),
              ("bv_vehicle_km", "BV vehicle-km", "{:.1f}"))
"""The rows of :func:`realism_table`: figure key, label, format."""


def realism_table(pooled: dict[str, dict[str, Any]]) -> str:
    """The pooled figures (:func:`combine`) of each column (a BV profile) as a text table, a row per
    :data:`TABLE_ROWS` with the highD figure beside it (``-``: none), the lane changes per vehicle-km
    of each social type, and highD's source (``scripts/bv_realism.py``)."""
    width = max(len(label) for _, label, _ in TABLE_ROWS)
    lines = [" " * width + "".join(f"  {p:>12}" for p in pooled) + f"  {'highD':>12}"]
    for key, label, fmt in TABLE_ROWS:
        ref = fmt.format(HIGHD_REFERENCE[key]) if key in HIGHD_REFERENCE else "-"
        lines.append(label.ljust(width) + "".join(f"  {fmt.format(pooled[p][key]):>12}" for p in pooled) + f"  {ref:>12}")
    for name in ("competitive", "mutual", "cooperative"):
        rates = [lane_changes_per_km_by_policy(pooled[p]).get(name, float("nan")) for p in pooled]
        lines.append(f"LC / veh-km, {name}".ljust(width) + "".join(f"  {r:>12.3f}" for r in rates))
    lines.append(f"highD: {HIGHD_SOURCE}")
    return "\n".join(lines) + "\n"
