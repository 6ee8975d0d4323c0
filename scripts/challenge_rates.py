#!/usr/bin/env python3
"""One SUT's naturalistic rates per SUT-km from challenge runs, weighted back, beside a reference block.

    python scripts/challenge_rates.py [--sut mobil] [--mode nade] [--episodes 200] [--first-seed S]
                                      [--reference-mode naturalistic] [--reference-episodes 2000]
                                      [--reference-first-seed S2] [--episode-steps 300] [--config FILE]
                                      [--jobs 2] [--out DIR]

Runs ``--episodes`` episodes of the SUT under ``challenge.mode: --mode`` and ``--reference-episodes``
under ``--reference-mode`` on disjoint seed blocks, and prints per rate (SUT exposures, SUT collisions,
front TTC episodes, per SUT-km) the ratio estimate Σ w·count / Σ w·km of each set (w: the run's
likelihood ratio p/q, docs/challenges.md) with its 95 % interval, and their difference: whether the
challenge runs, weighted back, give the naturalistic rates. Writes ``rates.md`` and ``rates.csv`` into
``--out``; rounds are saved and resumed as in every experiment. Exit status: 0, 2 bad input,
130 interrupted.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.one_line_errors(cli.parser("challenge_rates.py", __doc__))
    ap.add_argument("--sut", default="mobil", help="the SUT model (default mobil)")
    ap.add_argument("--mode", default="nade", help="challenge.mode of the challenge set (default nade)")
    ap.add_argument("--episodes", default="200", help="episodes of the challenge set (default 200)")
    ap.add_argument("--first-seed", default="0", help="its first seed (default 0)")
    ap.add_argument("--reference-mode", default="naturalistic",
                    help="challenge.mode of the reference set (default naturalistic)")
    ap.add_argument("--reference-episodes", default="2000", help="episodes of the reference set (default 2000)")
    ap.add_argument("--reference-first-seed", default="1000000", help="its first seed (default 1000000)")
    ap.add_argument("--episode-steps", default="300", help="steps per episode (default 300)")
    cli.add_config(ap)
    ap.add_argument("--jobs", default="2", help="parallel workers (default 2)")
    cli.add_out(ap, "runs/challenge_rates")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import challenge_rates

    return cli.run(lambda: challenge_rates.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
