#!/usr/bin/env python3
"""The background traffic's make-up beside highD's, measured from recorded bags (docs/bv-profiles.md).

    python scripts/traffic_makeup.py [--makeup highd] [--seeds 7001 7002 ...] [--steps 3000] [--sut mobil]
                                     [--bv-driver learned] [--out DIR] [--bench ROUNDS] [--json OUT]
                                     [--set KEY=VALUE ...]
    python scripts/traffic_makeup.py --bags BAG [BAG ...] [--json OUT]

Records one bag per seed in process (``bvs.makeup`` of ``--makeup``), reads each back
(:func:`evoscen_eval.scoring.rundata.read_run`) and prints, pooled over the seeds (``--bags BAG ...``: of
these recorded bags instead, nothing run):

* what highD measures, measured as docs/fidelity.md does (:mod:`evoscen_eval.naturalistic.fidelity_highd`, one
  definition for both): each BV trip cut into 420-m pieces, the pieces' mean speeds (mean, sd, p5,
  p50, p95), all and per class (truck: longer than 7 m); BV lane changes per vehicle-km, all and
  per class;
* this script's own: the share of trucks among the pieces (pieces count vehicles as a fixed section
  of road does, in proportion to the distance driven), the trips and the slots; per class the
  merges from the merge lane (completed ``evoscen/lane_change`` events from lane 0) and the lane
  changes without them (highD's recordings are mostly without an on-ramp); BV-BV collisions per
  BV slot-hour; trucks' steps in the leftmost lane; the BVs within ±100 m of the SUT, the run
  report's ``traffic`` section (:func:`evoscen_eval.scoring.metrics.evaluate`: per 30-s window, the lowest
  window mean over the seeds);
* with ``--bench N``: in-process steps/s (recording off; N rounds of 300 steps alternating the two,
  best of each) of this make-up and of ``uniform`` on the first seed, and their ratio.

Beside each, highD's figure at 120 km/h (Krajewski et al., *The highD Dataset*, ITSC 2018), from the
aggregates shipped with evoscen_eval (:func:`evoscen_eval.naturalistic.fidelity_highd.load_reference`). Bad input:
``error: ...``, exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
import numpy as np
import yaml
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK

CLASSES = ("car", "truck")


def highd_figures(reference: dict | None = None) -> dict:
    """highD's figures beside this script's (120 km/h recordings), from the shipped aggregates."""
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
    """The make-up's figures of one run (a RunData): the fidelity measures (``measures``) and this
    script's own. ``report``: the run's report (default: scored here, :func:`evoscen_eval.scoring.metrics.evaluate`
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


def bench(configs: dict, rounds: int = 15, steps: int = 300, warmup: int = 300) -> dict:
    """Best in-process steps/s of each config (recording off) over ``rounds`` rounds of ``steps`` steps,
    the configs alternated in every round (a shared machine's load hits both alike)."""
    from evoscen_bringup.scenario import build_scenario

    scenarios = {name: build_scenario(cfg) for name, cfg in configs.items()}
    for sc in scenarios.values():
        for _ in range(warmup):
            sc.step()
    best = dict.fromkeys(configs, 0.0)
    for _ in range(rounds):
        for name, sc in scenarios.items():
            t0 = time.perf_counter()
            for _ in range(steps):
                sc.step()
            best[name] = max(best[name], steps / (time.perf_counter() - t0))
    return best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="traffic_makeup.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--makeup", default="highd", help="bvs.makeup (default highd)")
    ap.add_argument("--seeds", nargs="+", type=int, default=[7001, 7002, 7003, 7004, 7005, 7006])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--sut", default="mobil", help="sut.model (default mobil)")
    ap.add_argument("--bv-driver", default=None, help="bvs.driver (default: the config's)")
    ap.add_argument("--out", type=Path, default=None, help="keep the bags here (default: a temporary directory)")
    ap.add_argument("--bags", nargs="+", type=Path, default=None, metavar="BAG",
                    help="measure these recorded bags instead of recording (e.g. an earlier --out's)")
    ap.add_argument("--bench", type=int, default=0, metavar="ROUNDS",
                    help="also time this make-up against uniform: ROUNDS alternated rounds of 300 steps, best of each")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures as JSON here")
    ap.add_argument("--set", action="extend", nargs="+", default=[], metavar="KEY=VALUE",
                    help="scenario overrides, e.g. models.truck.threshold_mps2=0.4 (repeatable)")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.bench < 0:
        print("error: --steps: expected an integer >= 1 (and --bench >= 0)", file=sys.stderr)
        return EXIT_BAD_INPUT

    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_eval.scoring.rundata import read_run
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    def config(seed: int, makeup: str):
        over = {"bvs.makeup": makeup, "seed": seed, "steps": args.steps, "sut.model": args.sut}
        if args.bv_driver:
            over["bvs.driver"] = args.bv_driver
        for item in args.set:
            key, _, value = item.partition("=")
            over[key] = yaml.safe_load(value)
        return load_scenario_config(None, over)

    runs = []
    recorded_makeups = []
    for bag in args.bags or []:
        try:
            run = read_run(bag)
            recorded_makeups.append(((run.scenario or {}).get("bvs") or {}).get("makeup", "uniform"))
            runs.append(figures(run))
        except InputError as exc:
            print(f"error: --bags: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out if args.out is not None else Path(tmp)
        for seed in [] if args.bags else args.seeds:
            try:
                cfg = config(seed, args.makeup)
            except InputError as exc:
                print(f"error: {exc}", file=sys.stderr)
                return EXIT_BAD_INPUT
            t0 = time.perf_counter()
            bag = root / f"{args.makeup}_{seed}"
            try:  # (a policy directory or a map is checked when the run builds its world and drivers)
                summary = run_inprocess(cfg, bag_dir=bag, evaluate=True)
            except InputError as exc:
                print(f"error: {exc}", file=sys.stderr)
                return EXIT_BAD_INPUT
            f = figures(read_run(bag), summary.report)
            runs.append(f)
            print(f"seed {seed}: {f['truck_slots']} trucks of {f['slots']}, "
                  f"lane changes {int(f['measures'].trip_lane_changes.sum())}, "
                  f"{f['bv_bv_collisions']} BV-BV collisions ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    out = pooled(runs)
    if args.bench and not args.bags:
        rates = bench({args.makeup: config(args.seeds[0], args.makeup), "uniform": config(args.seeds[0], "uniform")},
                      rounds=args.bench)
        out["steps_per_s"] = rates[args.makeup]
        out["steps_per_s_uniform"] = rates["uniform"]
        out["steps_per_s_ratio"] = rates[args.makeup] / rates["uniform"]
    head = ({"bags": [str(b) for b in args.bags], "makeup": sorted(set(recorded_makeups))} if args.bags else
            {"makeup": args.makeup, "seeds": args.seeds, "steps": args.steps, "sut": args.sut})
    print(json.dumps({**head, "figures": out, "highd": highd_figures()}, indent=1))
    if args.json:
        args.json.write_text(json.dumps({"figures": out, "highd": highd_figures()}, indent=2))
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
