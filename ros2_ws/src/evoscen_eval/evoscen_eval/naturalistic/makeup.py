"""The background traffic's make-up beside highD's (docs/bv-profiles.md), the figures of ``scripts/traffic_makeup.py``.

What highD measures is measured as docs/fidelity.md does (:mod:`evoscen_eval.naturalistic.fidelity_highd`,
one definition for both: pieces' mean speeds, lane changes per vehicle-km, all and per class); beside
them the make-up's own figures of a run (:func:`figures`): the trucks' share of the pieces, trips and
slots, merges from the merge lane, BV-BV collisions per BV slot-hour, trucks' steps in the leftmost
lane and the BVs near the SUT (the run report's ``traffic`` section), pooled over runs by
:func:`pooled`; :func:`highd_figures` gives highD's figures beside them (120 km/h, the shipped aggregates).
"""

from __future__ import annotations

import numpy as np

CLASSES = ("car", "truck")


def highd_figures(reference: dict | None = None) -> dict:
    """highD's figures beside the make-up's (120 km/h recordings), from the shipped aggregates."""
    from evoscen_eval.naturalistic.fidelity_highd import load_reference

    r = (reference or load_reference())["speed_limit_120_kmh"]
    out = {"mean_speed_mps": r["per_vehicle_mean_speed_mps"]["mean"],
           "mean_speed_sd_mps": r["per_vehicle_mean_speed_mps"]["sd"],
           "lane_changes_per_vehicle_km": r["lane_changes_per_vehicle_km"]}
    for cls in CLASSES:
        c = r.get(cls, {})
        out[f"{cls}_mean_speed_mps"] = c.get("mean_speed_mps", {}).get("mean")
        out[f"{cls}_sd_mps"] = c.get("mean_speed_mps", {}).get("sd")
        out[f"{cls}_lane_changes_per_vehicle_km"] = c.get("lane_changes_per_vehicle_km")
    out["truck_share"] = r.get("truck", {}).get("share_of_vehicles")
    return out


def figures(run, report: dict | None = None) -> dict:
    """The make-up's figures of one run (a RunData): the fidelity measures (``measures``) and its
    own. ``report``: the run's report (default: scored here, :func:`evoscen_eval.scoring.metrics.evaluate`
    with the run's recorded evaluation settings), whose ``traffic`` section gives the BVs near the SUT."""
    from evoscen_contract.contract import EVENT_COLLISION, EVENT_LANE_CHANGE, KIND_COMPLETED, ROLE_BV
    from evoscen_eval.naturalistic.fidelity_highd import PieceConfig, run_measures
    from evoscen_sim.road.road_model import MERGE_LANE

    truck_length = PieceConfig().truck_length_m
    c = run.columns
    bv = c["role"][0] == ROLE_BV
    ids = c["id"][0].astype(np.int64)
    truck = bv & (c["length"][0] > truck_length)
    cls_of = {int(i): ("truck" if truck[j] else "car") for j, i in enumerate(ids) if bv[j]}
    merges = dict.fromkeys(CLASSES, 0)
    for e in run.events_named(EVENT_LANE_CHANGE, KIND_COMPLETED):
        who = int(e.get("ids", [-1])[0])
        if who in cls_of and e.get("from_lane", -1) == MERGE_LANE:
            merges[cls_of[who]] += 1
    bvbv = 0
    for e in run.events_named(EVENT_COLLISION):
        pair = [int(x) for x in e.get("ids", [])]
        if pair and all(x in cls_of for x in pair):
            bvbv += 1
    if report is None:
        from evoscen_eval.scoring.metrics import evaluate
        from evoscen_eval.scoring.rundata import evaluation_settings_of

        report = evaluate(run, evaluation_settings_of(run.scenario))
    traffic = report["traffic"]
    leftmost = int(np.nanmax(c["lane"]))
    return {"measures": run_measures(run), "merges": merges, "bv_bv_collisions": bvbv,
            "vehicle_hours": float(bv.sum()) * (run.states - 1) * float(run.dt_s) / 3600.0,
            "truck_steps_leftmost_lane": int(np.sum(c["lane"][:, truck] == leftmost)) if truck.any() else 0,
            "leftmost_lane": leftmost, "slots": int(bv.sum()), "truck_slots": int(truck.sum()),
            "min_30s_mean_bvs_within_100m": traffic["min_window_mean_bvs"],
            "mean_bvs_within_100m": traffic["mean_bvs"]}


def pooled(runs: list[dict]) -> dict:
    """The figures of several runs (:func:`figures`), pooled."""
    from evoscen_eval.naturalistic.fidelity_highd import Measures

    m = Measures.concat(r["measures"] for r in runs)

    def stats(x: np.ndarray) -> dict:
        if x.size == 0:
            return {"n": 0}
        return {"n": int(x.size), "mean": float(x.mean()), "sd": float(x.std(ddof=1)) if x.size > 1 else 0.0,
                **{f"p{q}": float(np.percentile(x, q)) for q in (5, 50, 95)}}

    def ratio(a: float, b: float) -> float:
        return a / b if b else float("nan")

    sel = {"car": ~m.trip_truck, "truck": m.trip_truck}
    km = {cls: float(m.trip_km[s].sum()) for cls, s in sel.items()}
    lcs = {cls: int(m.trip_lane_changes[s].sum()) for cls, s in sel.items()}
    merges = {cls: sum(r["merges"][cls] for r in runs) for cls in CLASSES}
    hours = sum(r["vehicle_hours"] for r in runs)
    coll = sum(r["bv_bv_collisions"] for r in runs)
    near = [r["min_30s_mean_bvs_within_100m"] for r in runs if r["min_30s_mean_bvs_within_100m"] is not None]
    return {
        "truck_share_of_pieces": ratio(float(m.truck.sum()), float(m.pieces)),
        "truck_share_of_trips": ratio(float(m.trip_truck.sum()), float(m.trip_truck.size)),
        "truck_share_of_slots": ratio(sum(r["truck_slots"] for r in runs), sum(r["slots"] for r in runs)),
        "piece_mean_speed": stats(m.mean_speed_mps), "car_piece_mean_speed": stats(m.mean_speed_mps[~m.truck]),
        "truck_piece_mean_speed": stats(m.mean_speed_mps[m.truck]),
        "lane_changes_per_vehicle_km": ratio(lcs["car"] + lcs["truck"], km["car"] + km["truck"]),
        "car_lane_changes_per_vehicle_km": ratio(lcs["car"], km["car"]),
        "truck_lane_changes_per_vehicle_km": ratio(lcs["truck"], km["truck"]),
        "mainline_lane_changes_per_vehicle_km": {cls: ratio(lcs[cls] - merges[cls], km[cls]) for cls in CLASSES},
        "lane_changes": lcs, "merges_from_merge_lane": merges, "vehicle_km": km,
        "bv_bv_collisions": coll, "bv_bv_collisions_per_vehicle_hour": ratio(coll, hours),
        "vehicle_hours": hours,
        "truck_steps_leftmost_lane": sum(r["truck_steps_leftmost_lane"] for r in runs),
        "min_30s_mean_bvs_within_100m": min(near) if near else None,
        "mean_bvs_within_100m": float(np.mean([r["mean_bvs_within_100m"] for r in runs])),
    }
