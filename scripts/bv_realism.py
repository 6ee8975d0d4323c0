#!/usr/bin/env python3
"""Realism figures of learned BVs per run-time profile (docs/bv-profiles.md).

    python scripts/bv_realism.py [--profiles driver safety_net] [--seeds 1 2 3 4 5]
                                 [--steps 3000] [--sut level0] [--config FILE] [--policy-dir DIR] [--json OUT]
                                 [--cut-in-headway H] [--lane-hold S] [--traffic window|loop]

Runs every (profile, seed) in process (``bvs.driver: learned``, no bag) and prints, per
profile, the pooled figures of :func:`evoscen_eval.naturalistic.bv_realism.bv_realism`: BV lane changes
per vehicle-km, BV-BV collisions per vehicle-hour, SUT collisions, and the BVs' time-headway
distribution, with highD's published figure beside each one that has one
(:data:`evoscen_eval.naturalistic.bv_realism.HIGHD_REFERENCE`; lane changes: 0.295 per vehicle-km at 120 km/h).
``--traffic`` sets ``traffic.mode`` (window: the traffic moves with the SUT; loop: vehicles
re-enter at the road's start), so the same seeds compare both. Bad input prints one line
``error: ...`` and exits 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK

KEYS = (("bv_lane_changes_per_vehicle_km", "BV lane changes / veh-km", "{:.3f}"),
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bv_realism.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--profiles", nargs="+", default=["driver", "safety_net"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3, 4, 5])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--sut", default=None, help="SUT model (default: the config's)")
    ap.add_argument("--config", type=Path, default=None, help="scenario YAML (default: the shipped default)")
    ap.add_argument("--policy-dir", default=None,
                    help="models.learned.policy_dir: shipped (default), v0.1.0, or a train_bv.py --out directory")
    ap.add_argument("--cut-in-headway", type=float, default=None, metavar="H",
                    help="measure with the profiles' cut-in closing headway h replaced by H s (0: the method's plain 10 m)")
    ap.add_argument("--lane-hold", type=float, default=None, metavar="S",
                    help="models.learned.lane_hold_s (default: the config's, 20 s; 0: no hold)")
    ap.add_argument("--cut-in-decel", type=float, default=None, metavar="B",
                    help="models.learned.cut_in_decel_mps2 (default: the config's, 0: the linear cut-in gap only)")
    ap.add_argument("--standing-at-once", choices=("true", "false"), default=None,
                    help="models.learned.standing_leader_at_once (default: the config's)")
    ap.add_argument("--traffic", choices=("window", "loop"), default=None,
                    help="traffic.mode: window (the traffic moves with the SUT) or loop (re-entry at the road's start; "
                         "with the uniform make-up, which the loop needs: bvs.makeup: uniform); default: the config's")
    ap.add_argument("--hard-brake", choices=("true", "false"), default=None,
                    help="models.learned.hard_brake: the SUT's leader brakes hard now and then (default: the config's)")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures as JSON here")
    args = ap.parse_args(argv)

    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_eval.naturalistic.bv_realism import bv_realism, combine
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    if args.cut_in_headway is not None:  # a what-if knob for the measurement only (docs/bv-profiles.md)
        import dataclasses

        from evoscen_bv import profile as prof

        for name, p in list(prof.PROFILES.items()):
            prof.PROFILES[name] = dataclasses.replace(p, cut_in_closing_headway_s=args.cut_in_headway)
    out: dict[str, dict] = {}
    for profile in args.profiles:
        figures = []
        for seed in args.seeds:
            overrides = {"bvs.driver": "learned", "seed": seed, "steps": args.steps,
                         "models.learned.profile": profile}
            if args.sut:
                overrides["sut.model"] = args.sut
            if args.policy_dir:
                overrides["models.learned.policy_dir"] = args.policy_dir
            if args.lane_hold is not None:
                overrides["models.learned.lane_hold_s"] = args.lane_hold
            if args.cut_in_decel is not None:
                overrides["models.learned.cut_in_decel_mps2"] = args.cut_in_decel
            if args.standing_at_once is not None:
                overrides["models.learned.standing_leader_at_once"] = args.standing_at_once == "true"
            if args.traffic is not None:
                overrides["traffic.mode"] = args.traffic
                if args.traffic == "loop":  # the highd make-up needs the window (docs/bv-profiles.md)
                    overrides["bvs.makeup"] = "uniform"
            if args.hard_brake is not None:
                overrides["models.learned.hard_brake"] = args.hard_brake == "true"
            try:
                cfg = load_scenario_config(args.config, overrides)
            except InputError as exc:
                print(f"error: {exc}", file=sys.stderr)
                return EXIT_BAD_INPUT
            t0 = time.perf_counter()
            try:
                summary = run_inprocess(cfg, bag_dir=None, evaluate=True, plots=False, keep_run=True)
            except InputError as exc:  # e.g. a policy directory that cannot be loaded
                print(f"error: {exc}", file=sys.stderr)
                return EXIT_BAD_INPUT
            f = bv_realism(summary.run)
            figures.append(f)
            print(f"{profile} seed {seed}: {f['bv_lane_changes']} BV lane changes, {f['bv_bv_collisions']} BV-BV "
                  f"and {f['sut_collisions']} SUT collisions ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
        out[profile] = combine(figures)
    from evoscen_eval.naturalistic.bv_realism import HIGHD_REFERENCE, HIGHD_SOURCE

    width = max(len(label) for _, label, _ in KEYS)
    print(f"traffic.mode: {cfg.traffic.mode}; bvs.makeup: {cfg.bvs.makeup}")
    print(" " * width + "".join(f"  {p:>12}" for p in out) + f"  {'highD':>12}")
    for key, label, fmt in KEYS:
        ref = fmt.format(HIGHD_REFERENCE[key]) if key in HIGHD_REFERENCE else "-"
        print(label.ljust(width) + "".join(f"  {fmt.format(out[p][key]):>12}" for p in out) + f"  {ref:>12}")
    from evoscen_eval.naturalistic.bv_realism import lane_changes_per_km_by_policy

    for name in ("competitive", "mutual", "cooperative"):
        rates = [lane_changes_per_km_by_policy(out[p]).get(name, float("nan")) for p in out]
        print(f"LC / veh-km, {name}".ljust(width) + "".join(f"  {r:>12.3f}" for r in rates))
    print(f"highD: {HIGHD_SOURCE}")
    if args.json:
        args.json.write_text(json.dumps({"args": {k: (str(v) if isinstance(v, Path) else v)
                                                  for k, v in vars(args).items()}, "traffic_mode": cfg.traffic.mode,
                                         "figures": out, "highd": HIGHD_REFERENCE}, indent=2))
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
