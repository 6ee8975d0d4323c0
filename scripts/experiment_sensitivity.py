#!/usr/bin/env python3
"""The sensitivity experiment (SUT mutation analysis): does each scenario tell a SUT from its mutants?

    python scripts/experiment_sensitivity.py [--out DIR] [--config FILE] [--base mobil]
                                            [--mutants all|NAME,...] [--scenarios evolving,level0,nilsson,mobil]
                                            [--design episodes|long] [--episodes 100] [--episode-steps 300]
                                            [--seeds 10] [--steps 3000] [--first-seed S] [--jobs N]
                                            [--blocks K] [--block-size N] [--seed-blocks A:B,C:D]
    python scripts/experiment_sensitivity.py --compare-designs [--first-seed S] [--long-first-seed S] ...

For every base SUT model (``--base``) and every scenario (``evolving``: the configuration's BVs; a BV
driver name: every BV driven by it), the intact model and each mutant that applies to it
(docs/mutants.md) run on the same seeds, in one of two test designs (docs/sensitivity.md): ``episodes``
(``--episodes`` runs of ``--episode-steps``) or ``long`` (``--seeds`` runs of ``--steps``); without
``--design`` the design whose flags are given, else episodes. Per mutant and scenario: the paired
difference intact − mutant of every score with its 95 % interval, *detected* when the intelligence
interval lies above zero, the seeds needed; per scenario the mutation score; with seed blocks
(``--blocks``/``--block-size`` or ``--seed-blocks``) all of it per block too. Rounds run on ``--jobs``
Ray workers and are saved as they finish (an interrupted experiment continues). Writes
``sensitivity.md``, ``sensitivity.csv``, ``mutation_scores.csv``, ``blocks.csv``, ``not_applicable.csv``,
``speeds.csv``, ``rounds.csv`` and ``sensitivity.png`` into ``--out``; ``--compare-designs`` runs both
designs at equal SUT steps into ``--out/episodes`` and ``--out/long`` and compares them in
``designs.md``, ``designs.csv`` and ``designs_mutants.csv``. Exit status: 0 done, 2 bad input, 130
interrupted.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli
from evoscen_experiments.sensitivity_experiment import DEFAULT_DESIGN, EPISODE_STEPS, EPISODES, SEEDS, STEPS


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("experiment_sensitivity.py", __doc__, ranks_by="D")
    cli.add_out(ap, "runs/experiment_sensitivity")
    cli.add_config(ap)
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
    cli.add_jobs(ap)
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import sensitivity_experiment

    return cli.run(lambda: sensitivity_experiment.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
