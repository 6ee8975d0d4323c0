#!/usr/bin/env python3
"""The intelligence experiment (docs/method.md §6.1): each SUT among 20 BVs, several seeds.

    python scripts/experiment_intelligence.py [--out DIR] [--config FILE] [--suts nilsson,mobil,stackelberg]
                                             [--seeds N] [--first-seed S] [--steps N] [--mix C:M:K]
                                             [--bvs N] [--jobs N]

Every SUT runs the same seeds (same BV layout and draws) for ``--steps`` steps in-process; the
rounds run on ``--jobs`` Ray workers (the campaign engine) and are saved as they finish, so an interrupted experiment
continues where it stopped (a finished round is not recomputed). Writes into ``--out``:
``intelligence.csv`` / ``intelligence.md`` (per SUT: the weighted safety, efficiency and
interaction terms and the method's intelligence I, mean ± 95 % interval over seeds, with the
collisions and exposures, and the comparative score D (docs/evaluation.md §10); below it every pair of
SUTs compared on the same seeds: the mean per-seed difference of the score ``evaluation.score_form``
selects (D by default, the method's I with ``method``) with its 95 % interval, and of the method's
efficiency term; then per SUT
its surrogate-safety rates per SUT-km, docs/evaluation.md), ``surrogate_safety.csv``, ``paired.csv``,
``paired_efficiency.csv``, ``rounds.csv`` (every round, with its rates), ``ttc.png`` and ``speed.png``
(the SUTs' distributions overlaid, pooled over seeds); prints the table. Exit status: 0 done,
2 bad input, 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli
from evoscen.experiment_runs import intelligence_parser


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    return intelligence_parser(__doc__).parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import intelligence_experiment

    return cli.run(lambda: intelligence_experiment.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
