"""The sensitivity experiment (SUT mutation analysis, docs/sensitivity.md): its designs, its rounds, its run.

``scripts/experiment_sensitivity.py`` parses the command line and calls :func:`main`: the test designs
from the options (:func:`resolve_designs`, seed blocks by :func:`resolve_blocks`), the rounds of every
design (:func:`build_rounds`: every base SUT, intact and each applicable mutant, on the same seeds), run
on the campaign engine (:func:`evoscen_experiments.experiments.run_rounds_with_bar`), then one design's
tables (:func:`evoscen_experiments.sensitivity_tables.summarise`) or, with ``--compare-designs``, both
designs' and their comparison (:func:`compare_designs`, :func:`comparison_rows`).
"""

from __future__ import annotations

import math
from pathlib import Path

from evoscen_contract.contract import EXIT_INTERRUPTED, EXIT_OK

from evoscen_experiments.timing import finish
from evoscen_sim.errors import InputError

from evoscen_experiments.experiments import challenge_mode, positive_int, batch_option
from evoscen_experiments.sensitivity_tables import INTACT, compute_text, summarise, warmup_steps

DEFAULT_DESIGN = "episodes"
"""The design run when neither ``--design`` nor a design's own flags are given: the sharper one at equal
compute in the measured comparison (docs/sensitivity.md "Two designs")."""
EPISODES, EPISODE_STEPS = "100", "300"
"""The episodes design's defaults: 100 episodes × 300 steps (= the long design's SUT steps)."""
SEEDS, STEPS = "10", "3000"
"""The long design's defaults: 10 seeds × 3,000 steps (the method's run length)."""


def _design_names(args) -> list[str]:
    """The names of the designs the options ask for (InputError on a bad combination)."""
    from evoscen_experiments.sensitivity import DESIGNS

    ep_flags = [f for f, v in (("--episodes", args.episodes), ("--episode-steps", args.episode_steps)) if v is not None]
    long_flags = [f for f, v in (("--seeds", args.seeds), ("--steps", args.steps)) if v is not None]
    if args.design is not None and args.design not in DESIGNS:
        raise InputError(f"--design {args.design!r}: expected one of {', '.join(DESIGNS)}")
    if args.compare_designs and args.design is not None:
        raise InputError("--compare-designs runs both designs: leave out --design")
    if args.long_first_seed is not None and not args.compare_designs:
        raise InputError("--long-first-seed applies with --compare-designs only (one design starts at --first-seed)")
    if args.compare_designs:
        return list(DESIGNS)
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
    return [name]


def resolve_designs(args) -> list:
    """The designs to run (:class:`evoscen_experiments.sensitivity.Design`) from the parsed options (text
    values): one, or both with ``--compare-designs``.

    Raises InputError (one line) on a bad combination or value: ``--design`` with the other
    design's flags, both designs' flags without ``--design``, ``--compare-designs`` with
    ``--design``, ``--long-first-seed`` without ``--compare-designs``, unequal SUT steps.
    """
    from evoscen_experiments.sensitivity import Design, blocked_design

    names = _design_names(args)

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


def resolve_blocks(args, design: str, first: int) -> list | None:
    """The seed blocks (:class:`evoscen_experiments.replication.SeedBlock`) of ``--blocks``/``--block-size`` or
    ``--seed-blocks``; None when neither is given (one block: the design's runs from ``--first-seed``).

    InputError (one line): blocks with ``--compare-designs``, with the design's run count (``--episodes``,
    ``--seeds``), ``--seed-blocks`` with ``--first-seed``/``--blocks``/``--block-size``."""
    from evoscen_experiments.replication import consecutive_blocks, parse_seed_blocks

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
                 config: Path | None, challenge: str | None = None) -> tuple[list, dict[str, tuple[str, str, str, str]]]:
    """The rounds of every design: per scenario, SUT variant (intact, then each mutant that applies to the
    base, :func:`evoscen_experiments.replication.applicable_split`) and seed of the design, one run of the design's
    steps. Returns the rounds and their key -> (design, scenario,
    base, variant); every variant of a scenario runs on the same seeds (paired)."""
    from evoscen_experiments.experiments import Round, config_loader
    from evoscen_experiments.replication import applicable_split
    from evoscen_sut.mutants import mutant_overrides

    load = config_loader(config, challenge)
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


def variant_names(args) -> tuple[list[str], list[str], list[str], int]:
    """The bases, scenarios, mutants and workers of the options (InputError, one line, on a bad one)."""
    from evoscen_experiments.experiments import distinct_names
    from evoscen_sut.mutants import LIBRARY

    jobs = positive_int("--jobs", args.jobs)
    bases = distinct_names("--base", args.base)
    scenarios = distinct_names("--scenarios", args.scenarios)
    mutants = list(LIBRARY) if args.mutants.strip() == "all" else distinct_names("--mutants", args.mutants)
    unknown = [m for m in mutants if m not in LIBRARY]
    if unknown:
        raise InputError(f"--mutants: unknown mutant {unknown[0]!r}: expected 'all' or names from "
                         f"{', '.join(LIBRARY)}")
    return bases, scenarios, mutants, jobs


def _build(args):
    """The designs, bases, scenarios, mutants, rounds (with their meta) and workers of the options."""
    designs = resolve_designs(args)
    bases, scenarios, mutants, jobs = variant_names(args)
    rounds, meta = build_rounds(designs, bases, scenarios, mutants, args.config,
                                challenge_mode(getattr(args, "challenge", None)))
    return designs, bases, scenarios, mutants, rounds, meta, jobs


def main(args) -> int:
    """The experiment of the parsed options (``scripts/experiment_sensitivity.py``; text values, checked here):
    the rounds run (or read back), then one design's files in ``args.out``, or both designs' and their
    comparison, or with ``--sequential`` the sequential verdicts (:mod:`evoscen_experiments.sensitivity_sequential`).
    Returns the exit status; InputError (one line) on bad input, before anything is written."""
    from evoscen_experiments import sensitivity_sequential
    from evoscen_experiments.experiments import run_rounds_with_bar, set_up

    plan = sensitivity_sequential.resolve_plan(args, EPISODE_STEPS)
    if plan is not None:
        return sensitivity_sequential.main(args, plan, lambda: variant_names(args))
    designs, bases, scenarios, mutants, rounds, meta, jobs = set_up(args.out, lambda: _build(args))
    results = run_rounds_with_bar(rounds, args.out, jobs=jobs, desc="sensitivity", batch=batch_option(args))
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
        finish(args.out)  # the command's start-up and throughput (timing.json)
        return EXIT_OK
    summaries = {d.name: summarise(d, rounds, results, meta, args.out / d.name, bases, scenarios, mutants)[0]
                 for d in designs}
    compare_designs(args.out, designs, summaries, rounds, results, meta)
    finish(args.out)  # the command's start-up and throughput (timing.json)
    return EXIT_OK


def compare_designs(out: Path, designs: list, summaries: dict, rounds: list, results: dict, meta: dict) -> None:
    """The design comparison (``--compare-designs``): ``designs.md``, ``designs.csv``, ``designs_mutants.csv``
    in ``out`` from each design's summaries, printed."""
    from evoscen_experiments.experiments import markdown_table, write_csv
    from evoscen_experiments.sensitivity import PROFILES, design_compute, sharper_design

    cfg0 = rounds[0].cfg
    variants = len({meta[r.key][1:] for r in rounds})
    computes, walls = {}, {}
    for d in designs:
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
        mut_header += [f"{d.name}: ΔD (95 % CI, n)", f"{d.name}: detected"]
    write_csv(out / "designs.csv", ["scenario", "base", "design", "runs", "steps", "detected", "mutants",
                                    "mutation_score", "median_ci95", "median_pairing_r", "sut_steps",
                                    "warmup_steps", "simulated_steps", "run_time_s"], rows)
    write_csv(out / "designs_mutants.csv",
              ["scenario", "base", "mutant", *(f"{d.name}_{k}" for d in designs
                                               for k in ("delta_d_mean", "delta_d_ci95", "n",
                                                         "detected"))], rows_m)
    totals = ", ".join(f"{d.name} {detected[d.name]}" for d in designs)
    sharper = ("neither (tie on detections and median half-width)" if verdict is None else
               f"{verdict} (detected over all scenarios: {totals}; ties go to the narrower median half-width)")
    compute = "\n".join(f"- {compute_text(d, cfg0, variants)}" for d in designs)
    text = (f"# Test designs compared: episodes vs long runs at equal compute\n\nBoth designs give every SUT "
            f"variant the same SUT steps; intact and mutants are paired per seed (an episode, or a long run), "
            f"95 % Student-t intervals of intact − mutant D (the compared score: evaluation.score_form's, D by default) "
            f"over the n runs; detected: the interval lies above 0; detected, median half-width and median pairing "
            f"r over the defects of a scenario (profiles, {', '.join(PROFILES)}, not counted). The designs' "
            f"seeds are {designs[0].seeds[0]}..{designs[0].seeds[-1]} and "
            f"{designs[1].seeds[0]}..{designs[1].seeds[-1]}.\n\n{compute}\n\nSharper design: {sharper}.\n\n"
            f"{table}\n## Per mutant\n\n{markdown_table(mut_header, md_m)}\nEach design's own tables: "
            + ", ".join(f"[{d.name}/sensitivity.md]({d.name}/sensitivity.md)" for d in designs) + ".\n")
    (out / "designs.md").write_text(text, encoding="utf-8")
    print(compute)
    print(table, end="")
    print(f"sharper design: {sharper}")
    print(f"written: {out / 'designs.md'}, designs.csv, designs_mutants.csv, "
          + ", ".join(f"{d.name}/" for d in designs))


def comparison_rows(designs: list, summaries: dict, computes: dict, walls: dict) -> tuple[list, list, list, list]:
    """The design comparison from each design's summaries ((scenario, base) -> DesignSummary, per design name).

    Returns the per-scenario rows (Markdown, CSV) and the per-mutant rows (Markdown, CSV): per
    scenario and design the detected mutants, the mutation score, the median 95 % half-width of
    intact − mutant D, the median pairing r, n (runs per variant), SUT and simulated
    steps per variant, the runs' summed wall time (``walls``: design -> (scenario, base) -> s);
    per mutant both designs' intervals with n and detection.
    """
    from evoscen_experiments.stats import fmt_ci

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
