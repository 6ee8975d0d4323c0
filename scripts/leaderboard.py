#!/usr/bin/env python3
"""The planner leaderboard: every installed SUT in the default test, ranked by D, the comparative score.

    python scripts/leaderboard.py [--out DIR] [--config FILE] [--suts all|NAME,...] [--reference mobil]
                                  [--blocks 2] [--block-size 100] [--first-seed 20000] | [--episodes N]
                                  | [--seed-blocks A:B,C:D] [--episode-steps 300]
                                  [--mutant-refs timid,frozen|none] [--mutant-base mobil] [--jobs N]
    python scripts/leaderboard.py --sequential [--budget 2000] [--round-size 100] [--delta 0.005]
                                  [--spending pocock|obrien_fleming] [--first-seed 20000] ...

Every SUT model installed — the built-ins and the ``evoscen.sut`` plug-ins (docs/plugins.md);
not the sensitivity experiment's ``mutant`` wrapper, which is a defect of another model — runs
the default test (docs/sensitivity.md, the episodes design): ``--episodes`` short in-process
runs of ``--episode-steps`` steps among the configuration's BVs (the shipped default: learned
social drivers), each episode its own seed from ``--first-seed`` on. Every SUT gets the same
seeds (the same initial traffic after the warm-up and the same random streams) and the same
SUT steps, so the SUTs are compared paired, episode by episode. The score is the one
``evaluation.score_form`` selects (docs/evaluation.md §10): the comparative score D by default, its
weighted terms P·i_s·S (safety), P·i_e·L (lane-change time) and P·i_i·X (interaction), which sum
to D; with ``method`` the method's I and its weighted terms w_s·I_s, w_e·I_e, w_i·I_i. Per SUT:
its rank range and letters (below), D and its three weighted terms, mean ± 95 % Student-t interval
over the episodes, n, the collisions and exposures per episode, the surrogate-safety rates per
SUT-km (docs/evaluation.md §9), and the paired difference of D against
``--reference`` (SUT − reference, mean ± 95 % interval over the shared episodes; significant
when the interval excludes 0). SUTs are ranked by mean D (ties: by name). A SUT whose
runs fail is listed as failed with the first error, not ranked; the others are still ranked.

Every pair of SUTs gets a verdict on ΔD paired by episode (95 % interval, z = 1.96): a > b or a < b
when the interval excludes 0, a ≈ b inside ±0.005, else unresolved with the episodes it would need.
Rank range: the best and worst rank the resolved pairs leave a SUT; letters: SUTs that share one are
not told apart (compact letter display, Piepho 2004).

The episodes come in seed blocks (default 2 × 100 from ``--first-seed``; ``--episodes N``: one block;
``--seed-blocks``: blocks named by their seeds). Beside the ranked table: every term of the comparative
score (D, S, P, L, X) and of the method's (I, I_s, I_e, I_i), unweighted; every pair's verdict over all
episodes and in each block side by side (a contradiction, a > b in one block and a < b in another,
flagged and counted); the planners' order in each block and Kendall's τ-b between blocks
(:func:`evoscen_experiments.replication.kendall_tau`). ``--mutant-refs`` mutants of ``--mutant-base``
(default ``timid`` and ``frozen`` of MOBIL) are ranked beside the planners as references and left out
of τ (docs/experiments.md §4).

Runs go on ``--jobs`` Ray workers (the campaign engine, one run per worker process) and are saved
as they finish: an interrupted leaderboard continues where it stopped. Writes into ``--out``:
``leaderboard.md`` (the ranked table, the terms, the pairs, the orders per block, the surrogate-safety
table, the command), ``leaderboard.csv`` (one row per SUT, ranked, failed SUTs last), ``episodes.csv``
(every episode of every SUT), ``terms.csv``, ``pairs.csv``, ``blocks.csv``, ``kendall.csv`` and
``leaderboard.png`` (D with its interval and the paired difference against the
reference, per SUT); prints the tables. Exit status: 0 done (failed SUTs included), 2 bad
input, 130 interrupted.

``--sequential`` replaces the seed blocks by sequential pair verdicts (docs/sensitivity.md "Sequential
verdicts"): the episodes run in looks of ``--round-size`` seeds from ``--first-seed``, the same seeds for
every SUT; after each look every open pair is judged on ΔD so far and closed at a > b, a < b or a ≈ b
(±``--delta``), else unresolved at ``--budget`` episodes; a SUT runs a look while one of its pairs is open.
Writes ``leaderboard.md`` (the SUTs ranked by mean D over the episodes each ran, with rank range and
letters; every pair's verdict, interval, episodes and looks), ``leaderboard.csv`` and ``pairs.csv``
(sut_a, sut_b, verdict, mean, low, high, episodes, looks); prints both tables.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli
from evoscen.experiment_runs import add_sequential
from evoscen_experiments.leaderboard import BLOCK_SIZE, BLOCKS, EPISODE_STEPS, FIRST_SEED, MUTANT_REFS, REFERENCE


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("leaderboard.py", __doc__, ranks_by="D")
    cli.add_out(ap, "runs/leaderboard")
    cli.add_config(ap)
    ap.add_argument("--challenge", default="nade", help="challenge.mode of every run, over the config's: nade "
                    "(default: the challenge scenario, docs/challenges.md), naturalistic or none")
    ap.add_argument("--suts", default="all", help="'all' (every installed SUT model) or comma-separated SUT models")
    ap.add_argument("--reference", default=REFERENCE,
                    help=f"the SUT whose D the others are compared with, paired by episode (ΔD; default {REFERENCE})")
    ap.add_argument("--episodes", help="episodes (seeds) per SUT in one block (default: --blocks blocks of "
                                       "--block-size)")
    ap.add_argument("--blocks", help=f"seed blocks, one after the other from --first-seed (default {BLOCKS})")
    ap.add_argument("--block-size", help=f"episodes per block (default {BLOCK_SIZE})")
    ap.add_argument("--seed-blocks", help="explicit seed blocks 'A:B,C:D' (seeds A..B and C..D, both included, "
                                          "disjoint); replaces --first-seed, --blocks, --block-size, --episodes")
    ap.add_argument("--episode-steps", default=EPISODE_STEPS, help=f"steps per episode (default {EPISODE_STEPS})")
    ap.add_argument("--first-seed", default=FIRST_SEED, help=f"first episode's seed (default {FIRST_SEED})")
    ap.add_argument("--mutant-refs", default=MUTANT_REFS,
                    help=f"'none' or comma-separated mutants of --mutant-base ranked beside the SUTs as references "
                         f"(default {MUTANT_REFS})")
    ap.add_argument("--mutant-base", default=REFERENCE,
                    help=f"the SUT whose mutants are the references (default {REFERENCE}; one of the SUTs ranked)")
    add_sequential(ap, "sequential pair verdicts: looks of --round-size paired episodes (seeds from --first-seed "
                       "on, or one design per --seed-blocks block), each pair of SUTs stopped at its verdict (a > b, "
                       "a < b, a ≈ b on D) or unresolved at --budget; replaces --episodes, --blocks, --block-size")
    cli.add_jobs(ap)
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import leaderboard_sequential

    command = list(argv if argv is not None else sys.argv[1:])  # quoted in leaderboard.md
    return cli.run(lambda: leaderboard_sequential.main(parse_args(argv), command))


if __name__ == "__main__":
    sys.exit(main())
