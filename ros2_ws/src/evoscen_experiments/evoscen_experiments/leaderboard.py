"""The planner leaderboard (docs/experiments.md §4): every installed SUT in the default test, ranked.

``scripts/leaderboard.py`` parses the command line and calls :func:`main`: the SUTs (:func:`resolve_suts`),
the seed blocks (:func:`resolve_blocks`) and the reference mutants (:func:`resolve_mutant_refs`) checked,
one round per SUT and episode run on the campaign engine, then the ranked table (:func:`ranked_rows`) with each
SUT's rank range and letters, every term (:func:`term_rows`), every pair's verdict
(:mod:`evoscen_experiments.leaderboard_tiers`), the order per seed block with Kendall's τ
(:func:`block_orders`), the surrogate-safety table and the plot, written into ``--out`` and printed. The
score ranked by is the one ``evaluation.score_form`` selects (the comparative score D by default,
docs/evaluation.md §10); SUTs whose runs fail are listed as failed, not ranked.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from evoscen_contract.contract import EXIT_INTERRUPTED, EXIT_OK

from evoscen_experiments.timing import finish
from evoscen_sim.errors import InputError

from evoscen_experiments.experiments import distinct_names, positive_int, batch_option
from evoscen_experiments.leaderboard_tiers import DELTA, pair_tables, pairs_csv_header, range_text, tiers
from evoscen_experiments.sensitivity import SSM_RATES, score_of, ssm_label, ssm_rate, symbols
from evoscen_experiments.stats import fmt_ci, markdown_table, mean_ci

BLOCKS, BLOCK_SIZE, EPISODE_STEPS, FIRST_SEED = "2", "100", "300", "20000"
"""The defaults: 2 blocks of 100 episodes of 300 steps per SUT on seeds 20000..20199 (docs/experiments.md §4: the
built-ins and both example plug-ins, 1,200 runs, took 7 min 36 s on 2 cores; the budget is 20 minutes); two
blocks so that the order's agreement between disjoint seeds (Kendall τ) is measured."""
REFERENCE = "mobil"
MUTANT_REFS = "timid,frozen"
"""The reference mutants ranked beside the SUTs (docs/experiments.md §4 "References"): a planner that gives away
progress and one that never changes lanes by choice, both of ``--mutant-base``."""
TERMS = ("safety", "efficiency", "interaction")
WEIGHTED = {"D": ("P·i_s·S", "P·i_e·L", "P·i_i·X"), "I": ("w_s·I_s", "w_e·I_e", "w_i·I_i")}
"""The weighted terms of :data:`TERMS` as the tables write them (they sum to the score): D's safety, lane-change
time and interaction terms (docs/evaluation.md §10), or the method's weighted sub-scores (§1)."""
WEIGHTED_CSV = ("p_is_s", "p_ie_l", "p_ii_x")
METHOD_TERMS = (("I", "intelligence"), ("I_s", "safety"), ("I_e", "efficiency"), ("I_i", "interaction"))
"""The method's score and its sub-scores (the report's sections' ``score``; docs/evaluation.md §1)."""
COMPARATIVE_TERMS = (("D", ("score",)), ("S", ("safety", "score")), ("P", ("progress", "score")),
                     ("L", ("lane_change_time", "score")), ("X", ("interaction", "score")))
"""The comparative score and its terms (the report's ``comparative`` section; docs/evaluation.md §10)."""
TERM_NAMES = [n for n, _ in COMPARATIVE_TERMS] + [n for n, _ in METHOD_TERMS]


def installed_suts() -> list[str]:
    """Every SUT model installed, in registration order (built-ins, then plug-ins), without the mutant wrapper."""
    from evoscen_sim import model_registry as models
    from evoscen_sut.mutant import NAME as MUTANT

    models.discover()
    return [name for name in models.SUT_MODELS if name != MUTANT]


def resolve_suts(text: str, reference: str) -> list[str]:
    """The SUTs of ``--suts`` (InputError of one line: unknown, twice, the mutant wrapper, no reference)."""
    installed = installed_suts()
    suts = installed if text.strip() == "all" else distinct_names("--suts", text, "SUT model names")
    for name in suts:
        if name not in installed:
            raise InputError(f"--suts: {name!r} is no installed SUT model to rank: expected 'all' or names from "
                             f"{', '.join(installed)}")
    if reference not in suts:
        raise InputError(f"--reference {reference!r} is not among the SUTs ranked ({', '.join(suts)})")
    return suts


def resolve_blocks(args) -> list:
    """The seed blocks (:class:`evoscen_experiments.replication.SeedBlock`) of the parsed options (text values):
    ``--seed-blocks``, or ``--episodes`` (one block), or ``--blocks`` × ``--block-size`` from ``--first-seed``
    (InputError of one line on a bad value or a mix)."""
    from evoscen_experiments.replication import consecutive_blocks, parse_seed_blocks

    first = positive_int("--first-seed", args.first_seed, 0)
    if args.seed_blocks is not None:
        other = [f for f, v in (("--episodes", args.episodes), ("--blocks", args.blocks),
                                ("--block-size", args.block_size)) if v is not None]
        if other or args.first_seed != FIRST_SEED:
            raise InputError(f"--seed-blocks and {other[0] if other else '--first-seed'} together: the blocks "
                             f"name their seeds")
        return parse_seed_blocks(args.seed_blocks)
    if args.episodes is not None:
        if args.blocks is not None or args.block_size is not None:
            raise InputError(f"--episodes and {'--blocks' if args.blocks is not None else '--block-size'} together: "
                             f"--episodes is one block")
        return consecutive_blocks(first, 1, positive_int("--episodes", args.episodes))
    return consecutive_blocks(first, positive_int("--blocks", args.blocks or BLOCKS),
                              positive_int("--block-size", args.block_size or BLOCK_SIZE))


def resolve_mutant_refs(text: str, base: str, suts: list[str]) -> list[str]:
    """The reference mutants of ``--mutant-refs`` ('none': none); each must be in the library and apply to
    ``base``, which must be among ``suts`` (InputError of one line)."""
    from evoscen_sut.mutants import LIBRARY, mutants_for

    if text.strip() == "none":
        return []
    names = distinct_names("--mutant-refs", text, "mutant names")
    if base not in suts:
        raise InputError(f"--mutant-base {base!r} is not among the SUTs ranked ({', '.join(suts)})")
    for name in names:
        if name not in LIBRARY:
            raise InputError(f"--mutant-refs: unknown mutant {name!r}: expected 'none' or names from "
                             f"{', '.join(LIBRARY)}")
        if name not in mutants_for(base):
            raise InputError(f"--mutant-refs: {name!r} does not apply to --mutant-base {base!r} (docs/mutants.md)")
    return names


def ref_label(mutant: str, base: str) -> str:
    """The leaderboard's name of a reference mutant: ``timid(mobil)``."""
    return f"{mutant}({base})"


def term_values(report: dict) -> dict[str, float]:
    """Every term of both scores of one ``report.json`` dict (``nan`` where undefined or absent)."""
    out = {}
    comp = report.get("comparative") or {}
    for name, path in COMPARATIVE_TERMS:
        v = comp
        for k in path:
            v = (v or {}).get(k) if isinstance(v, dict) else None
        out[name] = math.nan if v is None else float(v)
    for name, section in METHOD_TERMS:
        v = (report.get(section) or {}).get("score")
        out[name] = math.nan if v is None else float(v)
    return out


def ranked(means: dict[str, float]) -> list[str]:
    """SUT names by mean score, highest first; ties (and nan, last) by name."""
    return sorted(means, key=lambda s: (math.isnan(means[s]), -means[s] if not math.isnan(means[s]) else 0.0, s))


def block_orders(values: dict[str, dict[int, float]], blocks: list, names: list[str]) -> tuple[list, list]:
    """Per block the mean score of each of ``names`` (SUT -> seed -> score) and its rank in that block, and
    Kendall's τ-b between every two blocks. Returns (per-block rows [block, sut, mean, rank], τ rows
    [block a, block b, τ, concordant, discordant, n])."""
    from evoscen_experiments.replication import kendall_tau, restrict

    means = []
    for b in blocks:
        m = {}
        for name in names:
            vals = [v for v in restrict(values[name], b).values() if not math.isnan(v)]
            m[name] = sum(vals) / len(vals) if vals else math.nan
        means.append(m)
    rows = []
    for b, m in zip(blocks, means):
        order = ranked(m)
        rows += [[b.label, name, m[name], order.index(name) + 1] for name in names]
    taus = []
    for i in range(len(blocks)):
        for j in range(i + 1, len(blocks)):
            tau, c, d, n = kendall_tau(means[i], means[j])
            taus.append([blocks[i].label, blocks[j].label, tau, c, d, n])
    return rows, taus


def term_rows(terms: dict[str, dict[int, dict[str, float]]], order: list[str]) -> tuple[list, list]:
    """Per SUT (in ``order``) every term of both scores (``terms``: SUT -> seed -> term -> value), mean ± 95 %
    interval over the episodes where it is defined, and that n. Returns Markdown rows and CSV rows."""
    md, rows = [], []
    for sut in order:
        cells, values = [], []
        for name in TERM_NAMES:
            vals = [t[name] for t in terms[sut].values() if not math.isnan(t[name])]
            mean, half = mean_ci(vals)
            cells.append(f"{fmt_ci(mean, half, 3)}" + ("" if len(vals) == len(terms[sut]) else f" (n {len(vals)})"))
            values += [mean, half, len(vals)]
        md.append([sut, *cells, str(len(terms[sut]))])
        rows.append([sut, *values])
    return md, rows


def _build(args):
    """The planners, the reference mutants' names, the rounds (one per SUT and episode), the seed blocks, the
    steps per episode and the workers of the parsed options."""
    from evoscen_experiments.experiments import Round, challenge_mode, config_loader
    from evoscen_sut.mutants import mutant_overrides

    blocks = resolve_blocks(args)
    steps = positive_int("--episode-steps", args.episode_steps)
    jobs = positive_int("--jobs", args.jobs)
    planners = resolve_suts(args.suts, args.reference)
    refs = resolve_mutant_refs(args.mutant_refs, args.mutant_base, planners)
    load = config_loader(args.config, challenge_mode(getattr(args, "challenge", None)))
    seeds = [s for b in blocks for s in b.seeds]
    common = {"steps": str(steps), "recording.enabled": "false"}
    rounds = [Round(sut, load({"sut.model": sut, "seed": str(seed), **common}))
              for sut in planners for seed in seeds]
    rounds += [Round(ref_label(m, args.mutant_base),
                     load({**mutant_overrides(args.mutant_base, m), "seed": str(seed), **common}))
               for m in refs for seed in seeds]
    return planners, [ref_label(m, args.mutant_base) for m in refs], rounds, blocks, steps, jobs


@dataclass
class Board:
    """A finished leaderboard's rounds and what is ranked: the SUTs that ran (``ok``), their reports and
    score per episode seed (D by default: ``sym``), its mean ± 95 % interval, the order, and the failed SUTs."""

    args: object
    planners: list
    ref_names: list
    rounds: list
    blocks: list
    steps: int
    results: dict
    failed: dict
    """SUT -> (failed episodes, first error)."""

    def __post_init__(self) -> None:
        self.suts = self.planners + self.ref_names
        self.episodes = sum(b.size for b in self.blocks)
        self.ok = [s for s in self.suts if s not in self.failed]
        self.reports = {s: {r.cfg.seed: self.results[r.key]["report"] for r in self.rounds if r.label == s}
                        for s in self.ok}
        self.intel = {s: {seed: score_of(rep, "intelligence") for seed, rep in self.reports[s].items()}
                      for s in self.ok}
        self.stats = {s: mean_ci([v for v in self.intel[s].values() if not math.isnan(v)]) for s in self.ok}
        self.order = ranked({s: self.stats[s][0] for s in self.ok})
        self.ref = self.args.reference if self.args.reference in self.ok else None
        first = next((rep for s in self.ok for rep in self.reports[s].values()), None)
        self.sym = symbols(first)["intelligence"] if first is not None else "D"
        """The ranked score's symbol: D (``evaluation.score_form: comparative``, the default) or the method's I."""
        self.pairs, self.ranges, self.letters = tiers(self.intel, self.order, self.blocks)
        """Every pair's verdict, each SUT's rank range and letters (:mod:`evoscen_experiments.leaderboard_tiers`)."""


def failed_suts(rounds: list, failures: dict[str, str]) -> dict[str, tuple[int, str]]:
    """SUT -> (failed episodes, first error) from the failed rounds' errors by key."""
    failed: dict[str, tuple[int, str]] = {}
    for rnd in rounds:
        if rnd.key in failures:
            count, first_error = failed.get(rnd.label, (0, failures[rnd.key]))
            failed[rnd.label] = (count + 1, first_error)
    return failed


def main(args, argv: list[str]) -> int:
    """The leaderboard of the parsed options (``scripts/leaderboard.py``; text values, checked here; ``argv``:
    the command line, quoted in ``leaderboard.md``): the rounds run (or read back), the tables written into
    ``args.out`` and printed. Returns the exit status; InputError (one line) on bad input, before anything is
    written."""
    from evoscen_experiments.experiments import run_rounds_with_bar, set_up

    started = time.monotonic()
    planners, ref_names, rounds, blocks, steps, jobs = set_up(args.out, lambda: _build(args))
    failures: dict[str, str] = {}
    results = run_rounds_with_bar(rounds, args.out, jobs=jobs, desc="leaderboard", failures=failures, batch=batch_option(args))
    if results is None:
        return EXIT_INTERRUPTED
    board = Board(args, planners, ref_names, rounds, blocks, steps, results, failed_suts(rounds, failures))
    table, ssm_table, plot_rows = ranked_tables(board)
    write_episodes(board)
    verdict, terms_table, pairs_text, tau_text = replication_tables(board)
    if plot_rows:
        plot(args.out / "leaderboard.png", plot_rows, args.reference if board.ref else None, board.sym)
    text = markdown_text(board, table, verdict, ssm_table, argv, time.monotonic() - started)
    (args.out / "leaderboard.md").write_text(text, encoding="utf-8")
    print(table, end="")
    print("\n" + terms_table, end="")
    resolved = [f"{p.a} > {p.b}" if p.verdict.verdict == "a_higher" else f"{p.b} > {p.a}" for p in board.pairs
                if p.verdict.verdict in ("a_higher", "b_higher")]
    print(f"\npairs: {pairs_text}" + (f"; resolved: {'; '.join(resolved)}" if resolved else ""))
    print(f"order between blocks: {tau_text}")
    if ssm_table:
        print("\n" + ssm_table, end="")
    for sut, (count, error) in board.failed.items():
        print(f"failed: {sut}: {count}/{board.episodes} episodes: {error}", file=sys.stderr)
    print(f"written: {args.out / 'leaderboard.md'}, leaderboard.csv, episodes.csv, terms.csv, pairs.csv, blocks.csv, "
          f"kendall.csv"
          + (", leaderboard.png" if plot_rows else ""))
    finish(args.out)  # the command's start-up and throughput (timing.json)
    return EXIT_OK


def _weighted(rep: dict, term: str) -> float:
    """A weighted term of the compared score (``evaluation.score_form``; nan where undefined)."""
    from evoscen_eval.scoring.metrics import compared_weighted

    value = compared_weighted(rep).get(term)
    return math.nan if value is None else float(value)


def _ci(values) -> tuple[float, float]:
    return mean_ci([v for v in values if not math.isnan(v)])


def _against_reference(board: Board, sut: str):
    """The paired difference of ``sut`` against the reference: None without a reference, the word for the
    reference itself, else a :class:`~evoscen_experiments.sensitivity.Paired`."""
    from evoscen_experiments.sensitivity import paired

    if board.ref is None:
        return None
    if sut == board.ref:
        return "reference"
    return paired(board.intel[sut], board.intel[board.ref])


def ranked_rows(board: Board) -> tuple[list, list, list, list]:
    """The ranked SUTs' rows, then the failed ones': Markdown rows and CSV rows of the leaderboard, the
    surrogate-safety rows and the plot's rows."""
    from evoscen_experiments.stats import difference_words

    rows, csv_rows, ssm_rows, plot_rows = [], [], [], []
    for rank, sut in enumerate(board.order, 1):
        reps = list(board.reports[sut].values())
        terms = [_ci(_weighted(x, t) for x in reps) for t in TERMS]
        col = _ci(float(x["safety"]["collisions"]) for x in reps)
        exp = _ci(float(x["safety"]["exposures"]) for x in reps)
        rates = [_ci(ssm_rate(x, side, m) for x in reps) for side, m in SSM_RATES]
        d = _against_reference(board, sut)
        if isinstance(d, str) or d is None:
            d_text, sig_text, d_csv, sig = ("reference" if d else "–"), "–", [math.nan, math.nan, 0], ""
        else:
            sig = d.n >= 2 and math.isfinite(d.half) and abs(d.mean) > d.half
            d_text = fmt_ci(d.mean, d.half)
            sig_text = difference_words(d.mean, d.half, d.n)
            d_csv, sig = [d.mean, d.half, d.n], int(sig)
        best, worst = board.ranges[sut]
        rows.append([str(rank), range_text(best, worst), board.letters[sut], sut, fmt_ci(*board.stats[sut]),
                     *(fmt_ci(*t) for t in terms), d_text, sig_text, fmt_ci(*col, 2), fmt_ci(*exp, 2), str(len(reps))])
        csv_rows.append([rank, best, worst, board.letters[sut], sut, "ok", *board.stats[sut],
                         *(v for t in terms for v in t), *d_csv, sig, *col, *exp, len(reps),
                         *(v for r in rates for v in r), ""])
        ssm_rows.append([str(rank), sut, *(fmt_ci(*r, 2) for r in rates), str(len(reps))])
        plot_rows.append((f"{sut} [{board.letters[sut]}]", board.stats[sut],
                          None if isinstance(d, str) or d is None else d))
    width = len(csv_header(board.args.reference))
    for sut in board.suts:
        if sut in board.failed:
            count, error = board.failed[sut]
            rows.append(["–", "–", "–", sut, f"failed ({count}/{board.episodes} episodes): {error}", *["–"] * 3, "–",
                         "–", "–", "–", "–"])
            csv_rows.append(["", "", "", "", sut, "failed", *[""] * (width - 7),
                             f"{count}/{board.episodes} episodes: {error}"])
    return rows, csv_rows, ssm_rows, plot_rows


def csv_header(reference: str) -> list[str]:
    """The columns of ``leaderboard.csv``."""
    return ["rank", "rank_best", "rank_worst", "letters", "sut", "status", "d_mean", "d_ci95",
            *(f"{t}_{s}" for t in WEIGHTED_CSV for s in ("mean", "ci95")),
            f"delta_d_vs_{reference}_mean", f"delta_d_vs_{reference}_ci95", "paired_n",
            "significant", "collisions_mean", "collisions_ci95", "exposures_mean", "exposures_ci95", "episodes",
            *(f"{side}_{m}_per_km_{s}" for side, m in SSM_RATES for s in ("mean", "ci95")), "error"]


def ranked_tables(board: Board) -> tuple[str, str, list]:
    """``leaderboard.csv`` written; the ranked table and the surrogate-safety table (Markdown; the latter empty
    when no SUT ran) and the plot's rows."""
    from evoscen_experiments.experiments import write_csv

    reference = board.args.reference
    rows, csv_rows, ssm_rows, plot_rows = ranked_rows(board)
    write_csv(board.args.out / "leaderboard.csv", csv_header(reference), csv_rows)
    d = board.sym
    weighted = WEIGHTED.get(d, WEIGHTED["D"])
    header = ["rank", "rank range", "letters", "SUT", f"{d} ± 95 %", *(f"{w} ({t})" for w, t in zip(weighted, (
                  "safety", "lane-change time" if d == "D" else "efficiency", "interaction"))),
              f"Δ{d} = SUT − {reference} (paired)", f"SUT vs {reference} (95 %)", "collisions / episode",
              "exposures / episode", "n"]
    first_report = next((board.results[r.key]["report"] for r in board.rounds if r.label in board.ok), None)
    ssm_table = markdown_table(["rank", "SUT", *(ssm_label(side, m, first_report) for side, m in SSM_RATES), "n"],
                               ssm_rows) if ssm_rows else ""
    return markdown_table(header, rows), ssm_table, plot_rows


def write_episodes(board: Board) -> None:
    """``episodes.csv``: every episode of every SUT that ran."""
    from evoscen_experiments.experiments import write_csv

    episode_rows = []
    for rnd in board.rounds:
        if rnd.label in board.failed:
            continue
        r = board.results[rnd.key]
        x = r["report"]
        episode_rows.append([rnd.label, r["seed"], r["steps"], score_of(x, "intelligence"),
                             *(_weighted(x, t) for t in TERMS), *(score_of(x, t) for t in TERMS),
                             x["safety"]["collisions"], x["safety"]["exposures"], x["efficiency"]["mean_speed_mps"],
                             r["wall_time_s"], *(ssm_rate(x, side, m) for side, m in SSM_RATES)])
    write_csv(board.args.out / "episodes.csv",
              ["sut", "seed", "steps", "d", *WEIGHTED_CSV, "s", "p", "x", "collisions",
               "exposures", "mean_speed_mps", "wall_time_s", *(f"ssm_{side}_{m}_per_km" for side, m in SSM_RATES)],
              episode_rows)


def replication_tables(board: Board) -> tuple[str, str, str, str]:
    """Every term, every pair's verdict and the order per block (docs/experiments.md §4): ``terms.csv``,
    ``pairs.csv``, ``blocks.csv``, ``kendall.csv`` written; returns their section of ``leaderboard.md``, the
    terms table, the pairs' summary and the agreement between blocks in words."""
    from evoscen_experiments.experiments import write_csv

    out, blocks = board.args.out, board.blocks
    terms = {s: {seed: term_values(rep) for seed, rep in board.reports[s].items()} for s in board.ok}
    t_md, t_rows = term_rows(terms, board.order)
    write_csv(out / "terms.csv", ["sut", *(f"{n}_{k}" for n in TERM_NAMES for k in ("mean", "ci95", "n"))], t_rows)
    p_head, p_md, p_rows, pairs_text = pair_tables(board.pairs, blocks, board.sym)
    write_csv(out / "pairs.csv", pairs_csv_header(blocks), p_rows)
    ranked_planners = [s for s in board.order if s in board.planners]
    b_rows, taus = block_orders(board.intel, blocks, ranked_planners)
    write_csv(out / "blocks.csv", ["block", "sut", "d_mean", "rank"], b_rows)
    write_csv(out / "kendall.csv", ["block_a", "block_b", "tau_b", "concordant", "discordant", "n"], taus)
    terms_table = markdown_table(["SUT", *TERM_NAMES, "episodes"], t_md)
    d = board.sym
    pairs_table = markdown_table(p_head, p_md)
    block_table = markdown_table(["SUT", *(f"block {b.label}: {d} (rank)" for b in blocks)],
                                 [[sut, *(f"{r[2]:.3f} ({r[3]})" for b in blocks for r in b_rows
                                          if r[0] == b.label and r[1] == sut)] for sut in ranked_planners])
    tau_text = ("; ".join(f"blocks {a} and {b}: τ = {t:.2f} ({c} concordant, {d} discordant pairs of {n} SUTs)"
                          for a, b, t, c, d, n in taus) if taus else
                "one block: no agreement between blocks measured (give --blocks 2 or more)")
    verdict = (f"## Every term\n\nThe comparative score D and its terms S, P, L, X (docs/evaluation.md §10) and the "
               f"method's I, I_s, I_e, I_i (§1), unweighted, mean ± 95 % interval over the episodes (n where a term "
               f"is undefined in some):\n\n{terms_table}\n## Pairs\n\nEvery pair, a ranked above b: Δ{d} = a − b "
               f"paired by episode over all blocks, 95 % interval (z = 1.96), n episodes; verdict a > b or a < b "
               f"where the interval excludes 0, a ≈ b inside ±{DELTA:g}, else unresolved, with the episodes needed "
               f"(80 % power at the observed mean and sd)"
               + (", and the verdict in each seed block" if len(blocks) > 1 else "")
               + f": {pairs_text}.\n\n{pairs_table}\n"
               f"## Does the order replicate?\n\nThe planners' mean {d} and rank per seed block; Kendall's "
               f"τ-b between the blocks' orders (1: the same order, −1: reversed): {tau_text}.\n\n{block_table}\n")
    return verdict, terms_table, pairs_text, tau_text


def markdown_text(board: Board, table: str, verdict: str, ssm_table: str, argv: list[str], wall: float) -> str:
    """``leaderboard.md``: the set-up in words, the ranked table, the replication sections, the surrogate-safety
    table, the plot and the command that made it (``wall``: the command's measured wall time so far, s)."""
    args, results, rounds = board.args, board.results, board.rounds
    cfg0 = rounds[0].cfg
    run_time = sum(results[r.key]["wall_time_s"] for r in rounds if r.key in results)
    simulated = sum(results[r.key]["report"]["run"]["duration_s"] for r in rounds if r.key in results)
    d = board.sym
    score = "D, the comparative score" if d == "D" else "I, the method's intelligence"
    ref_note = (f"Δ{d} = SUT − {args.reference}: the SUT's {d} minus {args.reference}'s on the same episodes, "
                "mean ± 95 % interval of the per-episode difference; 'significantly higher' ('lower') when the whole "
                "interval lies above (below) 0, else 'no significant difference'. The three weighted terms sum to "
                f"{d}."
                if board.ref else f"The reference {args.reference} failed: no paired differences.")
    refs_text = (f" References: {', '.join(board.ref_names)}, mutants of {args.mutant_base} (docs/mutants.md), ranked "
                 f"beside the planners and left out of the agreement between blocks." if board.ref_names else "")
    blocks_text = ", ".join(b.label for b in board.blocks)
    return (f"# Planner leaderboard\n\n{len(board.suts)} SUTs x {board.episodes} episodes (seed blocks {blocks_text}) "
            f"x {board.steps} steps, after a warm-up of {cfg0.traffic.warmup_s:g} s, among {cfg0.bvs.count} BVs "
            f"({cfg0.bvs.driver}), challenge.mode {cfg0.challenge.mode}; weights "
            f"{cfg0.evaluation.weight_safety:g}/{cfg0.evaluation.weight_efficiency:g}/"
            f"{cfg0.evaluation.weight_interaction:g}; mean ± 95 % interval over the episodes; ranked by mean "
            f"{score}.{refs_text} {ref_note} Rank range: the best and worst rank the resolved pairs (## Pairs) "
            f"leave a SUT; SUTs sharing a letter are not told apart (compact letter display, Piepho 2004). "
            f"{simulated:,.0f} s simulated (scored states of all episodes); this command's wall time "
            f"{wall:,.0f} s (runs read back from an earlier command take none), the runs' own {run_time:,.0f} s "
            f"summed over workers.\n\n{table}\n{verdict}\n"
            + (f"Surrogate safety per SUT-km (docs/evaluation.md §9; front: the SUT behind its leader, rear: its "
               f"follower behind it), mean ± 95 % interval over the episodes:\n\n{ssm_table}\n" if ssm_table else "")
            + "![leaderboard](leaderboard.png)\n\nMade by:\n\n    python scripts/leaderboard.py "
            + " ".join(argv) + "\n")


def plot(path: Path, rows, reference: str | None, d: str = "D") -> None:
    """Per SUT (ranked, top first, its letters in brackets): the score (symbol ``d``: D by default) with its 95 %
    interval; beside it the paired difference against the reference with its interval (green/red: significantly
    higher/lower)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = 2 if reference else 1
    fig, axes = plt.subplots(1, panels, figsize=(5.0 * panels, 0.45 * len(rows) + 1.6), sharey=True, squeeze=False)
    ys = range(len(rows))
    ax = axes[0][0]
    for y, (_sut, (mean, half), _d) in zip(ys, rows):
        h = 0.0 if math.isnan(half) else half
        ax.errorbar([mean], [y], xerr=[[h], [h]], fmt="o", color="tab:blue", capsize=3)
    ax.set_yticks(list(ys), [r[0] for r in rows])
    ax.invert_yaxis()
    ax.set_xlabel(f"{d} (mean, 95 % CI)")
    ax.set_title("Leaderboard", fontsize=10)
    if reference:
        ax = axes[0][1]
        for y, (_sut, _s, diff) in zip(ys, rows):
            if diff is None:
                ax.plot([0.0], [y], "D", color="k")
                continue
            h = 0.0 if math.isnan(diff.half) else diff.half
            sig = diff.n >= 2 and math.isfinite(diff.half) and abs(diff.mean) > diff.half
            color = ("tab:green" if diff.mean > 0 else "tab:red") if sig else "tab:gray"
            ax.errorbar([diff.mean], [y], xerr=[[h], [h]], fmt="o", color=color, capsize=3)
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_xlabel(f"Δ{d} = SUT − {reference}, paired by episode (95 % CI)")
        ax.set_title(f"Against {reference}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
