#!/usr/bin/env python3
"""Does the test keep testing? The traffic around the SUT over whole runs (docs/method.md §1).

    python scripts/experiment_traffic.py [--sut mobil] [--seeds 6] [--first-seed 60000] [--steps 3000]
                                         [--config FILE] [--set KEY=VALUE ...] [--compare-steps N] [--json OUT]

Runs the SUT on ``--seeds`` seeds in-process (no bag) and prints, from each run's report and
states:

* BVs within ±100 m of the SUT (any lane) per 30-s window, the mean over seeds of each window
  (the report's ``traffic`` figure), the lowest window mean, their mean, and the lowest window of any
  single run (docs/bv-profiles.md: every window mean >= 6, the lowest single-run window >= 4);
* SUT jumps: a step in which the SUT moved other than by driving (its arc length changed by
  more than it can drive in a step once the window's shift is undone, or it came to a lane
  that was neither its lane nor its target lane) — the test counts 0;
* where the SUT's exposures fall: the share that starts in the first 10 % of the run;
* BV–BV collisions per BV-hour; window entries and shifts per run.

``--compare-steps N`` also runs every seed for N steps and prints the paired difference of
intelligence (N steps − ``--steps``), mean ± 95 % interval over seeds (length independence,
docs/evaluation.md). ``--set KEY=VALUE`` overrides a scenario key (e.g. ``traffic.mode=loop``).
Exit status: 0 done, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("experiment_traffic.py", __doc__)  # measures the traffic of one SUT's runs: ranks nothing
    ap.add_argument("--sut", default="mobil", help="SUT model (default mobil)")
    cli.add_seeds(ap, count=6, first=60000)
    cli.add_steps(ap, 3000)
    cli.add_config(ap)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a scenario key")
    ap.add_argument("--compare-steps", default=None, metavar="N", help="also run N steps per seed, paired")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures as JSON here")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import traffic_experiment

    return cli.run(lambda: traffic_experiment.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
