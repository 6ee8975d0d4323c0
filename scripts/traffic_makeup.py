#!/usr/bin/env python3
"""The background traffic's make-up beside highD's, measured from recorded bags (docs/bv-profiles.md).

    python scripts/traffic_makeup.py [--makeup highd] [--seeds 7001 7002 ...] [--steps 3000] [--sut mobil]
                                     [--bv-driver learned] [--out DIR] [--bench ROUNDS] [--json OUT]
                                     [--set KEY=VALUE ...]

Records one bag per seed in process (``bvs.makeup`` of ``--makeup``), reads each back
(:func:`evoscen_eval.rundata.read_run`) and prints, pooled over the seeds:

* the share of trucks (BVs longer than 7 m) among the 420-m pieces of trip — a trip is cut into
  pieces as highD's vehicles were recorded over ~420 m, and pieces count vehicles as a fixed section
  of road does (in proportion to the distance driven) — and among the trips;
* the pieces' mean speeds (mean, sd, p5, p50, p95), all and per class;
* BV lane changes per vehicle-km, all and per class, and per class without the merges from the merge
  lane (highD's recordings are mostly without an on-ramp); BV-BV collisions per vehicle-hour;
* trucks' steps in the leftmost lane; the BVs within ±100 m of the SUT, the lowest 30-s mean;
* with ``--bench N``: in-process steps/s (recording off; N rounds of 300 steps alternating the two,
  best of each) of this make-up and of ``uniform`` on the first seed, and their ratio.

Beside each, highD's figure at 120 km/h (Krajewski et al., *The highD Dataset*, ITSC 2018): the
numbers below are copied from its per-vehicle aggregates. A trip ends where the vehicle leaves the
traffic window (``evoscen/reentry``) or the window is shifted under it (the common shift is
removed); a piece shorter than 420 m at a trip's end is dropped. Bad input: ``error: ...``, exit 2.
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

PIECE_M = 420.0
"""Length of highD's recorded section (m)."""
TRUCK_MIN_LENGTH_M = 7.0
MERGE_LANE = 0
HIGHD = {  # highD, recordings with a 120 km/h limit (Krajewski et al., ITSC 2018)
    "truck_share": 0.1886, "mean_speed_mps": 29.14, "mean_speed_sd_mps": 5.83,
    "car_mean_speed_mps": 30.38, "car_sd_mps": 5.62, "truck_mean_speed_mps": 23.84, "truck_sd_mps": 3.05,
    "lane_changes_per_vehicle_km": 0.295, "car_lane_changes_per_vehicle_km": 0.328,
    "truck_lane_changes_per_vehicle_km": 0.151,
}


def trip_pieces(s: np.ndarray, speed: np.ndarray, dt: float, new_trip: np.ndarray) -> tuple[list[float], int]:
    """Mean speeds of the whole 420-m pieces of one vehicle's trips, and the number of trips.

    ``s``/``speed``: its states; ``new_trip[k]``: a new trip begins at state k (k >= 1)."""
    means: list[float] = []
    trips = 1
    dist = 0.0
    t = 0.0
    for k in range(1, s.shape[0]):
        if new_trip[k]:
            trips += 1
            dist, t = 0.0, 0.0
            continue
        step = 0.5 * (speed[k - 1] + speed[k]) * dt
        dist += step
        t += dt
        if dist >= PIECE_M:
            means.append(dist / t)
            dist, t = 0.0, 0.0
    return means, trips


def figures(run) -> dict:
    """The make-up's figures of one run (RunData)."""
    from evoscen_contract.contract import EVENT_COLLISION, EVENT_LANE_CHANGE, KIND_COMPLETED, ROLE_BV
    from evoscen_sim.physics.traffic import common_shift, new_trips

    c = run.columns
    dt = float(run.dt_s)
    bv = c["role"][0] == ROLE_BV
    ids = c["id"][0].astype(np.int64)
    truck = bv & (c["length"][0] > TRUCK_MIN_LENGTH_M)
    s = c["s"]
    k_states = s.shape[0]
    new = np.zeros(s.shape, dtype=bool)
    for k in range(1, k_states):
        shift = common_shift(s[k - 1], s[k])
        new[k] = new_trips(s[k - 1], s[k], dt, shift_m=shift)
    out = {"pieces": {"car": [], "truck": []}, "trips": {"car": 0, "truck": 0}}
    for v in np.flatnonzero(bv):
        means, trips = trip_pieces(s[:, v], c["speed"][:, v], dt, new[:, v])
        cls = "truck" if truck[v] else "car"
        out["pieces"][cls].extend(means)
        out["trips"][cls] += trips
    body = slice(0, max(k_states - 1, 0))
    km = {cls: float(np.sum(c["speed"][body][:, m]) * dt / 1000.0) for cls, m in (("car", bv & ~truck),
                                                                                 ("truck", truck))}
    cls_of = {int(i): ("truck" if truck[j] else "car") for j, i in enumerate(ids) if bv[j]}
    lcs = {"car": 0, "truck": 0}
    merges = {"car": 0, "truck": 0}
    for e in run.events_named(EVENT_LANE_CHANGE, KIND_COMPLETED):
        who = int(e.get("ids", [-1])[0])
        if who in cls_of:
            lcs[cls_of[who]] += 1
            merges[cls_of[who]] += int(e.get("from_lane", -1) == MERGE_LANE)
    bvbv = 0
    for e in run.events_named(EVENT_COLLISION):
        pair = [int(x) for x in e.get("ids", [])]
        if pair and all(x in cls_of for x in pair):
            bvbv += 1
    hours = float(bv.sum()) * (k_states - 1) * dt / 3600.0
    leftmost = int(np.nanmax(c["lane"]))
    truck_left_steps = int(np.sum(c["lane"][:, truck] == leftmost)) if truck.any() else 0
    sut = run.sut_index
    near = np.sum((np.abs(s[:, bv] - s[:, [sut]]) <= 100.0), axis=1)
    w = int(round(30.0 / dt))
    window_means = [float(near[a:a + w].mean()) for a in range(0, k_states - w + 1, w)]
    out.update(km=km, lane_changes=lcs, merges=merges, bv_bv_collisions=bvbv, vehicle_hours=hours,
               truck_steps_leftmost_lane=truck_left_steps, leftmost_lane=leftmost,
               min_30s_mean_bvs_within_100m=min(window_means) if window_means else float("nan"),
               mean_bvs_within_100m=float(near.mean()),
               min_bvs_within_100m=int(near.min()), slots=int(bv.sum()), truck_slots=int(truck.sum()))
    return out


def pooled(runs: list[dict]) -> dict:
    """The figures of several runs, pooled."""
    pieces = {cls: np.array([x for r in runs for x in r["pieces"][cls]]) for cls in ("car", "truck")}
    allp = np.concatenate([pieces["car"], pieces["truck"]])
    km = {cls: sum(r["km"][cls] for r in runs) for cls in ("car", "truck")}
    lcs = {cls: sum(r["lane_changes"][cls] for r in runs) for cls in ("car", "truck")}
    merges = {cls: sum(r["merges"][cls] for r in runs) for cls in ("car", "truck")}
    trips = {cls: sum(r["trips"][cls] for r in runs) for cls in ("car", "truck")}
    hours = sum(r["vehicle_hours"] for r in runs)
    coll = sum(r["bv_bv_collisions"] for r in runs)

    def stats(x: np.ndarray) -> dict:
        if x.size == 0:
            return {"n": 0}
        return {"n": int(x.size), "mean": float(x.mean()), "sd": float(x.std(ddof=1)) if x.size > 1 else 0.0,
                **{f"p{q}": float(np.percentile(x, q)) for q in (5, 50, 95)}}

    total_km = km["car"] + km["truck"]
    return {
        "truck_share_of_pieces": float(pieces["truck"].size / allp.size) if allp.size else float("nan"),
        "truck_share_of_trips": trips["truck"] / max(1, trips["car"] + trips["truck"]),
        "truck_share_of_slots": sum(r["truck_slots"] for r in runs) / max(1, sum(r["slots"] for r in runs)),
        "piece_mean_speed": stats(allp), "car_piece_mean_speed": stats(pieces["car"]),
        "truck_piece_mean_speed": stats(pieces["truck"]),
        "lane_changes_per_vehicle_km": (lcs["car"] + lcs["truck"]) / total_km if total_km else float("nan"),
        "car_lane_changes_per_vehicle_km": lcs["car"] / km["car"] if km["car"] else float("nan"),
        "truck_lane_changes_per_vehicle_km": lcs["truck"] / km["truck"] if km["truck"] else float("nan"),
        "mainline_lane_changes_per_vehicle_km": {
            cls: (lcs[cls] - merges[cls]) / km[cls] if km[cls] else float("nan") for cls in ("car", "truck")},
        "lane_changes": lcs, "merges_from_merge_lane": merges, "vehicle_km": km,
        "bv_bv_collisions": coll, "bv_bv_collisions_per_vehicle_hour": coll / hours if hours else float("nan"),
        "vehicle_hours": hours,
        "truck_steps_leftmost_lane": sum(r["truck_steps_leftmost_lane"] for r in runs),
        "min_30s_mean_bvs_within_100m": min(r["min_30s_mean_bvs_within_100m"] for r in runs),
        "mean_bvs_within_100m": float(np.mean([r["mean_bvs_within_100m"] for r in runs])),
        "min_bvs_within_100m": min(r["min_bvs_within_100m"] for r in runs),
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
    ap.add_argument("--bench", type=int, default=0, metavar="ROUNDS",
                    help="also time this make-up against uniform: ROUNDS alternated rounds of 300 steps, best of each")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures as JSON here")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="scenario overrides, e.g. models.truck.threshold_mps2=0.4")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.bench < 0:
        print("error: --steps: expected an integer >= 1 (and --bench >= 0)", file=sys.stderr)
        return EXIT_BAD_INPUT

    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_eval.rundata import read_run
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
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out if args.out is not None else Path(tmp)
        for seed in args.seeds:
            try:
                cfg = config(seed, args.makeup)
            except InputError as exc:
                print(f"error: {exc}", file=sys.stderr)
                return EXIT_BAD_INPUT
            t0 = time.perf_counter()
            bag = root / f"{args.makeup}_{seed}"
            run_inprocess(cfg, bag_dir=bag)
            f = figures(read_run(bag))
            runs.append(f)
            print(f"seed {seed}: {f['truck_slots']} trucks of {f['slots']}, lane changes {f['lane_changes']}, "
                  f"{f['bv_bv_collisions']} BV-BV collisions ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    out = pooled(runs)
    if args.bench:
        rates = bench({args.makeup: config(args.seeds[0], args.makeup), "uniform": config(args.seeds[0], "uniform")},
                      rounds=args.bench)
        out["steps_per_s"] = rates[args.makeup]
        out["steps_per_s_uniform"] = rates["uniform"]
        out["steps_per_s_ratio"] = rates[args.makeup] / rates["uniform"]
    print(json.dumps({"makeup": args.makeup, "seeds": args.seeds, "steps": args.steps, "sut": args.sut,
                      "figures": out, "highd": HIGHD}, indent=1))
    if args.json:
        args.json.write_text(json.dumps({"figures": out, "highd": HIGHD}, indent=2))
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
