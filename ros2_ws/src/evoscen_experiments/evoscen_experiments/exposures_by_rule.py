"""Exposures and collisions per episode by rule, for each SUT on the same episodes (docs/evaluation.md §3).

``scripts/exposure_rules.py`` parses the command line and calls :func:`main`: each seed one episode of the
shipped default scenario run in process and scored as a report scores it (:func:`episode`); an exposure
counts once under each rule that named it (:data:`evoscen_eval.scoring.exposure_rules.RULES`). Per SUT the
mean per episode with its 95 % Student-t interval, and every collision, are printed.
"""

from __future__ import annotations

import json

from evoscen_contract.contract import EXIT_OK
from evoscen_eval.scoring.exposure_rules import RULES

from evoscen_experiments.stats import fmt_ci, mean_ci


def episode(sut: str, seed: int, steps: int, sets: dict) -> dict:
    """One episode's exposures (all, and by rule) and its collisions."""
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


def table_lines(out: dict[str, dict[int, dict]]) -> list[str]:
    """The Markdown table: per SUT the exposures, each rule's and the collisions per episode (mean ± 95 %), n."""
    def ci(values: list[float]) -> str:
        return fmt_ci(*mean_ci(values), 3)

    lines = ["| SUT | exposures | " + " | ".join(RULES) + " | collisions | n |", "|---" * (len(RULES) + 4) + "|"]
    for sut, eps in out.items():
        row = [ci([e["exposures"] for e in eps.values()])]
        row += [ci([e["by_rule"][r] for e in eps.values()]) for r in RULES]
        row.append(ci([len(e["collisions"]) for e in eps.values()]))
        lines.append(f"| {sut} | " + " | ".join(row) + f" | {len(eps)} |")
    return lines


def main(args) -> int:
    """The episodes of the parsed options (``scripts/exposure_rules.py``; text values, checked here): run, the
    table and the collisions printed, every episode's figures written as JSON to ``args.out`` if given.
    Returns the exit status; InputError (one line) on bad input."""
    from evoscen_experiments.experiments import key_values, positive_int
    from evoscen_experiments.replication import parse_seed_blocks

    blocks = parse_seed_blocks(args.seeds, "--seeds")
    steps = positive_int("--episode-steps", args.episode_steps)
    seeds = [seed for block in blocks for seed in block.seeds]
    sets = key_values("--set", args.set)
    out: dict[str, dict[int, dict]] = {}
    for sut in args.suts.split(","):
        out[sut] = {seed: episode(sut, seed, steps, sets) for seed in seeds}
    print(f"{len(seeds)} episodes (seed blocks {args.seeds}) x {steps} steps; per episode, "
          "mean ± 95 % interval")
    for line in table_lines(out):
        print(line)
    for sut, eps in out.items():
        for seed, e in eps.items():
            for c in e["collisions"]:
                print(f"{sut} seed {seed}: collision at {c['time_s']:.1f} s with vehicle "
                      f"{[i for i in c['ids'] if i != 0]}, kind {c['kind']}")
    if args.out is not None:
        args.out.write_text(json.dumps(out, indent=1), encoding="utf-8")
    return EXIT_OK
