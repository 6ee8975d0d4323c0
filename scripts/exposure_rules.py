#!/usr/bin/env python3
"""Exposures and collisions per episode by rule, for each SUT on the same episodes.

    python scripts/exposure_rules.py --suts stackelberg,mobil,nilsson --seeds 472000:472099 \
        [--episode-steps 300] [--set KEY=VALUE ...] [--out FILE.json]

Each seed is one episode of the shipped default scenario (``--set`` overrides a key, e.g.
``models.stackelberg.target_gap_rule=end_of_game``), run in process and scored as a report scores it
(docs/evaluation.md §3: the exposure rules front_ttc, hard_braking, rear, cut_in, beside, tailgating).
An exposure counts once under each rule that named it. Prints per SUT the mean per episode with its
95 % Student-t interval and n, and each collision (seed, time, the other vehicle, its kind). Exit
status 0, 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import _bootstrap  # noqa: F401
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK

RULES = ("front_ttc", "hard_braking", "rear", "cut_in", "beside", "tailgating")


def episode(sut: str, seed: int, steps: int, sets: dict) -> dict:
    """One episode's exposures by rule and its collisions."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": steps, "seed": seed, "sut.model": sut, **sets})
    report = run_inprocess(cfg, bag_dir=None, evaluate=True).report
    by_rule = dict.fromkeys(RULES, 0)
    for x in report["safety"]["exposure_list"]:
        for rule in {r["rule"] for r in x.get("rules", [])}:
            by_rule[rule] = by_rule.get(rule, 0) + 1
    return {"exposures": len(report["safety"]["exposure_list"]), "by_rule": by_rule,
            "collisions": report["safety"]["collision_list"]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="exposure_rules.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--suts", required=True, help="comma-separated SUT models")
    ap.add_argument("--seeds", required=True, help="episodes' seeds: blocks A:B[,C:D] (both ends included)")
    ap.add_argument("--episode-steps", default="300", help="steps per episode (default 300)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a scenario key for every run")
    ap.add_argument("--out", type=Path, help="write every episode's figures as JSON here")
    args = ap.parse_args(argv)
    from evoscen_experiments.experiments import positive_int
    from evoscen_experiments.replication import parse_seed_blocks
    from evoscen_experiments.stats import fmt_ci, mean_ci
    from evoscen_sim.errors import InputError

    try:
        blocks = parse_seed_blocks(args.seeds, "--seeds")
        steps = positive_int("--episode-steps", args.episode_steps)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    seeds = [seed for block in blocks for seed in block.seeds]
    sets = {}
    for item in args.set:
        key, eq, value = item.partition("=")
        if not eq or not key:
            print(f"error: --set {item!r}: expected KEY=VALUE", file=sys.stderr)
            return EXIT_BAD_INPUT
        sets[key] = value

    def ci(values: list[float]) -> str:
        return fmt_ci(*mean_ci(values), 3)

    out: dict[str, dict[int, dict]] = {}
    try:
        for sut in args.suts.split(","):
            out[sut] = {seed: episode(sut, seed, steps, sets) for seed in seeds}
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    n = len(seeds)
    print(f"{n} episodes (seed blocks {args.seeds}) x {steps} steps; per episode, "
          "mean ± 95 % interval")
    print("| SUT | exposures | " + " | ".join(RULES) + " | collisions | n |")
    print("|---" * (len(RULES) + 4) + "|")
    for sut, eps in out.items():
        row = [ci([e["exposures"] for e in eps.values()])]
        row += [ci([e["by_rule"][r] for e in eps.values()]) for r in RULES]
        row.append(ci([len(e["collisions"]) for e in eps.values()]))
        print(f"| {sut} | " + " | ".join(row) + f" | {n} |")
    for sut, eps in out.items():
        for seed, e in eps.items():
            for c in e["collisions"]:
                print(f"{sut} seed {seed}: collision at {c['time_s']:.1f} s with vehicle "
                      f"{[i for i in c['ids'] if i != 0]}, kind {c['kind']}")
    if args.out is not None:
        args.out.write_text(json.dumps(out, indent=1), encoding="utf-8")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
