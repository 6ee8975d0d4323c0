#!/usr/bin/env python3
"""The complexity experiment (docs/method.md §6.2): one SUT in the evolving scenario and in rule-based baselines.

    python scripts/experiment_complexity.py [--out DIR] [--config FILE] [--sut stackelberg]
                                           [--scenarios evolving,nilsson,mobil] [--rounds N] [--steps N]
                                           [--first-seed S] [--mix C:M:K] [--jobs N]

Scenarios: ``evolving`` — the BVs as the scenario configuration drives them (``bvs.driver``;
the shipped default); ``nilsson`` / ``mobil`` (any BV driver name) — every BV driven by that
model. The SUT (default Stackelberg) is the same everywhere. Each scenario runs ``--rounds``
rounds (seeds ``--first-seed`` …) of ``--steps`` steps in-process, on ``--jobs`` Ray workers (the campaign engine);
finished rounds are saved and never recomputed. Per scenario: LC, AD and E per
``evaluation.window_steps`` (100) states, averaged over windows and rounds (± 95 % interval
over rounds), and the complexity score C of those averages (± the interval of the rounds'
own C). Writes ``complexity.csv``, ``complexity.md``, ``rounds.csv`` and ``complexity.png``
into ``--out`` and prints the table. Exit status: 0 done, 2 bad input, 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("experiment_complexity.py", __doc__)  # compares scenarios by complexity C: no SUT score
    cli.add_out(ap, "runs/experiment_complexity")
    cli.add_config(ap)
    ap.add_argument("--sut", default="stackelberg", help="SUT model (default stackelberg)")
    ap.add_argument("--scenarios", default="evolving,nilsson,mobil",
                    help="comma-separated: evolving (the config's BV driver) and/or BV driver names")
    ap.add_argument("--rounds", default="20", help="rounds per scenario (default 20)")
    cli.add_steps(ap, 10000)
    ap.add_argument("--first-seed", default="0", help="seed of the first round (default 0)")
    ap.add_argument("--mix", default=None, help="BV policy mix of the evolving scenario (default: the config's)")
    cli.add_jobs(ap)
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import complexity_experiment

    return cli.run(lambda: complexity_experiment.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
