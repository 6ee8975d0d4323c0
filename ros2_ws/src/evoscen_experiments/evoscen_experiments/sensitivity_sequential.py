"""The sensitivity experiment's sequential design (``--sequential``, docs/sensitivity.md "Sequential verdicts").

Every (scenario, base, mutant) comparison runs paired episodes in rounds of ``--round-size`` seeds (S, S+1, …
from ``--first-seed``, in order) and is looked at after each round (:func:`evoscen_experiments.sequential.verdict`
on intact − mutant of D): a comparison with its verdict gets no further seeds; one still ``continue`` gets the
next round's, up to ``--budget``. The intact episodes of a seed are shared by all mutants of its base and run
while any of them still needs the seed. The rounds run on the experiment's engine
(:func:`evoscen_experiments.experiments.run_rounds_with_bar`), which saves every run under ``OUT/runs/``: a rerun
into the same ``--out`` reads the saved runs back, reaches the same verdicts at the same looks and computes only
what is missing. :func:`run_looks` is the loop, its run function injectable; :func:`main` the experiment's door.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

from evoscen_contract.contract import EXIT_INTERRUPTED, EXIT_OK

from evoscen_experiments.timing import finish
from evoscen_sim.errors import InputError

from evoscen_experiments.sensitivity import PROFILES, score_of
from evoscen_experiments.sensitivity_tables import INTACT, role
from evoscen_experiments.sequential import SPENDING, Verdict, looks_of, verdict

BUDGET, ROUND_SIZE, DELTA, SPENDING_DEFAULT = "2000", "100", "0.005", "pocock"
"""The defaults: at most 2,000 paired episodes per comparison, looks every 100 episodes ([choice]: the first look
is the fixed episodes design's 100, 20 looks in all, and the standard deviation of ≥ 100 differences makes the
normal-scale boundaries of :mod:`~evoscen_experiments.sequential` close to Student-t's), margin δ = 0.005 of D,
Pocock spending ([choice], docs/sensitivity.md "Sequential verdicts": a design's cost is the episodes its
comparisons run before their verdicts, and O'Brien–Fleming's early boundaries (40, 6.2, 5.1, 4.4 standard errors at
the first four of 20 looks; Pocock's 2.87 to 2.53) keep even large differences open for several looks;
``obrien_fleming`` stays selectable)."""
WORDS = {"a_higher": "worse", "b_higher": "better", "equivalent": "equivalent", "unresolved": "unresolved",
         "continue": "unresolved", "failed": "failed"}
"""A verdict on intact − mutant in the user's words about the mutant (``a_higher``: the intact SUT scores higher,
so the mutant is *worse*)."""
VERDICTS_CSV = ["scenario", "bv_driver", "base", "mutant", "class", "role", "verdict", "delta_d_mean",
                "delta_d_low", "delta_d_high", "episodes", "looks", "budget", "episodes_needed", "block"]
COUNTS_CSV = ["scenario", "bv_driver", "base", "worse", "better", "equivalent", "unresolved", "defects",
              "profiles", "not_applicable", "runs", "block", "failed"]
CONFLICTS = ("--design long", "--compare-designs", "--episodes", "--seeds", "--steps", "--long-first-seed",
             "--blocks", "--block-size")


@dataclass(frozen=True)
class Plan:
    """A sequential design: looks every ``round_size`` paired episodes of ``steps`` steps up to ``budget``, seeds
    ``first_seed`` on, margin ``delta``, ``spending`` shape, error rate ``alpha`` over all looks."""

    round_size: int
    budget: int
    delta: float
    spending: str
    steps: int
    first_seed: int
    alpha: float = 0.05
    blocks: tuple = ()
    """``--seed-blocks``: the :class:`~evoscen_experiments.replication.SeedBlock` s, each a design of its own
    (:attr:`parts`); empty: one design from ``first_seed``."""

    @property
    def parts(self) -> list[Plan]:
        """One design per seed block: from its first seed, its budget at most the block's size; without blocks,
        this design."""
        if not self.blocks:
            return [self]
        return [dataclasses.replace(self, first_seed=b.first, budget=min(self.budget, b.size), blocks=())
                for b in self.blocks]

    @property
    def label(self) -> str:
        """The seeds this design may use, ``first–last``."""
        return f"{self.first_seed}–{self.first_seed + self.budget - 1}"

    @property
    def looks(self) -> tuple[int, ...]:
        """The episodes at each look (:func:`~evoscen_experiments.sequential.looks_of`)."""
        return looks_of(self.round_size, self.budget)

    def judge(self, diffs: Sequence[float]) -> Verdict:
        """The verdict on the paired differences so far (episode order)."""
        return verdict(diffs, round_size=self.round_size, budget=self.budget, delta=self.delta, alpha=self.alpha,
                       spending=self.spending)


def resolve_plan(args, episode_steps: str = "300") -> Plan | None:
    """The sequential design of the parsed options (``episode_steps``: ``--episode-steps``' default), None without
    ``--sequential``; InputError (one line) on a bad value or on another design's flags with it, or its flags
    without it."""
    given = {"--design long": args.design == "long", "--compare-designs": args.compare_designs,
             "--episodes": args.episodes, "--seeds": args.seeds, "--steps": args.steps,
             "--long-first-seed": args.long_first_seed, "--blocks": args.blocks, "--block-size": args.block_size}
    return plan_of(args, {f: given[f] for f in CONFLICTS}, episode_steps)


def plan_of(args, conflicts: dict[str, object], episode_steps: str = "300", first_seed: str = "0") -> Plan | None:
    """The sequential design of parsed options with ``--sequential``, ``--budget``, ``--round-size``, ``--delta``,
    ``--spending``, ``--episode-steps`` and ``--first-seed`` (the sensitivity experiment's and the leaderboard's),
    None without ``--sequential``; with ``--seed-blocks`` one design per block (:attr:`Plan.parts`, the
    replication of the verdicts). ``conflicts``: the fixed designs' flags (in the order to name them) -> their
    values, None or False where not given. InputError (one line) on a bad value, on a conflicting flag with
    ``--sequential``, or on the sequential flags without it (``first_seed``: ``--first-seed``'s default)."""
    from evoscen_experiments.experiments import positive_int

    own = [f for f, v in (("--budget", args.budget), ("--round-size", args.round_size), ("--delta", args.delta),
                          ("--spending", args.spending)) if v is not None]
    if not getattr(args, "sequential", False):
        if own:
            raise InputError(f"{own[0]} applies with --sequential only")
        return None
    bad = [f for f, v in conflicts.items() if v not in (None, False)]
    if bad:
        raise InputError(f"--sequential and {bad[0]} together: the sequential design runs rounds of --round-size "
                         f"episodes from --first-seed up to --budget")
    budget = positive_int("--budget", args.budget or BUDGET, 2)
    size = positive_int("--round-size", args.round_size or ROUND_SIZE, 2)
    if size > budget:
        raise InputError(f"--round-size {size} exceeds --budget {budget}")
    try:
        delta = float(args.delta or DELTA)
    except ValueError:
        delta = math.nan
    if not (delta > 0 and math.isfinite(delta)):
        raise InputError(f"--delta = {args.delta!r}: expected a number > 0")
    spending = args.spending or SPENDING_DEFAULT
    if spending not in SPENDING:
        raise InputError(f"--spending {spending!r}: expected one of {', '.join(SPENDING)}")
    steps = positive_int("--episode-steps", args.episode_steps or episode_steps)
    first = positive_int("--first-seed", args.first_seed, 0)
    return Plan(size, budget, delta, spending, steps, first, blocks=_blocks(args, size, first_seed))


def _blocks(args, round_size: int, first_seed: str) -> tuple:
    """The ``--seed-blocks`` of a sequential design (empty without); InputError (one line) with ``--first-seed``
    or a block smaller than a round."""
    from evoscen_experiments.replication import parse_seed_blocks

    text = getattr(args, "seed_blocks", None)
    if text is None:
        return ()
    if args.first_seed not in (None, first_seed):
        raise InputError("--seed-blocks and --first-seed together: the blocks name their seeds")
    blocks = parse_seed_blocks(text)
    for b in blocks:
        if b.size < round_size:
            raise InputError(f"--seed-blocks: block {b.label} holds {b.size} seeds, fewer than --round-size "
                             f"{round_size}")
    return tuple(blocks)


Comparison = tuple[str, str, str]
"""(scenario, base, mutant)."""


def comparisons(bases: Sequence[str], scenarios: Sequence[str], mutants: Sequence[str]) -> list[Comparison]:
    """Every applicable (scenario, base, mutant), in that order (:func:`~evoscen_experiments.replication.applicable_split`)."""
    from evoscen_experiments.replication import applicable_split

    return [(s, b, m) for s in scenarios for b in bases for m in applicable_split(b, mutants)[0]]


def look_rounds(plan: Plan, open_: Sequence[Comparison], k: int, load: Callable) -> tuple[list, dict]:
    """The rounds of look ``k`` (0-based) for the comparisons still open: the seeds after look k − 1 up to look
    k, intact once per (scenario, base) with an open mutant, each open mutant; and their key -> (design,
    scenario, base, variant)."""
    from evoscen_experiments.experiments import Round
    from evoscen_sut.mutants import mutant_overrides

    lo = plan.looks[k - 1] if k else 0
    seeds = range(plan.first_seed + lo, plan.first_seed + plan.looks[k])
    variants: dict[tuple[str, str, str], dict] = {}
    for scenario, base, mutant in open_:
        variants.setdefault((scenario, base, INTACT), {"sut.model": base})
        variants[(scenario, base, mutant)] = mutant_overrides(base, mutant)
    rounds, meta = [], {}
    for (scenario, base, variant), sut in variants.items():
        for seed in seeds:
            overrides = {**sut, "seed": str(seed), "steps": str(plan.steps), "recording.enabled": "false"}
            if scenario != "evolving":
                overrides["bvs.driver"] = scenario
            rnd = Round(f"{scenario}--{base}--{variant}", load(overrides))
            rounds.append(rnd)
            meta[rnd.key] = ("sequential", scenario, base, variant)
    return rounds, meta


def verdicts_of(plan: Plan, comps: Sequence[Comparison], d: dict, n: int) -> dict[Comparison, Verdict]:
    """Each comparison's verdict on its first ``n`` episodes (``d``: (scenario, base, variant) -> seed -> D)."""
    seeds = range(plan.first_seed, plan.first_seed + n)
    out = {}
    for scenario, base, m in comps:
        intact, mutant = d.get((scenario, base, INTACT), {}), d.get((scenario, base, m), {})
        out[(scenario, base, m)] = plan.judge([intact[s] - mutant[s] for s in seeds if s in intact and s in mutant])
    return out


def scores_into(d: dict, rounds: Sequence, results: dict, meta: dict) -> dict:
    """``d`` ((scenario, base, variant) -> seed -> D) with the D of every round of ``rounds`` that has a result
    (the rounds' ``meta``: (design, scenario, base, variant)); returns ``d``."""
    for rnd in rounds:
        if rnd.key in results:
            d.setdefault(meta[rnd.key][1:], {})[rnd.cfg.seed] = score_of(results[rnd.key]["report"], "intelligence")
    return d


def needed_of(plan: Plan, comp: Comparison, v: Verdict, d: dict) -> int | None:
    """For a comparison left unresolved, the paired episodes a fixed design would need to resolve a true ΔD equal to
    the one observed over its ``v.episodes`` (:func:`evoscen_experiments.leaderboard_tiers.episodes_needed`: 80 %
    power, two-sided 5 %; the sequential boundaries ask a few per cent more); None for a resolved one. ``d``: D per
    (scenario, base, variant) and seed (:func:`scores_into`)."""
    from evoscen_experiments.leaderboard_tiers import episodes_needed

    if WORDS[v.verdict] != "unresolved":
        return None
    scenario, base, mutant = comp
    intact, mutated = d.get((scenario, base, INTACT), {}), d.get(comp, {})
    seeds = range(plan.first_seed, plan.first_seed + v.episodes)
    diffs = [intact[s] - mutated[s] for s in seeds if s in intact and s in mutated]
    return episodes_needed([x for x in diffs if math.isfinite(x)])


def run_looks(plan: Plan, comps: Sequence[Comparison], load: Callable,
              run: Callable[[list], dict | None]) -> tuple[dict, list, dict, dict] | None:
    """Run the looks: before each, the comparisons still ``continue`` get its seeds (:func:`look_rounds`),
    ``run(rounds)`` gives their results by key (the saved ones read back; a failed round's key absent) or None
    when interrupted. A comparison whose mutant, or whose base's intact SUT, failed an episode ends ``failed``; a
    profile's (:data:`~evoscen_experiments.sensitivity.PROFILES`) ends after the first look, unresolved if open.
    Returns the verdicts, every round that ran, the results and the rounds' meta (the failed ones' too); None
    when interrupted."""
    d: dict[tuple[str, str, str], dict[int, float]] = {}
    all_rounds, results, meta = [], {}, {}
    verdicts = verdicts_of(plan, comps, d, 0)
    for k in range(len(plan.looks)):
        # [choice] a profile (reported, never counted) is looked at once: no budget spent on it after the first look
        open_ = [c for c in comps if verdicts[c].verdict == "continue" and not (k and c[2] in PROFILES)]
        if not open_:
            break
        rounds, look_meta = look_rounds(plan, open_, k, load)
        got = run(rounds)
        if got is None:
            return None
        failed = {look_meta[r.key][1:] for r in rounds if r.key not in got}
        scores_into(d, rounds, got, look_meta)
        results.update((r.key, got[r.key]) for r in rounds if r.key in got)
        all_rounds += [r for r in rounds if r.key in got]
        meta.update(look_meta)
        new = verdicts_of(plan, open_, d, plan.looks[k])
        for c in open_:
            if c in failed or (c[0], c[1], INTACT) in failed:
                new[c] = dataclasses.replace(new[c], verdict="failed")
        verdicts.update(new)
    return verdicts, all_rounds, results, meta


def main(args, plan: Plan, names: Callable[[], tuple]) -> int:
    """The sequential design of the parsed options (``names()``: their bases, scenarios, mutants and workers,
    checked): looks run (or read back), then ``verdicts.csv``, ``verdict_counts.csv``, ``rounds.csv`` and
    ``sensitivity.md`` in ``args.out``, the table printed."""
    from evoscen_experiments.experiments import batch_option, challenge_mode, config_loader, run_rounds_with_bar, set_up

    bases, scenarios, mutants, jobs = set_up(args.out, names)
    comps = comparisons(bases, scenarios, mutants)
    if not comps:
        raise InputError("--sequential: no mutant applies to the bases given")
    load = config_loader(args.config, challenge_mode(getattr(args, "challenge", None)))
    looks, fails = [0], {}

    def run(rounds: list) -> dict | None:
        looks[0] += 1
        return run_rounds_with_bar(rounds, args.out, jobs=jobs, desc=f"sensitivity, look {looks[0]}", failures=fails, batch=batch_option(args))

    parts = []
    for part in plan.parts:
        done = run_looks(part, comps, load, run)
        if done is None:
            return EXIT_INTERRUPTED
        parts.append((part, *done))
    table = write_blocks(args.out, plan, bases, scenarios, mutants, parts)
    print(table, end="")
    for part, _, _, _, meta in parts:
        for key, error in fails.items():
            if key in meta:
                print(f"failed: {'/'.join(meta[key][1:])} (seeds {part.label}): {error}", file=sys.stderr)
    print(f"written: {args.out / 'sensitivity.md'}, verdicts.csv, verdict_counts.csv, rounds.csv"
          + (", replication.csv" if len(parts) > 1 else ""))
    finish(args.out)  # the command's start-up and throughput (timing.json)
    return EXIT_OK


def write_tables(out: Path, plan: Plan, bases: Sequence[str], scenarios: Sequence[str], mutants: Sequence[str],
                 verdicts: dict, rounds: list, results: dict, meta: dict) -> str:
    """The tables of one design (:func:`write_blocks`)."""
    return write_blocks(out, plan, bases, scenarios, mutants, [(plan, verdicts, rounds, results, meta)])


def _block_rows(part: Plan, bases: Sequence[str], scenarios: Sequence[str], mutants: Sequence[str], verdicts: dict,
                rounds: list, results: dict, meta: dict) -> tuple[list, list, list, list, dict]:
    """One block's rows: ``verdicts.csv``'s, the verdicts' Markdown, ``verdict_counts.csv``'s, the counts'
    Markdown, and the verdict word per comparison."""
    from evoscen_experiments.replication import applicable_split
    from evoscen_sut.mutants import LIBRARY

    drivers = {meta[r.key][1]: r.cfg.bvs.driver for r in rounds}
    d = scores_into({}, rounds, results, meta)  # D per variant and seed, once per block
    rows, md, counts, md_counts, words = [], [], [], [], {}
    for scenario in scenarios:
        for base in bases:
            applicable, not_applicable = applicable_split(base, mutants)
            for m in applicable:
                v = verdicts[(scenario, base, m)]
                word = words[(scenario, base, m)] = WORDS[v.verdict]
                needed = needed_of(part, (scenario, base, m), v, d)
                rows.append([scenario, drivers.get(scenario, ""), base, m, LIBRARY[m].klass, role(m), word, v.mean,
                             v.low, v.high, v.episodes, v.looks, part.budget, "" if needed is None else needed,
                             part.label])
                md.append([part.label, scenario, base, m if m not in PROFILES else f"{m} (profile)", word,
                           f"{v.mean:+.4f} [{v.low:+.4f}, {v.high:+.4f}]", str(v.episodes), str(v.looks),
                           "–" if needed is None else f"{needed:,}"])
            defects = [m for m in applicable if m not in PROFILES]
            tally = {w: sum(words[(scenario, base, m)] == w for m in defects)
                     for w in ("worse", "better", "equivalent", "unresolved", "failed")}
            runs = sum(1 for r in rounds if meta[r.key][1:3] == (scenario, base))
            counts.append([scenario, drivers.get(scenario, ""), base, *list(tally.values())[:4], len(defects),
                           len(applicable) - len(defects), len(not_applicable), runs, part.label, tally["failed"]])
            md_counts.append([part.label, scenario, base, f"{tally['worse']}/{len(defects)}", str(tally["better"]),
                              str(tally["equivalent"]), str(tally["unresolved"]), f"{runs:,}"])
    return rows, md, counts, md_counts, words


def replication_rows(words: Sequence[dict]) -> tuple[list, list, list]:
    """Per comparison its verdict in every block side by side and whether they contradict (worse in one block,
    better in another; :func:`evoscen_experiments.replication.side_by_side`): ``replication.csv``'s rows, Markdown
    rows, and the contradicting comparisons."""
    from evoscen_experiments.replication import side_by_side

    rows, md, contradictions = [], [], []
    for comp, per, clash in side_by_side(list(words[0]), words, "worse", "better"):
        if clash:
            contradictions.append(comp)
        rows.append([*comp, role(comp[2]), *per, "yes" if clash else ""])
        md.append([*comp, *per, "**yes**" if clash else ""])
    return rows, md, contradictions


def write_blocks(out: Path, plan: Plan, bases: Sequence[str], scenarios: Sequence[str], mutants: Sequence[str],
                 parts: Sequence[tuple]) -> str:
    """``verdicts.csv`` (per block and comparison), ``verdict_counts.csv`` (per block, scenario and base: worse /
    applicable defects), ``rounds.csv``, ``sensitivity.md`` and, with two or more blocks, ``replication.csv``
    (:func:`replication_rows`); ``parts``: (design, verdicts, rounds, results, meta) per block. Returns the
    Markdown tables."""
    from evoscen_experiments.experiments import write_csv
    from evoscen_experiments.sensitivity_tables import ROUNDS_CSV, round_rows
    from evoscen_experiments.stats import markdown_table

    several = len(parts) > 1
    rows, md, counts, md_counts, words, rounds, results, meta = [], [], [], [], [], [], {}, {}
    for part, p_verdicts, p_rounds, p_results, p_meta in parts:
        r, m, c, mc, w = _block_rows(part, bases, scenarios, mutants, p_verdicts, p_rounds, p_results, p_meta)
        rows += r
        md += m
        counts += c
        md_counts += mc
        words.append(w)
        rounds += p_rounds
        results.update(p_results)
        meta.update(p_meta)
    cut = 0 if several else 1  # one block: no block column in the Markdown
    write_csv(out / "verdicts.csv", VERDICTS_CSV, rows)
    write_csv(out / "verdict_counts.csv", COUNTS_CSV, counts)
    write_csv(out / "rounds.csv", ROUNDS_CSV, round_rows(SimpleNamespace(name="sequential"), rounds, results, meta))
    table = (markdown_table(["block", "scenario", "SUT", "mutant", "mutant vs intact", "ΔD intact − mutant [RCI]",
                             "episodes", "looks", "episodes needed"][cut:], [x[cut:] for x in md])
             + "\n" + markdown_table(["block", "scenario", "SUT", "worse / applicable defects", "better",
                                      "equivalent", "unresolved", "runs"][cut:], [x[cut:] for x in md_counts]))
    labels = [part.label for part, *_ in parts]
    if several:
        rep_rows, rep_md, clashes = replication_rows(words)
        write_csv(out / "replication.csv", ["scenario", "base", "mutant", "role",
                                            *(f"verdict_block_{x.replace('–', '_')}" for x in labels),
                                            "contradiction"], rep_rows)
        table += ("\n" + markdown_table(["scenario", "SUT", "mutant", *labels, "contradiction"], rep_md)
                  + f"\nContradictions (worse in one block, better in another): "
                    f"{', '.join('/'.join(c) for c in clashes) or 'none'}.\n")
    seeds = (f"seed blocks {', '.join(labels)}, each a design of its own from its first seed"
             if several else f"seeds {plan.first_seed} on")
    text = (f"# Sensitivity experiment: sequential verdicts\n\n## Sequential verdicts\n\nPer (base, mutant): D of "
            f"the intact SUT minus D of the mutant, paired by episode ({seeds}, in order, "
            f"{plan.steps} steps each), looked at every {plan.round_size} episodes up to {plan.budget} "
            f"(docs/sensitivity.md \"Sequential verdicts\"); a comparison stops at its verdict: **worse** (the "
            f"repeated confidence interval, RCI, of ΔD lies above 0: the mutant scores lower), **better** (below "
            f"0), **equivalent** (inside ±{plan.delta:g}) or **unresolved** at the budget (with the paired episodes a "
            f"fixed design would need for its observed ΔD at 80 % power); {plan.spending} "
            f"spending, each verdict wrong with probability at most {plan.alpha:g} over all looks. Profiles ("
            f"{', '.join(PROFILES)}) are reported, not counted. Runs: intact and mutant episodes run, an intact "
            f"episode shared by the mutants of its base; {len(rounds):,} in all.\n\n{table}")
    (out / "sensitivity.md").write_text(text, encoding="utf-8")
    return table
