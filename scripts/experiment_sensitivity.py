#!/usr/bin/env python3
"""The sensitivity experiment (SUT mutation analysis): does each scenario tell a SUT from its mutants?

    python scripts/experiment_sensitivity.py [--out DIR] [--config FILE] [--base mobil]
                                            [--mutants all|NAME,...] [--scenarios evolving,level0,nilsson,mobil]
                                            [--seeds 10] [--first-seed S] [--steps 3000] [--jobs N]

For every base SUT model (``--base``, comma-separated) and every scenario, the intact model and
each mutant of the library (:mod:`evoscen_sut.mutants`, docs/mutants.md) run on the same seeds
(common random numbers) for ``--steps`` steps in-process. Scenarios: ``evolving`` — the BVs as
the configuration drives them (the shipped default: learned social drivers); any BV driver
name (``level0``, ``nilsson``, ``mobil``) — every BV driven by that model. Per mutant and
scenario: the paired difference intact − mutant of the intelligence score and of each
sub-score, with its 95 % interval over seeds, *detected* when the intelligence interval lies
above zero, and the seeds needed to detect it; per scenario the mutation score (detected /
all). Rounds run on ``--jobs`` Ray workers (the campaign engine) and are saved as they finish: an interrupted
experiment continues where it stopped. Writes ``sensitivity.md``, ``sensitivity.csv``,
``mutation_scores.csv``, ``rounds.csv`` and ``sensitivity.png`` into ``--out`` and prints the
tables. Exit status: 0 done, 2 bad input, 130 interrupted.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_OK

INTACT = "intact"


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="experiment_sensitivity.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("runs/experiment_sensitivity"), help="output directory")
    ap.add_argument("--config", type=Path, help="base scenario YAML (default: the shipped default)")
    ap.add_argument("--base", default="mobil", help="comma-separated intact SUT models (default mobil)")
    ap.add_argument("--mutants", default="all", help="'all' or comma-separated mutant names of the library")
    ap.add_argument("--scenarios", default="evolving,level0,nilsson,mobil",
                    help="comma-separated: evolving (the config's BV driver) and/or BV driver names")
    ap.add_argument("--seeds", default="10", help="seeds per SUT variant and scenario (default 10)")
    ap.add_argument("--first-seed", default="0", help="first seed (default 0)")
    ap.add_argument("--steps", default="3000", help="steps per round (default 3000)")
    ap.add_argument("--jobs", default=str(os.cpu_count() or 1), help="Ray workers (default: CPU count)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:  # noqa: PLR0915 - one linear report
    args = parse_args(argv)
    from evoscen_bringup.experiments import (Round, distinct_names, fmt_ci, markdown_table, mean_ci, positive_int,
                                             run_rounds_with_bar, set_up, write_csv)
    from evoscen_bringup.sensitivity import SCORES, mutation_score, paired, pairing, score_of, seeds_needed
    from evoscen_sim.config import load_scenario_config
    from evoscen_sim.errors import InputError
    from evoscen_sut.mutants import LIBRARY, mutant_overrides

    Built = tuple[list[str], list[str], list[str], list[Round], dict[str, tuple[str, str, str]], int, int, int]

    def build() -> Built:
        seeds = positive_int("--seeds", args.seeds)
        first = positive_int("--first-seed", args.first_seed, 0)
        jobs = positive_int("--jobs", args.jobs)
        bases = distinct_names("--base", args.base)
        scenarios = distinct_names("--scenarios", args.scenarios)
        mutants = list(LIBRARY) if args.mutants.strip() == "all" else distinct_names("--mutants", args.mutants)
        unknown = [m for m in mutants if m not in LIBRARY]
        if unknown:
            raise InputError(f"--mutants: unknown mutant {unknown[0]!r}: expected 'all' or names from "
                             f"{', '.join(LIBRARY)}")
        variants: list[tuple[str, str, dict[str, str]]] = []  # (base, mutant or intact, overrides)
        for base in bases:
            variants.append((base, INTACT, {"sut.model": base}))
            variants += [(base, m, mutant_overrides(base, m)) for m in mutants]
        rounds: list[Round] = []
        meta: dict[str, tuple[str, str, str]] = {}  # round key -> (scenario, base, variant)
        for scenario in scenarios:
            for base, variant, sut_overrides in variants:
                for seed in range(first, first + seeds):
                    overrides = {**sut_overrides, "seed": str(seed), "steps": args.steps,
                                 "recording.enabled": "false"}
                    if scenario != "evolving":
                        overrides["bvs.driver"] = scenario
                    rnd = Round(f"{scenario}--{base}--{variant}", load_scenario_config(args.config, overrides))
                    rounds.append(rnd)
                    meta[rnd.key] = (scenario, base, variant)
        return bases, scenarios, mutants, rounds, meta, jobs, seeds, first

    built = set_up(args.out, build)
    if built is None:
        return EXIT_BAD_INPUT
    bases, scenarios, mutants, rounds, meta, jobs, seeds, first = built

    results = run_rounds_with_bar(rounds, args.out, jobs=jobs, desc="sensitivity")
    if results is None:
        return EXIT_INTERRUPTED

    # seed -> report, per (scenario, base, variant)
    reports: dict[tuple[str, str, str], dict[int, dict]] = {}
    for rnd in rounds:
        reports.setdefault(meta[rnd.key], {})[rnd.cfg.seed] = results[rnd.key]["report"]

    def per_seed(key: tuple[str, str, str], name: str) -> dict[int, float]:
        return {s: score_of(r, name) for s, r in reports[key].items()}

    def counts(key: tuple[str, str, str], section: str, field: str) -> dict[int, float]:
        return {s: float(r[section][field]) for s, r in reports[key].items()}

    def min_pet(key: tuple[str, str, str]) -> dict[int, float]:
        out = {}
        for s, r in reports[key].items():
            v = (r["safety"].get("conflicts") or {}).get("min_pet_s")
            out[s] = math.nan if v is None else float(v)
        return out

    header = ["mutant", "class", "ΔI (intact − mutant)", "ΔI_s", "ΔI_e", "ΔI_i", "Δ collisions (mutant − intact)",
              "Δ exposures", "Δ min PET (s)", "detected", "seeds needed", "pairing r"]
    csv_rows, score_rows, md_parts, plot_data = [], [], [], []
    round_rows = []
    for scenario in scenarios:
        driver = next(r.cfg.bvs.driver for r in rounds if meta[r.key][0] == scenario)
        for base in bases:
            intact_key = (scenario, base, INTACT)
            rows, detected, points, rs = [], [], [], []
            for m in mutants:
                key = (scenario, base, m)
                diffs = {name: paired(per_seed(intact_key, name), per_seed(key, name)) for name in SCORES}
                d_col = paired(counts(key, "safety", "collisions"), counts(intact_key, "safety", "collisions"))
                d_exp = paired(counts(key, "safety", "exposures"), counts(intact_key, "safety", "exposures"))
                d_pet = paired(min_pet(intact_key), min_pet(key))
                i_intact, i_mutant = per_seed(intact_key, "intelligence"), per_seed(key, "intelligence")
                need = seeds_needed(i_intact, i_mutant)
                r_pair = pairing(i_intact, i_mutant)
                rs.append(r_pair)
                hit = diffs["intelligence"].above_zero
                detected.append(hit)
                points.append((m, diffs["intelligence"]))
                rows.append([m, LIBRARY[m].klass, *(fmt_ci(diffs[n].mean, diffs[n].half) for n in SCORES),
                             fmt_ci(d_col.mean, d_col.half, 2), fmt_ci(d_exp.mean, d_exp.half, 2),
                             fmt_ci(d_pet.mean, d_pet.half, 2), "yes" if hit else "no", "–" if need is None else str(need),
                             "–" if math.isnan(r_pair) else f"{r_pair:.2f}"])
                csv_rows.append([scenario, driver, base, m, LIBRARY[m].klass,
                                 *(v for n in SCORES for v in (diffs[n].mean, diffs[n].half)),
                                 d_col.mean, d_col.half, d_exp.mean, d_exp.half, d_pet.mean, d_pet.half, int(hit),
                                 "" if need is None else need, diffs["intelligence"].n, r_pair])
            score = mutation_score(detected)
            intact_i = mean_ci(list(per_seed(intact_key, "intelligence").values()))
            finite_r = [x for x in rs if not math.isnan(x)]
            median_r = statistics.median(finite_r) if finite_r else math.nan
            score_rows.append([scenario, driver, base, sum(detected), len(detected), score, *intact_i, median_r])
            md_parts.append(f"## {scenario} (BVs: {driver}), SUT {base}\n\nIntact intelligence "
                            f"{fmt_ci(*intact_i)}; mutation score {sum(detected)}/{len(detected)}"
                            f"{'' if math.isnan(score) else f' = {score:.2f}'}.\n\n"
                            + markdown_table(header, rows))
            plot_data.append((f"{scenario} / {base}", points))
    for rnd in rounds:
        scenario, base, variant = meta[rnd.key]
        r = results[rnd.key]
        rep = r["report"]
        round_rows.append([scenario, base, variant, r["seed"], r["steps"], *(score_of(rep, n) for n in SCORES),
                           rep["safety"]["collisions"], rep["safety"]["exposures"], r["wall_time_s"]])

    write_csv(args.out / "sensitivity.csv",
              ["scenario", "bv_driver", "base", "mutant", "class",
               *(f"d_{n}_{s}" for n in SCORES for s in ("mean", "ci95")),
               "d_collisions_mean", "d_collisions_ci95", "d_exposures_mean", "d_exposures_ci95", "d_min_pet_mean",
               "d_min_pet_ci95", "detected",
               "seeds_needed", "seeds", "pairing_r"], csv_rows)
    write_csv(args.out / "mutation_scores.csv", ["scenario", "bv_driver", "base", "detected", "mutants",
                                                 "mutation_score", "intact_intelligence_mean",
                                                 "intact_intelligence_ci95", "median_pairing_r"], score_rows)
    write_csv(args.out / "rounds.csv", ["scenario", "base", "variant", "seed", "steps", *SCORES, "collisions",
                                        "exposures", "wall_time_s"], round_rows)
    score_table = markdown_table(["scenario", "BV driver", "SUT", "detected", "mutation score", "intact I",
                                  "median pairing r"],
                                 [[s, d, b, f"{k}/{n}", "–" if math.isnan(x) else f"{x:.2f}", fmt_ci(m, h),
                                   "–" if math.isnan(r) else f"{r:.2f}"]
                                  for s, d, b, k, n, x, m, h, r in score_rows])
    cfg0 = rounds[0].cfg
    wall = sum(results[r.key]["wall_time_s"] for r in rounds)
    text = (f"# Sensitivity experiment (SUT mutation analysis)\n\n{len(bases)} base SUT(s) x {len(mutants)} mutants "
            f"x {len(scenarios)} scenarios x {seeds} seeds ({first}..{first + seeds - 1}), {cfg0.steps} steps, "
            f"{cfg0.bvs.count} BVs; paired by seed (common random numbers); differences intact − mutant of the "
            f"unweighted scores (Δ collisions/exposures: mutant − intact; Δ min PET: intact − mutant of the run's "
            f"smallest lane-change PET, > 0 when the mutant cuts in closer), mean ± 95 % interval over seeds; "
            f"detected: the intelligence interval lies above 0; pairing r: correlation over seeds of intact and "
            f"mutant intelligence; {wall:.0f} s of simulation in all.\n\n"
            f"{score_table}\n" + "\n".join(md_parts) + "\n![sensitivity](sensitivity.png)\n")
    (args.out / "sensitivity.md").write_text(text, encoding="utf-8")
    plot(args.out / "sensitivity.png", plot_data)
    print(score_table, end="")
    print(f"written: {args.out / 'sensitivity.md'}, sensitivity.csv, mutation_scores.csv, rounds.csv, sensitivity.png")
    return EXIT_OK


def plot(path: Path, panels) -> None:  # noqa: ANN001
    """Paired intelligence difference (intact − mutant) of every mutant with its 95 % interval, one panel per scenario."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 0.45 * max(len(p[1]) for p in panels) + 1.6),
                             sharey=True, squeeze=False)
    for ax, (title, points) in zip(axes[0], panels):
        for y, (_name, d) in enumerate(points):
            half = 0.0 if math.isnan(d.half) else d.half
            color = "tab:green" if d.above_zero else "tab:red"
            ax.errorbar([d.mean], [y], xerr=[[half], [half]], fmt="o", color=color, capsize=3)
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_yticks(range(len(points)), [p[0] for p in points])
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("ΔI intact − mutant (95 % CI)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
