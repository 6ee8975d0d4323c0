"""The planner leaderboard with sequential pair verdicts (``scripts/leaderboard.py --sequential``,
docs/experiments.md §4).

Every pair (A, B) of the SUTs ranked (planners and reference mutants) is a sequential comparison of D paired by
episode (:func:`evoscen_experiments.sequential.verdict`, the sensitivity experiment's design,
:class:`~evoscen_experiments.sensitivity_sequential.Plan`): the episodes run in looks of ``--round-size`` seeds
from ``--first-seed``, the same seeds for every SUT; a SUT runs a look's seeds while at least one of its pairs is
still open (:func:`needing`); after the look each open pair is judged on its A − B so far (:func:`judge_open`) and
closed at its verdict (A higher, B higher, equivalent) or unresolved at ``--budget``. The looks stop when no pair
is open. The resolved pairs give each SUT its rank range and letters
(:func:`evoscen_experiments.leaderboard_tiers.tiers_of`); SUTs are ranked by mean D over the episodes each ran.
The rounds run on the experiment's engine, saved under ``OUT/runs/``: a rerun reads them back and reaches the same
verdicts. :func:`run_looks` is the loop, its run function injectable; :func:`main` the door's function.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from evoscen_contract.contract import EXIT_INTERRUPTED, EXIT_OK

from evoscen_experiments.timing import finish

from evoscen_experiments.leaderboard_tiers import WORDS, PairResult, episodes_needed, range_text, tiers_of
from evoscen_experiments.sensitivity import score_of
from evoscen_experiments.sensitivity_sequential import Plan, plan_of
from evoscen_experiments.sequential import Verdict
from evoscen_experiments.stats import fmt_ci, markdown_table, mean_ci

Pair = tuple[str, str]
PAIRS_CSV = ["a", "b", "verdict", "delta_d_mean", "delta_d_low", "delta_d_high", "episodes", "looks",
             "episodes_needed"]
SUTS_CSV = ["rank", "rank_best", "rank_worst", "letters", "sut", "d_mean", "d_ci95", "episodes"]
FLIP = {"a_higher": "b_higher", "b_higher": "a_higher"}
XY = {"a_higher": "x > y", "b_higher": "x < y", "equivalent": "x ≈ y", "unresolved": "unresolved", "": ""}
"""A verdict on x − y in the replication table's words."""
TURNED = {"a_higher": "b_higher", "b_higher": "a_higher"}
"""A verdict on x − y as the verdict on y − x."""


def all_pairs(names: Sequence[str]) -> list[Pair]:
    """Every pair of ``names``, in their order."""
    return [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]


def judge_open(plan: Plan, verdicts: Mapping[Pair, Verdict], d: Mapping[str, Mapping[int, float]],
               n: int) -> dict[Pair, Verdict]:
    """The verdicts after the look at ``n`` episodes: each pair still ``continue`` judged on A − B of D over the
    seeds ``first_seed`` .. ``first_seed + n − 1`` both ran (``d``: SUT -> seed -> D; finite differences only);
    the closed pairs keep theirs."""
    seeds = range(plan.first_seed, plan.first_seed + n)
    out = dict(verdicts)
    for (a, b), v in verdicts.items():
        if v.verdict != "continue":
            continue
        va, vb = d.get(a, {}), d.get(b, {})
        diffs = [va[s] - vb[s] for s in seeds if s in va and s in vb]
        out[(a, b)] = plan.judge([x for x in diffs if math.isfinite(x)])
    return out


def needing(names: Sequence[str], verdicts: Mapping[Pair, Verdict]) -> list[str]:
    """The SUTs of ``names`` (in order) in at least one pair still open (``continue``): they run the next look."""
    busy = {s for pair, v in verdicts.items() if v.verdict == "continue" for s in pair}
    return [s for s in names if s in busy]


def look_rounds(plan: Plan, names: Sequence[str], k: int, load: Callable, overrides: Mapping[str, dict]) -> list:
    """The rounds of look ``k`` (0-based): each of ``names`` on the seeds after look k − 1 up to look k
    (``overrides``: SUT -> its configuration overrides)."""
    from evoscen_experiments.experiments import Round

    lo = plan.looks[k - 1] if k else 0
    common = {"steps": str(plan.steps), "recording.enabled": "false"}
    return [Round(s, load({**overrides[s], "seed": str(seed), **common})) for s in names
            for seed in range(plan.first_seed + lo, plan.first_seed + plan.looks[k])]


def run_looks(plan: Plan, names: Sequence[str], overrides: Mapping[str, dict], load: Callable,
              run: Callable[[list], dict | None]) -> tuple[dict, dict, list, dict] | None:
    """Run the looks: before each, the SUTs with an open pair get its seeds (:func:`look_rounds`); ``run(rounds)``
    gives their results by key (the saved ones read back; a failed round's key absent) or None when interrupted.
    A SUT with a failed episode leaves the ranking: its pairs are dropped and it runs no more (the fixed
    leaderboard's rule; :func:`main` lists it). Returns the pairs' verdicts, D per SUT and seed (the SUTs ranked),
    every round run and the results; None when interrupted."""
    d: dict[str, dict[int, float]] = {s: {} for s in names}
    verdicts = {p: plan.judge([]) for p in all_pairs(names)}
    rounds, results, failed = [], {}, set()
    for k, n in enumerate(plan.looks):
        todo = needing(names, verdicts)
        if not todo:
            break
        look = look_rounds(plan, todo, k, load, overrides)
        got = run(look)
        if got is None:
            return None
        for rnd in look:
            if rnd.key not in got:
                failed.add(rnd.label)
                continue
            results[rnd.key] = got[rnd.key]
            d[rnd.label][rnd.cfg.seed] = score_of(got[rnd.key]["report"], "intelligence")
        rounds += look
        if failed:
            verdicts = {p: v for p, v in verdicts.items() if not failed & set(p)}
            d = {s: v for s, v in d.items() if s not in failed}
        verdicts = judge_open(plan, verdicts, d, n)
    return verdicts, d, rounds, results


def oriented(verdicts: Mapping[Pair, Verdict], order: Sequence[str]) -> list[PairResult]:
    """The pairs with a ranked above b (the verdict, A − B and its interval turned round where needed; a pair
    left ``continue`` is unresolved), in the order of ``order``."""
    rank = {s: i for i, s in enumerate(order)}
    out = []
    for (a, b), v in verdicts.items():
        v = dataclasses.replace(v, verdict="unresolved") if v.verdict == "continue" else v
        if rank[a] > rank[b]:
            a, b = b, a
            v = dataclasses.replace(v, verdict=FLIP.get(v.verdict, v.verdict), mean=-v.mean, low=-v.high,
                                    high=-v.low)
        out.append(PairResult(a, b, v, None))
    return sorted(out, key=lambda p: (rank[p.a], rank[p.b]))


def with_needed(pairs: Sequence[PairResult], d: Mapping[str, Mapping[int, float]]) -> list[PairResult]:
    """``pairs`` with, for each unresolved one, the paired episodes a fixed design would need for its observed
    ΔD (:func:`~evoscen_experiments.leaderboard_tiers.episodes_needed`) over the pair's episodes: the first
    ``episodes`` seeds both SUTs ran."""
    out = []
    for p in pairs:
        needed = None
        if p.verdict.verdict == "unresolved":
            da, db = d.get(p.a, {}), d.get(p.b, {})
            seeds = sorted(set(da) & set(db))[: p.verdict.episodes]
            needed = episodes_needed([x for x in (da[s] - db[s] for s in seeds) if math.isfinite(x)])
        out.append(dataclasses.replace(p, needed=needed))
    return out


def tables(d: Mapping[str, Mapping[int, float]], verdicts: Mapping[Pair, Verdict]) -> tuple[list, list, list, list]:
    """The SUTs ranked by mean D over the episodes each ran, with rank range and letters, and the pairs (a ranked
    above b): Markdown rows and CSV rows of each."""
    from evoscen_experiments.leaderboard import ranked

    stats = {s: mean_ci([v for v in d[s].values() if math.isfinite(v)]) for s in d}
    order = ranked({s: stats[s][0] for s in d})
    pairs = with_needed(oriented(verdicts, order), d)
    ranges, letters = tiers_of(order, pairs)
    suts_md, suts_csv = [], []
    for rank, s in enumerate(order, 1):
        best, worst = ranges[s]
        suts_md.append([str(rank), range_text(best, worst), letters[s], s, fmt_ci(*stats[s]), str(len(d[s]))])
        suts_csv.append([rank, best, worst, letters[s], s, *stats[s], len(d[s])])
    pairs_md, pairs_csv = [], []
    for p in pairs:
        v = p.verdict
        pairs_md.append([p.a, p.b, WORDS[v.verdict], f"{v.mean:+.4f} [{v.low:+.4f}, {v.high:+.4f}]", str(v.episodes),
                         str(v.looks), "–" if p.needed is None else f"{p.needed:,}"])
        pairs_csv.append([p.a, p.b, v.verdict, v.mean, v.low, v.high, v.episodes, v.looks,
                          "" if p.needed is None else p.needed])
    return suts_md, suts_csv, pairs_md, pairs_csv


def _names(args) -> tuple[list[str], dict[str, dict], int]:
    """The SUTs ranked (planners, then reference mutants), their configuration overrides and the workers."""
    from evoscen_experiments.experiments import positive_int
    from evoscen_experiments.leaderboard import ref_label, resolve_mutant_refs, resolve_suts
    from evoscen_sut.mutants import mutant_overrides

    jobs = positive_int("--jobs", args.jobs)
    planners = resolve_suts(args.suts, args.reference)
    refs = resolve_mutant_refs(args.mutant_refs, args.mutant_base, planners)
    overrides = {s: {"sut.model": s} for s in planners}
    overrides.update({ref_label(m, args.mutant_base): mutant_overrides(args.mutant_base, m) for m in refs})
    return list(overrides), overrides, jobs


def main(args, argv: list[str]) -> int:
    """The leaderboard of the parsed options (``scripts/leaderboard.py``): with ``--sequential`` the sequential
    pair verdicts (looks run or read back, ``pairs.csv``, ``leaderboard.csv`` and ``leaderboard.md`` written
    into ``args.out``, the tables printed), else :func:`evoscen_experiments.leaderboard.main`. InputError (one
    line) on bad input, before anything is written."""
    from evoscen_experiments import leaderboard
    from evoscen_experiments.experiments import batch_option, challenge_mode, config_loader, run_rounds_with_bar, set_up

    plan = plan_of(args, {"--episodes": args.episodes, "--blocks": args.blocks, "--block-size": args.block_size},
                   leaderboard.EPISODE_STEPS, leaderboard.FIRST_SEED)
    if plan is None:
        return leaderboard.main(args, argv)
    started = time.monotonic()
    names, overrides, jobs = set_up(args.out, lambda: _names(args))
    load = config_loader(args.config, challenge_mode(getattr(args, "challenge", None)))
    looks, fails = [0], {}

    def run(rounds: list) -> dict | None:
        looks[0] += 1
        return run_rounds_with_bar(rounds, args.out, jobs=jobs, desc=f"leaderboard, look {looks[0]}", failures=fails, batch=batch_option(args))

    parts = []
    for part in plan.parts:
        done = run_looks(part, names, overrides, load, run)
        if done is None:
            return EXIT_INTERRUPTED
        parts.append((part, *done[:3]))
    failed = leaderboard.failed_suts([r for _, _, _, rounds in parts for r in rounds], fails)
    text, printed = write_blocks(args.out, plan, parts, argv, time.monotonic() - started, failed)
    print(printed, end="")
    for sut, (count, error) in failed.items():
        print(f"failed: {sut}: {count} episode(s): {error}", file=sys.stderr)
    print(f"written: {args.out / 'leaderboard.md'}, leaderboard.csv, pairs.csv, episodes.csv"
          + (", replication.csv" if len(parts) > 1 else ""))
    finish(args.out)  # the command's start-up and throughput (timing.json)
    return EXIT_OK


def write_tables(out: Path, plan: Plan, d: Mapping[str, Mapping[int, float]], verdicts: Mapping[Pair, Verdict],
                 rounds: list, argv: Sequence[str], wall: float, failed: Mapping | None = None) -> tuple[str, str]:
    """The tables of one design (:func:`write_blocks`)."""
    return write_blocks(out, plan, [(plan, verdicts, d, rounds)], argv, wall, failed)


def replication(names: Sequence[str], labels: Sequence[str], verdicts: Sequence[Mapping[Pair, Verdict]]
                ) -> tuple[list, list, list]:
    """Every pair (x, y) of ``names``, in their order, with its verdict on x − y in every block side by side and
    whether they contradict (x above y in one block, below in another;
    :func:`evoscen_experiments.replication.side_by_side`): ``replication.csv``'s rows, Markdown rows and the
    contradicting pairs. ``labels``: the blocks', one per entry of ``verdicts``."""
    from evoscen_experiments.replication import side_by_side

    if len(labels) != len(verdicts):
        raise ValueError(f"replication: {len(labels)} block labels for {len(verdicts)} blocks of verdicts")
    words = []
    for block in verdicts:  # each pair in both orientations: a block's pairs follow its own SUTs' order
        w = {}
        for (a, b), v in block.items():
            word = "unresolved" if v.verdict == "continue" else v.verdict
            w[(a, b)], w[(b, a)] = word, TURNED.get(word, word)
        words.append(w)
    rows, md, clashes = [], [], []
    for pair, per, clash in side_by_side(all_pairs(names), words, "a_higher", "b_higher"):
        if clash:
            clashes.append(pair)
        rows.append([*pair, *per, "yes" if clash else ""])
        md.append([*pair, *(XY[w] for w in per), "**yes**" if clash else ""])
    return rows, md, clashes


def write_blocks(out: Path, plan: Plan, parts: Sequence[tuple], argv: Sequence[str], wall: float,
                 failed: Mapping | None = None) -> tuple[str, str]:
    """``leaderboard.csv``, ``pairs.csv`` and ``episodes.csv`` (a ``block`` column each), ``leaderboard.md`` (a
    section per block, the failed SUTs after) and, with two or more blocks, ``replication.csv``
    (:func:`replication`); ``parts``: (design, verdicts, D per SUT and seed, rounds) per block; ``failed``: SUT ->
    (failed episodes, first error), not ranked. Returns the Markdown text and the printed tables."""
    from evoscen_experiments.experiments import write_csv

    several = len(parts) > 1
    sections, suts_rows, pairs_rows, runs = [], [], [], 0
    for part, verdicts, d, rounds in parts:
        suts_md, suts_csv, pairs_md, pairs_csv = tables(d, verdicts)
        suts_rows += [[*r, part.label] for r in suts_csv]
        pairs_rows += [[*r, part.label] for r in pairs_csv]
        runs += len(rounds)
        sections.append((f"### Seeds {part.label}\n\n" if several else "")
                        + markdown_table(["rank", "rank range", "letters", "SUT", "D ± 95 %", "episodes"], suts_md)
                        + "\n" + markdown_table(["a", "b", "verdict", "ΔD = a − b [RCI]", "episodes", "looks",
                                                 "episodes needed"], pairs_md))
    write_csv(out / "leaderboard.csv", [*SUTS_CSV, "block"], suts_rows)
    write_csv(out / "pairs.csv", [*PAIRS_CSV, "block"], pairs_rows)
    write_csv(out / "episodes.csv", ["sut", "seed", "d", "block"],
              [[s, seed, v, part.label] for part, _, d, _ in parts for s in d for seed, v in sorted(d[s].items())])
    printed = "\n".join(sections)
    if failed:
        printed += "\nFailed, not ranked: " + "; ".join(f"{s} ({c} episode(s): {e})" for s, (c, e) in failed.items()) + "\n"
    labels = [part.label for part, *_ in parts]
    if several:
        names = list(dict.fromkeys(s for _, _, d, _ in parts for s in d))  # every block's SUTs, first seen first
        rep_rows, rep_md, clashes = replication(names, labels, [v for _, v, _, _ in parts])
        write_csv(out / "replication.csv", ["x", "y", *(f"verdict_block_{x.replace('–', '_')}" for x in labels),
                                            "contradiction"], rep_rows)
        printed += ("\n### Replication\n\n" + markdown_table(["x", "y", *labels, "contradiction"], rep_md)
                    + "\nContradictions (x above y in one block, below in another): "
                    + (", ".join(f"{x}/{y}" for x, y in clashes) or "none") + ".\n")
    cfg0 = next((r[0].cfg for _, _, _, r in parts if r), None)
    setting = (f", {cfg0.bvs.count} BVs ({cfg0.bvs.driver}), challenge.mode {cfg0.challenge.mode}"
               if cfg0 is not None else "")
    seeds = (f"seed blocks {', '.join(labels)}, each a design of its own from its first seed" if several
             else f"seeds {plan.first_seed} on")
    n_suts = len(parts[0][2]) if parts else 0
    text = (f"# Planner leaderboard: sequential verdicts\n\n{n_suts} SUTs{setting}; episodes of {plan.steps} steps "
            f"on {seeds}, the same for every SUT. Every pair a, b (a ranked above b): D of a "
            f"minus D of b paired by episode, looked at every {plan.round_size} episodes up to {plan.budget}; a "
            f"SUT runs a look while one of its pairs is open, a pair stops at its verdict: a > b (the repeated "
            f"confidence interval, RCI, above 0), a < b (below 0), a ≈ b (inside ±{plan.delta:g}) or unresolved "
            f"at the budget (with the paired episodes a fixed design would need for its observed ΔD at 80 % "
            f"power); {plan.spending} spending, each verdict wrong with probability at most {plan.alpha:g} over "
            f"all looks (docs/sensitivity.md \"Sequential verdicts\"). SUTs ranked by mean D ± 95 % interval "
            f"over the episodes each ran; rank range: the best and worst rank the resolved pairs leave a SUT; "
            f"SUTs sharing a letter are not told apart (Piepho 2004). {runs:,} runs; this command's wall "
            f"time {wall:,.0f} s.\n\n{printed}\nMade by:\n\n    python scripts/leaderboard.py {' '.join(argv)}\n")
    (out / "leaderboard.md").write_text(text, encoding="utf-8")
    return text, printed
