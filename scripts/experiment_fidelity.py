#!/usr/bin/env python3
"""Fidelity experiment (docs/method.md §5.3, §6.3): our runs' BVs against naturalistic HighD traffic.

    python scripts/experiment_fidelity.py --highd DIR [--recordings 01,02] --bags RUN [RUN ...]
        [--out DIR] [--overwrite] [--leader-range M] [--min-speed MPS] [--max-ttc S]
        [--include-sut] [--bandwidth scott|silverman|FACTOR] [--grid-1d N] [--grid-2d N]

HighD may not be redistributed, so evoscen ships none: obtain it from
https://www.highd-dataset.com and point ``--highd`` at the directory holding its
``NN_recordingMeta.csv``, ``NN_tracksMeta.csv`` and ``NN_tracks.csv`` (``--recordings``
picks some; default all). Each RUN is a bag (directory or ``.mcap``) or a run directory of
``run_scenario.py`` (its ``bag/``). Both sources go through the same behaviour extraction;
the four distributions — (DHW, speed), (THW, speed), TTC of mandatory lane changes, speed of
voluntary ones — are compared as KDEs on a common grid by the Jensen–Shannon divergence
(log base 2) and the similarity S = (1 - JS)·100 %.

Writes ``OUT/fidelity.csv``, ``OUT/fidelity.md`` and the four plots ``OUT/*.png`` (default
``runs/fidelity``) and prints the table. Exit status: 0 done, 2 bad input (one line
``error: ...``; also without ``--highd``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("experiment_fidelity.py", __doc__, ranks_by="fidelity")
    ap.add_argument("--highd", type=Path, help="directory of HighD recordings (required; obtain HighD yourself)")
    ap.add_argument("--recordings", help="comma-separated recording ids, e.g. 01,02 (default: all in --highd)")
    ap.add_argument("--bags", type=Path, nargs="+", metavar="RUN", help="bags (or run directories) of our runs")
    cli.add_out(ap, "runs/fidelity")
    ap.add_argument("--overwrite", action="store_true", help="replace an earlier result in --out")
    g = ap.add_argument_group("behaviour extraction (the same for both sources)")
    g.add_argument("--leader-range", default="100", metavar="M", help="a preceding vehicle counts within this DHW (default 100 m)")
    g.add_argument("--min-speed", default="5", metavar="MPS", help="car-following samples from vehicles at least this fast (default 5 m/s)")
    g.add_argument("--max-ttc", default="30", metavar="S", help="mandatory lane changes with TTC above this are counted, not sampled (default 30 s)")
    g.add_argument("--include-sut", action="store_true", help="also sample the SUT of our runs (default: BVs only)")
    k = ap.add_argument_group("KDE")
    k.add_argument("--bandwidth", default="scott", help="scott (default), silverman, or a kernel factor > 0")
    k.add_argument("--grid-1d", default="512", metavar="N", help="grid nodes of the 1-D KDEs (default 512)")
    k.add_argument("--grid-2d", default="128", metavar="N", help="grid nodes per axis of the 2-D KDEs (default 128)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import fidelity_experiment

    return cli.run(lambda: fidelity_experiment.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
