#!/usr/bin/env python3
"""The sensitivity experiment (SUT mutation analysis): does each scenario tell a SUT from its mutants?

    python scripts/experiment_sensitivity.py [--out DIR] [--config FILE] [--base mobil]
                                            [--mutants all|NAME,...] [--scenarios evolving,level0,nilsson,mobil]
                                            [--design episodes|long] [--episodes 100] [--episode-steps 300]
                                            [--seeds 10] [--steps 3000] [--first-seed S] [--jobs N]
                                            [--blocks K] [--block-size N] [--seed-blocks A:B,C:D]
    python scripts/experiment_sensitivity.py --compare-designs [--first-seed S] [--long-first-seed S] ...
    python scripts/experiment_sensitivity.py --sequential [--budget 2000] [--round-size 100] [--delta 0.005]
                                            [--spending pocock|obrien_fleming] [--episode-steps 300]
                                            [--first-seed S | --seed-blocks A:B,C:D] ...

For every base SUT model (``--base``) and every scenario (``evolving``: the configuration's BVs; a BV
driver name: every BV driven by it), the intact model and each mutant that applies to it
(docs/mutants.md) run on the same seeds, in one of two test designs (docs/sensitivity.md): ``episodes``
(``--episodes`` runs of ``--episode-steps``) or ``long`` (``--seeds`` runs of ``--steps``); without
``--design`` the design whose flags are given, else episodes. Per mutant and scenario: the paired
difference intact − mutant of every score with its 95 % interval, *detected* when the interval of D
(the comparative score) lies above zero, the seeds needed; per scenario the mutation score; with seed blocks
(``--blocks``/``--block-size`` or ``--seed-blocks``) all of it per block too. Rounds run on ``--jobs``
Ray workers and are saved as they finish (an interrupted experiment continues). Writes
``sensitivity.md``, ``sensitivity.csv``, ``mutation_scores.csv``, ``blocks.csv``, ``not_applicable.csv``,
``speeds.csv``, ``rounds.csv`` and ``sensitivity.png`` into ``--out``; ``--compare-designs`` runs both
designs at equal SUT steps into ``--out/episodes`` and ``--out/long`` and compares them in
``designs.md``, ``designs.csv`` and ``designs_mutants.csv``; ``--sequential`` runs rounds of paired episodes
until each (base, mutant) has its verdict (worse, better, equivalent, or unresolved at the budget) into
``verdicts.csv``, ``verdict_counts.csv``, ``rounds.csv`` and ``sensitivity.md``; with ``--seed-blocks`` one
such design per block (its budget at most the block's seeds) and ``replication.csv``: every verdict per block
side by side, contradictions (worse in one, better in another) flagged. ``frozen`` is a profile,
not a defect: reported, not counted in detection. Exit status: 0 done, 2 bad input, 130
interrupted.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli
from evoscen.experiment_runs import sensitivity_parser


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    return sensitivity_parser(__doc__).parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import sensitivity_experiment

    return cli.run(lambda: sensitivity_experiment.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
