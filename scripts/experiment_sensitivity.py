#!/usr/bin/env python3
"""The sensitivity experiment (SUT mutation analysis): does each scenario tell a SUT from its mutants?

    python scripts/experiment_sensitivity.py [--out DIR] [--config FILE] [--base mobil]
                                            [--mutants all|NAME,...] [--scenarios evolving,level0,nilsson,mobil]
                                            [--design episodes|long] [--episodes 100] [--episode-steps 300]
                                            [--seeds 10] [--steps 3000] [--first-seed S] [--jobs N]
                                            [--blocks K] [--block-size N] [--seed-blocks A:B,C:D]
    python scripts/experiment_sensitivity.py --compare-designs [--first-seed S] [--long-first-seed S] ...

For every base SUT model (``--base``, comma-separated) and every scenario, the intact model and
each mutant of the library (:mod:`evoscen_sut.mutants`, docs/mutants.md) run on the same seeds
(common random numbers) in-process. Two test designs (docs/sensitivity.md): ``long`` —
``--seeds`` runs of ``--steps`` steps — and ``episodes`` — ``--episodes`` short runs of
``--episode-steps`` steps, each its own seed (initial state after the warm-up, random
streams); without ``--design`` the design whose flags are given runs, else
:data:`DEFAULT_DESIGN`. Scenarios: ``evolving`` — the BVs as the configuration drives them
(the shipped default: learned social drivers); any BV driver name (``level0``, ``nilsson``,
``mobil``) — every BV driven by that model. Per mutant and scenario: the paired difference
intact − mutant of the intelligence score and of each sub-score, with its 95 % interval over
seeds, *detected* when the intelligence interval lies above zero, and the seeds needed to
detect it; per scenario the mutation score (detected / all). Only the mutants that apply to a base
run on it (:func:`evoscen_sut.mutants.mutants_for`); the others are reported as not applicable and the
mutation score counts applicable (base, mutant) pairs. With seed blocks (``--blocks``/``--block-size``
or ``--seed-blocks``, docs/sensitivity.md "Seed blocks") every mutant's interval, detection and
episodes needed are also given per block, and the mutation score per block and its minimum. Rounds run on ``--jobs`` Ray
workers (the campaign engine) and are saved as they finish: an interrupted experiment
continues where it stopped. Writes ``sensitivity.md``, ``sensitivity.csv``,
``mutation_scores.csv``, ``blocks.csv``, ``not_applicable.csv``, ``speeds.csv``, ``rounds.csv`` and
``sensitivity.png`` into ``--out`` and prints the
tables.

``--compare-designs`` runs both designs at equal compute (the same SUT steps per variant:
episodes × episode steps = seeds × steps, default 100 × 300 = 10 × 3,000; the long design's
seeds follow the episodes' unless ``--long-first-seed``), writes each design's files into
``--out/episodes`` and ``--out/long`` and the comparison into ``designs.md``, ``designs.csv``
(per scenario: detected, median interval half-width, median pairing r, steps) and
``designs_mutants.csv`` (per mutant both intervals). Exit status: 0 done, 2 bad input, 130
interrupted.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_OK

INTACT = "intact"
DEFAULT_DESIGN = "episodes"
"""The design run when neither ``--design`` nor a design's own flags are given: the sharper one at equal
compute in the measured comparison (docs/sensitivity.md "Two designs")."""
EPISODES, EPISODE_STEPS = "100", "300"
"""The episodes design's defaults: 100 episodes × 300 steps (= the long design's SUT steps)."""
SEEDS, STEPS = "10", "3000"
"""The long design's defaults: 10 seeds × 3,000 steps (the method's run length)."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="experiment_sensitivity.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("runs/experiment_sensitivity"), help="output directory")
    ap.add_argument("--config", type=Path, help="base scenario YAML (default: the shipped default)")
    ap.add_argument("--base", default="mobil", help="comma-separated intact SUT models (default mobil)")
    ap.add_argument("--mutants", default="all", help="'all' or comma-separated mutant names of the library")
    ap.add_argument("--scenarios", default="evolving,level0,nilsson,mobil",
                    help="comma-separated: evolving (the config's BV driver) and/or BV driver names")
    ap.add_argument("--design", help=f"episodes (--episodes short runs of --episode-steps) or long (--seeds runs of "
                                     f"--steps); default: the design whose flags are given, else {DEFAULT_DESIGN}")
    ap.add_argument("--episodes", help=f"episodes design: episodes (seeds) per SUT variant and scenario "
                                       f"(default {EPISODES})")
    ap.add_argument("--episode-steps", help=f"episodes design: steps per episode (default {EPISODE_STEPS})")
    ap.add_argument("--seeds", help=f"long design: seeds per SUT variant and scenario (default {SEEDS})")
    ap.add_argument("--steps", help=f"long design: steps per run (default {STEPS})")
    ap.add_argument("--first-seed", default="0", help="first seed (default 0; with --compare-designs the episodes')")
    ap.add_argument("--long-first-seed", help="with --compare-designs: the long design's first seed (default: the "
                                              "seed after the episodes')")
    ap.add_argument("--blocks", help="seed blocks: this many blocks of --block-size seeds each, one after the other "
                                     "from --first-seed (replaces --episodes/--seeds; default: one block)")
    ap.add_argument("--block-size", help="seeds (episodes, or long runs) per block (default: the design's "
                                         f"--episodes {EPISODES} or --seeds {SEEDS})")
    ap.add_argument("--seed-blocks", help="explicit seed blocks 'A:B,C:D' (seeds A..B and C..D, both ends included, "
                                          "disjoint); replaces --first-seed, --blocks, --block-size")
    ap.add_argument("--compare-designs", action="store_true",
                    help="run both designs at equal SUT steps and compare their detection")
    ap.add_argument("--jobs", default=str(os.cpu_count() or 1), help="Ray workers (default: CPU count)")
    return ap.parse_args(argv)


def resolve_designs(args: argparse.Namespace) -> list:
    """The designs to run (:class:`evoscen_experiments.sensitivity.Design`): one, or both with ``--compare-designs``.

    Raises InputError (one line) on a bad combination or value: ``--design`` with the other
    design's flags, both designs' flags without ``--design``, ``--compare-designs`` with
    ``--design``, ``--long-first-seed`` without ``--compare-designs``, unequal SUT steps.
    """
    from evoscen_experiments.experiments import positive_int
    from evoscen_experiments.sensitivity import DESIGNS, Design, blocked_design
    from evoscen_sim.errors import InputError

    ep_flags = [f for f, v in (("--episodes", args.episodes), ("--episode-steps", args.episode_steps)) if v is not None]
    long_flags = [f for f, v in (("--seeds", args.seeds), ("--steps", args.steps)) if v is not None]
    if args.design is not None and args.design not in DESIGNS:
        raise InputError(f"--design {args.design!r}: expected one of {', '.join(DESIGNS)}")
    if args.compare_designs and args.design is not None:
        raise InputError("--compare-designs runs both designs: leave out --design")
    if args.long_first_seed is not None and not args.compare_designs:
        raise InputError("--long-first-seed applies with --compare-designs only (one design starts at --first-seed)")
    names = list(DESIGNS)
    if not args.compare_designs:
        name = args.design
        if name is None:
            if ep_flags and long_flags:
                raise InputError(f"{ep_flags[0]} (episodes design) and {long_flags[0]} (long design) together: "
                                 f"choose one --design, or --compare-designs to run both")
            name = "episodes" if ep_flags else "long" if long_flags else DEFAULT_DESIGN
        other = long_flags if name == "episodes" else ep_flags
        if other:
            raise InputError(f"{other[0]} does not apply to --design {name} (episodes: --episodes, --episode-steps; "
                             f"long: --seeds, --steps)")
        names = [name]

    def value(option: str, text: str | None, default: str) -> int:
        return positive_int(option, default if text is None else text)

    first = positive_int("--first-seed", args.first_seed, 0)
    episodes = Design("episodes", value("--episodes", args.episodes, EPISODES),
                      value("--episode-steps", args.episode_steps, EPISODE_STEPS), first)
    blocks = resolve_blocks(args, names[0], first)
    if blocks is not None:
        name = names[0]
        steps = (episodes.steps if name == "episodes"
                 else value("--steps", args.steps, STEPS))
        return [blocked_design(name, steps, [(b.first, b.last) for b in blocks])]
    long_first = first
    if args.compare_designs:
        long_first = (first + episodes.runs if args.long_first_seed is None
                      else positive_int("--long-first-seed", args.long_first_seed, 0))
    long = Design("long", value("--seeds", args.seeds, SEEDS), value("--steps", args.steps, STEPS), long_first)
    if args.compare_designs and episodes.runs * episodes.steps != long.runs * long.steps:
        raise InputError(f"--compare-designs needs equal compute: episodes {episodes.runs} x {episodes.steps} = "
                         f"{episodes.runs * episodes.steps} SUT steps per variant, long {long.runs} x {long.steps} = "
                         f"{long.runs * long.steps}")
    return [d for d in (episodes, long) if d.name in names]


def resolve_blocks(args: argparse.Namespace, design: str, first: int) -> list | None:
    """The seed blocks (:class:`evoscen_experiments.replication.SeedBlock`) of ``--blocks``/``--block-size`` or
    ``--seed-blocks``; None when neither is given (one block: the design's runs from ``--first-seed``).

    InputError (one line): blocks with ``--compare-designs``, with the design's run count (``--episodes``,
    ``--seeds``), ``--seed-blocks`` with ``--first-seed``/``--blocks``/``--block-size``."""
    from evoscen_experiments.experiments import positive_int
    from evoscen_experiments.replication import consecutive_blocks, parse_seed_blocks
    from evoscen_sim.errors import InputError

    given = [f for f, v in (("--blocks", args.blocks), ("--block-size", args.block_size),
                            ("--seed-blocks", args.seed_blocks)) if v is not None]
    if not given:
        return None
    if args.compare_designs:
        raise InputError(f"{given[0]} does not apply with --compare-designs (each design runs one block)")
    runs_flag = "--episodes" if design == "episodes" else "--seeds"
    if (args.episodes if design == "episodes" else args.seeds) is not None:
        raise InputError(f"{runs_flag} and {given[0]} together: a blocked design's runs are its blocks' seeds")
    if args.seed_blocks is not None:
        other = [f for f in ("--blocks", "--block-size") if f in given]
        if other or args.first_seed != "0":
            raise InputError(f"--seed-blocks and {other[0] if other else '--first-seed'} together: the blocks "
                             f"name their seeds")
        return parse_seed_blocks(args.seed_blocks)
    count = positive_int("--blocks", "1" if args.blocks is None else args.blocks)
    size = positive_int("--block-size", args.block_size if args.block_size is not None
                        else (EPISODES if design == "episodes" else SEEDS))
    return consecutive_blocks(first, count, size)


def build_rounds(designs: list, bases: list[str], scenarios: list[str], mutants: list[str],
                 config: Path | None) -> tuple[list, dict[str, tuple[str, str, str, str]]]:
    """The rounds of every design: per scenario, SUT variant (intact, then each mutant that applies to the
    base, :func:`evoscen_experiments.replication.applicable_split`) and seed of the design, one run of the design's
    steps. Returns the rounds and their key -> (design, scenario,
    base, variant); every variant of a scenario runs on the same seeds (paired)."""
    from evoscen_experiments.experiments import Round, config_loader
    from evoscen_sut.mutants import mutant_overrides

    load = config_loader(config)

    from evoscen_experiments.replication import applicable_split

    variants: list[tuple[str, str, dict[str, str]]] = []  # (base, mutant or intact, overrides)
    for base in bases:
        variants.append((base, INTACT, {"sut.model": base}))
        # only the mutants that apply to the base run (docs/sensitivity.md "Every base")
        variants += [(base, m, mutant_overrides(base, m)) for m in applicable_split(base, mutants)[0]]
    rounds = []
    meta: dict[str, tuple[str, str, str, str]] = {}
    for design in designs:
        for scenario in scenarios:
            for base, variant, sut_overrides in variants:
                for seed in design.seeds:
                    overrides = {**sut_overrides, "seed": str(seed), "steps": str(design.steps),
                                 "recording.enabled": "false"}
                    if scenario != "evolving":
                        overrides["bvs.driver"] = scenario
                    rnd = Round(f"{scenario}--{base}--{variant}", load(overrides))
                    rounds.append(rnd)
                    meta[rnd.key] = (design.name, scenario, base, variant)
    return rounds, meta


def warmup_steps(cfg) -> int:  # a ScenarioConfig
    """Steps of the warm-up before every run (``traffic.warmup_s / dt_s``; none without the traffic window)."""
    return int(round(cfg.traffic.warmup_s / cfg.dt_s)) if cfg.traffic.mode == "window" else 0


def compute_text(design, cfg, variants: int) -> str:
    """One paragraph: the design's SUT steps (what equal compute equalises) and its warm-up (extra compute)."""
    from evoscen_experiments.sensitivity import design_compute

    w = warmup_steps(cfg)
    c = design_compute(design, w)
    warm = (f"the warm-up (traffic.warmup_s = {cfg.traffic.warmup_s:g} s, {w} steps) runs before every run and is "
            f"extra compute, the same per run in either design: {design.runs} x {w} = {c.warmup_steps:,} steps"
            if w else "no warm-up (traffic.warmup_s = 0 or no traffic window)")
    seeds = (f"seeds {design.seeds[0]}..{design.seeds[-1]}" if len(design.block_bounds) == 1 else
             "seed blocks " + ", ".join(f"{a}..{b}" for a, b in design.block_bounds))
    return (f"Design {design.name}: {design.runs} {design.unit}s ({seeds}) x "
            f"{design.steps:,} steps = {c.sut_steps:,} SUT steps per variant and scenario; {warm}; "
            f"{c.total:,} simulated steps per variant and scenario, {c.total * variants:,} in all "
            f"({variants} variant-scenario pairs, {design.runs * variants:,} runs).")


def summarise(design, rounds: list, results: dict, meta: dict, out: Path, bases: list[str],
              scenarios: list[str], mutants: list[str]) -> tuple[dict, str]:
    """One design's tables and files in ``out`` (sensitivity.md/.csv, mutation_scores.csv, rounds.csv,
    sensitivity.png). Returns (scenario, base) -> :class:`DesignSummary` and the score table (Markdown)."""
    from evoscen_experiments.experiments import difference_words, fmt_ci, markdown_table, mean_ci, write_csv
    from evoscen_experiments.replication import SeedBlock, applicable_split, block_detection, block_scores
    from evoscen_experiments.sensitivity import (
        SCORES,
        SSM_RATES,
        paired,
        score_of,
        seeds_needed,
        ssm_label,
        ssm_rate,
        summarise_design,
    )
    from evoscen_sut.mutants import LIBRARY

    out.mkdir(parents=True, exist_ok=True)
    rounds = [r for r in rounds if meta[r.key][0] == design.name]
    # seed -> report, per (scenario, base, variant)
    reports: dict[tuple[str, str, str], dict[int, dict]] = {}
    for rnd in rounds:
        reports.setdefault(meta[rnd.key][1:], {})[rnd.cfg.seed] = results[rnd.key]["report"]

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

    def rates(key: tuple[str, str, str], side: str, measure: str) -> dict[int, float]:
        return {s: ssm_rate(r, side, measure) for s, r in reports[key].items()}

    def speeds(key: tuple[str, str, str], which: str) -> dict[int, float]:
        """Per seed the SUT's mean speed (``sut``) or the comparative score's reference speed (``reference``:
        the mean speed of the vehicles in the SUT's view, docs/evaluation.md §10.2), m/s; nan where absent."""
        out = {}
        for s, r in reports[key].items():
            if which == "sut":
                v = (r.get("efficiency") or {}).get("mean_speed_mps")
            else:
                v = (((r.get("comparative") or {}).get("progress")) or {}).get("reference_mean_speed_mps")
            out[s] = math.nan if v is None else float(v)
        return out

    unit = design.unit
    first_report = next(iter(next(iter(reports.values())).values()))
    ssm_header = ["mutant", *(ssm_label(side, m, first_report) for side, m in SSM_RATES), "n"]
    header = ["mutant", "class", "ΔI (intact − mutant)", "mutant's I vs intact (95 %)", "ΔI_s", "ΔI_e", "ΔI_i",
              "Δ collisions (mutant − intact)", "Δ exposures (mutant − intact)", "Δ min PET (s, intact − mutant)",
              "detected", f"{unit}s needed", "pairing r"]
    csv_rows, score_rows, md_parts, plot_data = [], [], [], []
    block_rows, block_csv, csv_na, speed_csv = [], [], [], []
    blocks = [SeedBlock(a, b) for a, b in design.block_bounds]
    summaries = {}
    round_rows = []
    for scenario in scenarios:
        driver = next(r.cfg.bvs.driver for r in rounds if meta[r.key][1] == scenario)
        for base in bases:
            intact_key = (scenario, base, INTACT)
            applicable, not_applicable = applicable_split(base, mutants)
            summary = summarise_design(per_seed(intact_key, "intelligence"),
                                       {m: per_seed((scenario, base, m), "intelligence") for m in applicable})
            summaries[(scenario, base)] = summary
            rows, points = [], []
            intact_rates = [mean_ci([v for v in rates(intact_key, side, ms).values() if not math.isnan(v)])
                            for side, ms in SSM_RATES]
            v_i = mean_ci([v for v in speeds(intact_key, "sut").values() if not math.isnan(v)])
            ref_i = mean_ci([v for v in speeds(intact_key, "reference").values() if not math.isnan(v)])
            speed_rows = []
            ssm_rows = [["intact (mean)", *(fmt_ci(mean, half, 2) for mean, half in intact_rates),
                         str(len(reports[intact_key]))]]
            per_block = {m: block_detection(per_seed(intact_key, "intelligence"),
                                            per_seed((scenario, base, m), "intelligence"), blocks)
                         for m in applicable}
            b_scores = block_scores(per_block, blocks)
            block_rows.append([m_row for m in applicable for m_row in [
                [m, *(cell for b in per_block[m].per_block for cell in (
                    f"{fmt_ci(b.diff.mean, b.diff.half)} (n {b.diff.n})", "yes" if b.detected else "no",
                    "–" if b.needed is None else str(b.needed))),
                 f"{per_block[m].detected_blocks}/{len(blocks)}"]]])
            for m in applicable:
                for b in per_block[m].per_block:
                    block_csv.append([design.name, scenario, driver, base, m, LIBRARY[m].klass, b.block.first,
                                      b.block.last, b.diff.mean, b.diff.half, b.diff.n, int(b.detected),
                                      "" if b.needed is None else b.needed])
            for m in applicable:
                key = (scenario, base, m)
                diffs = {name: paired(per_seed(intact_key, name), per_seed(key, name)) for name in SCORES}
                d_col = paired(counts(key, "safety", "collisions"), counts(intact_key, "safety", "collisions"))
                d_exp = paired(counts(key, "safety", "exposures"), counts(intact_key, "safety", "exposures"))
                d_pet = paired(min_pet(intact_key), min_pet(key))
                d_ssm = [paired(rates(key, side, ms), rates(intact_key, side, ms)) for side, ms in SSM_RATES]
                ssm_rows.append([m, *(fmt_ci(d.mean, d.half, 2) for d in d_ssm), str(d_ssm[0].n)])
                d_v = paired(speeds(key, "sut"), speeds(intact_key, "sut"))
                d_ref = paired(speeds(key, "reference"), speeds(intact_key, "reference"))
                speed_rows.append([m, fmt_ci(d_v.mean, d_v.half, 2), fmt_ci(d_ref.mean, d_ref.half, 2),
                                   # the ratio only where the SUT's speed changed beyond noise
                                   f"{d_ref.mean / d_v.mean:.2f}" if d_v.n >= 2 and abs(d_v.mean) > d_v.half else "–",
                                   str(d_v.n)])
                speed_csv.append([design.name, scenario, driver, base, m, d_v.mean, d_v.half, d_ref.mean, d_ref.half,
                                  d_v.n])
                need = seeds_needed(per_seed(intact_key, "intelligence"), per_seed(key, "intelligence"))
                r_pair = summary.pairing_r[m]
                hit = diffs["intelligence"].above_zero
                points.append((m, diffs["intelligence"]))
                di = diffs["intelligence"]
                cells = [fmt_ci(diffs[n].mean, diffs[n].half) for n in SCORES]
                # in words the mutant against the intact model: mutant − intact, the negative of the column's
                rows.append([m, LIBRARY[m].klass, cells[0], difference_words(-di.mean, di.half, di.n), *cells[1:],
                             fmt_ci(d_col.mean, d_col.half, 2), fmt_ci(d_exp.mean, d_exp.half, 2),
                             fmt_ci(d_pet.mean, d_pet.half, 2), "yes" if hit else "no", "–" if need is None else str(need),
                             "–" if math.isnan(r_pair) else f"{r_pair:.2f}"])
                csv_rows.append([design.name, scenario, driver, base, m, LIBRARY[m].klass,
                                 *(v for n in SCORES for v in (diffs[n].mean, diffs[n].half)),
                                 d_col.mean, d_col.half, d_exp.mean, d_exp.half, d_pet.mean, d_pet.half, int(hit),
                                 "" if need is None else need, diffs["intelligence"].n, r_pair,
                                 *(v for d in d_ssm for v in (d.mean, d.half)), d_ssm[0].n])
            for m in not_applicable:
                rows.append([m, LIBRARY[m].klass, f"not applicable to {base}", *["–"] * (len(header) - 3)])
                csv_na.append([scenario, driver, base, m, LIBRARY[m].klass, LIBRARY[m].applies])
            intact_i = mean_ci(list(per_seed(intact_key, "intelligence").values()))
            low = b_scores.min_block
            score_rows.append([scenario, driver, base, summary.detected, summary.mutants, summary.score, *intact_i,
                               summary.median_r, len(not_applicable), ";".join(map(str, b_scores.detected)),
                               b_scores.min_detected, "" if low is None else low.label, b_scores.every_block])
            score = summary.score
            block_header = ["mutant", *(h for b in blocks for h in (f"ΔI block {b.label}", f"detected {b.label}",
                                                                   f"{unit}s needed {b.label}")),
                            "detected in blocks"]
            per_block_text = ", ".join(f"{k}/{summary.mutants} in block {b.label}"
                                       for k, b in zip(b_scores.detected, blocks))
            md_parts.append(f"## {scenario} (BVs: {driver}), SUT {base}\n\nIntact intelligence "
                            f"{fmt_ci(*intact_i)}; mutation score over all {unit}s {summary.detected}/{summary.mutants}"
                            f"{'' if math.isnan(score) else f' = {score:.2f}'} (applicable mutants; "
                            f"{len(not_applicable)} not applicable to {base}"
                            f"{': ' + ', '.join(not_applicable) if not_applicable else ''}); per block: "
                            f"{per_block_text}; minimum over blocks {b_scores.min_detected}/{summary.mutants}"
                            f"{'' if low is None else f' (block {low.label})'}; detected in every block "
                            f"{b_scores.every_block}/{summary.mutants}.\n\n"
                            + markdown_table(header, rows)
                            + f"\nPer seed block: ΔI = intact − mutant over the block's {unit}s (95 % interval, n), "
                            f"detected, {unit}s needed (the smallest n from which every prefix of the block's {unit}s "
                            f"detects).\n\n" + markdown_table(block_header, block_rows[-1])
                            + f"\nSurrogate safety of the SUT per SUT-km (docs/evaluation.md): the intact model's mean "
                            f"± 95 % interval over {unit}s, then each mutant's paired difference mutant − intact "
                            f"(> 0: more conflicts), n {unit}s.\n\n" + markdown_table(ssm_header, ssm_rows)
                            + f"\nSpeeds (m/s): the intact SUT's mean {fmt_ci(*v_i, 2)}, the progress reference (the "
                            f"mean speed of the vehicles in its view, docs/evaluation.md §10.2) {fmt_ci(*ref_i, 2)}; "
                            f"per mutant the paired differences mutant − intact and their ratio (how much of the "
                            f"SUT's change the reference follows; where the SUT's change is significant).\n\n"
                            + markdown_table(["mutant", "Δ SUT speed", "Δ reference speed", "ratio", "n"],
                                             speed_rows))
            plot_data.append((f"{scenario} / {base}", points))
    for rnd in rounds:
        _, scenario, base, variant = meta[rnd.key]
        r = results[rnd.key]
        rep = r["report"]
        round_rows.append([design.name, scenario, base, variant, r["seed"], r["steps"],
                           *(score_of(rep, n) for n in SCORES), rep["safety"]["collisions"],
                           rep["safety"]["exposures"], r["wall_time_s"],
                           *(ssm_rate(rep, side, ms) for side, ms in SSM_RATES)])

    write_csv(out / "sensitivity.csv",
              ["design", "scenario", "bv_driver", "base", "mutant", "class",
               *(f"d_{n}_{s}" for n in SCORES for s in ("mean", "ci95")),
               "d_collisions_mean", "d_collisions_ci95", "d_exposures_mean", "d_exposures_ci95", "d_min_pet_mean",
               "d_min_pet_ci95", "detected",
               "seeds_needed", "seeds", "pairing_r",
               *(f"d_ssm_{side}_{ms}_per_km_{s}" for side, ms in SSM_RATES for s in ("mean", "ci95")), "ssm_n"],
              csv_rows)
    write_csv(out / "mutation_scores.csv", ["scenario", "bv_driver", "base", "detected", "mutants",
                                            "mutation_score", "intact_intelligence_mean",
                                            "intact_intelligence_ci95", "median_pairing_r", "not_applicable",
                                            "detected_per_block", "min_detected_over_blocks", "min_block",
                                            "detected_every_block"], score_rows)
    write_csv(out / "blocks.csv", ["design", "scenario", "bv_driver", "base", "mutant", "class", "block_first_seed",
                                   "block_last_seed", "d_intelligence_mean", "d_intelligence_ci95", "n", "detected",
                                   "needed"], block_csv)
    write_csv(out / "speeds.csv", ["design", "scenario", "bv_driver", "base", "mutant", "d_sut_speed_mean",
                                   "d_sut_speed_ci95", "d_reference_speed_mean", "d_reference_speed_ci95", "n"],
              speed_csv)
    write_csv(out / "not_applicable.csv", ["scenario", "bv_driver", "base", "mutant", "class", "applies_to"], csv_na)
    write_csv(out / "rounds.csv", ["design", "scenario", "base", "variant", "seed", "steps", *SCORES, "collisions",
                                   "exposures", "wall_time_s",
                                   *(f"ssm_{side}_{ms}_per_km" for side, ms in SSM_RATES)], round_rows)
    score_table = markdown_table(["scenario", "BV driver", "SUT", "detected", "mutation score", "intact I",
                                  "median pairing r", "not applicable", "detected per block",
                                  "min over blocks (block)", "detected in every block"],
                                 [[s, d, b, f"{k}/{n}", "–" if math.isnan(x) else f"{x:.2f}", fmt_ci(m, h),
                                   "–" if math.isnan(r) else f"{r:.2f}", str(na), per.replace(";", ", "),
                                   f"{lo}/{n} ({lo_b})", f"{ev}/{n}"]
                                  for s, d, b, k, n, x, m, h, r, na, per, lo, lo_b, ev in score_rows])
    pooled = []
    for scenario in scenarios:
        own = [row for row in score_rows if row[0] == scenario]
        k, n = sum(row[3] for row in own), sum(row[4] for row in own)
        every = sum(row[13] for row in own)
        pooled.append(f"{scenario}: detected {k}/{n} applicable (base, mutant) pairs over all {unit}s, "
                      f"{every}/{n} in every block; {sum(row[9] for row in own)} pairs not applicable")
    score_table += "\nMutation score over the applicable (base, mutant) pairs: " + "; ".join(pooled) + ".\n"
    cfg0 = rounds[0].cfg
    wall = sum(results[r.key]["wall_time_s"] for r in rounds)
    simulated = sum(results[r.key]["report"]["run"]["duration_s"] for r in rounds)
    variants = len({meta[r.key][1:] for r in rounds})
    form = (first_report.get("settings") or {}).get("score_form", "method")
    form_text = ("the comparative score (evaluation.score_form: comparative, docs/evaluation.md §10): I = D, I_s = its "
                 "safety S, I_e = its progress P, I_i = its interaction X" if form == "comparative" else
                 "the method's intelligence (evaluation.score_form: method)")
    text = (f"# Sensitivity experiment (SUT mutation analysis)\n\nScores: {form_text}.\n\n"
            f"{len(bases)} base SUT(s) x {len(mutants)} mutants "
            f"x {len(scenarios)} scenarios x {design.runs} {unit}s (seed blocks "
            f"{', '.join(b.label for b in blocks)}; no sequential stopping: every block runs all its {unit}s), "
            f"{design.steps} steps, {cfg0.bvs.count} BVs; paired by {unit} (common random numbers: a seed fixes the "
            f"initial state after the warm-up and every random stream); differences intact − mutant of the "
            f"unweighted scores (Δ collisions/exposures: mutant − intact; Δ min PET: intact − mutant of the run's "
            f"smallest lane-change PET, > 0 when the mutant cuts in closer), mean ± 95 % interval over {unit}s; "
            f"the mutant's I in words: 'significantly lower' (= detected: the intact − mutant interval lies above 0), "
            f"'significantly higher' or 'no significant difference'; pairing r: correlation over {unit}s of intact and "
            f"mutant intelligence; {simulated:,.0f} s simulated (scored states of all runs), {wall:,.0f} s wall "
            f"time in all.\n\n{compute_text(design, cfg0, variants)}\n\n"
            f"{score_table}\n" + "\n".join(md_parts) + "\n![sensitivity](sensitivity.png)\n")
    (out / "sensitivity.md").write_text(text, encoding="utf-8")
    plot(out / "sensitivity.png", plot_data)
    return summaries, score_table


def comparison_rows(designs: list, summaries: dict, computes: dict, walls: dict) -> tuple[list, list, list, list]:
    """The design comparison from each design's summaries ((scenario, base) -> DesignSummary, per design name).

    Returns the per-scenario rows (Markdown, CSV) and the per-mutant rows (Markdown, CSV): per
    scenario and design the detected mutants, the mutation score, the median 95 % half-width of
    intact − mutant intelligence, the median pairing r, n (runs per variant), SUT and simulated
    steps per variant, the runs' summed wall time (``walls``: design -> (scenario, base) -> s);
    per mutant both designs' intervals with n and detection.
    """
    from evoscen_experiments.experiments import fmt_ci

    def num(x: float, digits: int) -> str:
        return "–" if math.isnan(x) else f"{x:.{digits}f}"

    md, rows, md_m, rows_m = [], [], [], []
    first = designs[0].name
    for scenario, base in summaries[first]:
        for d in designs:
            s = summaries[d.name][(scenario, base)]
            c = computes[d.name]
            md.append([scenario, base, d.name, f"{d.runs} x {d.steps}", f"{s.detected}/{s.mutants}", num(s.score, 2),
                       num(s.median_half, 4), num(s.median_r, 2), f"{c.sut_steps:,}", f"{c.total:,}",
                       f"{walls[d.name].get((scenario, base), math.nan):.0f}"])
            rows.append([scenario, base, d.name, d.runs, d.steps, s.detected, s.mutants, s.score, s.median_half,
                         s.median_r, c.sut_steps, c.warmup_steps, c.total,
                         walls[d.name].get((scenario, base), math.nan)])
        for m in summaries[first][(scenario, base)].per_mutant:
            cells, values = [], []
            for d in designs:
                p = summaries[d.name][(scenario, base)].per_mutant[m]
                cells += [f"{fmt_ci(p.mean, p.half)} (n {p.n})", "yes" if p.above_zero else "no"]
                values += [p.mean, p.half, p.n, int(p.above_zero)]
            md_m.append([scenario, base, m, *cells])
            rows_m.append([scenario, base, m, *values])
    return md, rows, md_m, rows_m


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments.experiments import (
        distinct_names,
        markdown_table,
        positive_int,
        run_rounds_with_bar,
        set_up,
        write_csv,
    )
    from evoscen_experiments.sensitivity import design_compute, sharper_design
    from evoscen_sim.errors import InputError
    from evoscen_sut.mutants import LIBRARY

    def build():
        designs = resolve_designs(args)
        jobs = positive_int("--jobs", args.jobs)
        bases = distinct_names("--base", args.base)
        scenarios = distinct_names("--scenarios", args.scenarios)
        mutants = list(LIBRARY) if args.mutants.strip() == "all" else distinct_names("--mutants", args.mutants)
        unknown = [m for m in mutants if m not in LIBRARY]
        if unknown:
            raise InputError(f"--mutants: unknown mutant {unknown[0]!r}: expected 'all' or names from "
                             f"{', '.join(LIBRARY)}")
        rounds, meta = build_rounds(designs, bases, scenarios, mutants, args.config)
        return designs, bases, scenarios, mutants, rounds, meta, jobs

    try:
        built = set_up(args.out, build)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    designs, bases, scenarios, mutants, rounds, meta, jobs = built

    results = run_rounds_with_bar(rounds, args.out, jobs=jobs, desc="sensitivity")
    if results is None:
        return EXIT_INTERRUPTED

    cfg0 = rounds[0].cfg
    variants = len({meta[r.key][1:] for r in rounds})
    if not args.compare_designs:
        (design,) = designs
        _, score_table = summarise(design, rounds, results, meta, args.out, bases, scenarios, mutants)
        print(compute_text(design, cfg0, variants))
        print(score_table, end="")
        print(f"written: {args.out / 'sensitivity.md'}, sensitivity.csv, mutation_scores.csv, blocks.csv, "
              f"not_applicable.csv, speeds.csv, rounds.csv, sensitivity.png")
        return EXIT_OK

    summaries, computes, walls = {}, {}, {}
    for d in designs:
        summaries[d.name], _ = summarise(d, rounds, results, meta, args.out / d.name, bases, scenarios, mutants)
        computes[d.name] = design_compute(d, warmup_steps(cfg0))
        walls[d.name] = {}
        for r in rounds:
            name, scenario, base = meta[r.key][:3]
            if name == d.name:
                walls[d.name][(scenario, base)] = (walls[d.name].get((scenario, base), 0.0)
                                                   + results[r.key]["wall_time_s"])
    md, rows, md_m, rows_m = comparison_rows(designs, summaries, computes, walls)
    verdict = sharper_design({d.name: list(summaries[d.name].values()) for d in designs})
    detected = {d.name: sum(s.detected for s in summaries[d.name].values()) for d in designs}
    table = markdown_table(["scenario", "SUT", "design", "runs x steps", "detected", "mutation score",
                            "median half-width", "median pairing r", "SUT steps / variant",
                            "simulated steps / variant", "run time (s, summed)"], md)
    mut_header = ["scenario", "SUT", "mutant"]
    for d in designs:
        mut_header += [f"{d.name}: ΔI (95 % CI, n)", f"{d.name}: detected"]
    write_csv(args.out / "designs.csv", ["scenario", "base", "design", "runs", "steps", "detected", "mutants",
                                         "mutation_score", "median_ci95", "median_pairing_r", "sut_steps",
                                         "warmup_steps", "simulated_steps", "run_time_s"], rows)
    write_csv(args.out / "designs_mutants.csv",
              ["scenario", "base", "mutant", *(f"{d.name}_{k}" for d in designs
                                               for k in ("d_intelligence_mean", "d_intelligence_ci95", "n",
                                                         "detected"))], rows_m)
    totals = ", ".join(f"{d.name} {detected[d.name]}" for d in designs)
    sharper = ("neither (tie on detections and median half-width)" if verdict is None else
               f"{verdict} (detected over all scenarios: {totals}; ties go to the narrower median half-width)")
    compute = "\n".join(f"- {compute_text(d, cfg0, variants)}" for d in designs)
    text = (f"# Test designs compared: episodes vs long runs at equal compute\n\nBoth designs give every SUT "
            f"variant the same SUT steps; intact and mutants are paired per seed (an episode, or a long run), "
            f"95 % Student-t intervals of intact − mutant intelligence over the n runs; detected: the interval "
            f"lies above 0; median half-width and median pairing r over the mutants of a scenario. The designs' "
            f"seeds are {designs[0].seeds[0]}..{designs[0].seeds[-1]} and "
            f"{designs[1].seeds[0]}..{designs[1].seeds[-1]}.\n\n{compute}\n\nSharper design: {sharper}.\n\n"
            f"{table}\n## Per mutant\n\n{markdown_table(mut_header, md_m)}\nEach design's own tables: "
            + ", ".join(f"[{d.name}/sensitivity.md]({d.name}/sensitivity.md)" for d in designs) + ".\n")
    (args.out / "designs.md").write_text(text, encoding="utf-8")
    print(compute)
    print(table, end="")
    print(f"sharper design: {sharper}")
    print(f"written: {args.out / 'designs.md'}, designs.csv, designs_mutants.csv, "
          + ", ".join(f"{d.name}/" for d in designs))
    return EXIT_OK


def plot(path: Path, panels) -> None:
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
