#!/usr/bin/env python3
"""Score a recorded run from its bag alone: report.json, report.md and plots.

    python scripts/evaluate.py BAG [--out DIR] [--config FILE] [--overwrite] [--no-plots] [--reindex]
                                   [--animation-frames N]

BAG is a bag directory (``metadata.yaml`` + ``.mcap``) or its ``.mcap`` file. The evaluation
settings are the ones recorded in the bag (the run's scenario); ``--config FILE`` scores with
the ``evaluation`` section of another scenario YAML instead. The scores equal the ones the
evaluator node (or the in-process runner) wrote during the run. A truncated or corrupt bag is
evaluated up to the damage, with one warning saying how many steps were read and naming the
command that rebuilds such a bag (``scripts/reindex.py BAG``); ``--reindex`` runs it first.

``--out`` defaults to ``<the bag's directory>/../report_offline``; an existing non-empty
directory is replaced only with ``--overwrite``. ``--animation-frames N`` caps the frames of the
bird's-eye animation ``run.gif`` (one a second of driving, at most 600 by default; 0: none;
``--no-plots`` writes none). Exit status:
0 done, 2 bad input, 5 the report could not be written (a full disk, a read-only file system: one
line naming the file). The work is :func:`evoscen_eval.scoring.bag_report.evaluate_bag`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("evaluate.py", __doc__)
    ap.add_argument("bag", type=Path, help="bag directory or .mcap file")
    ap.add_argument("--out", type=Path, help="report directory (default: BAG/../report_offline)")
    ap.add_argument("--config", type=Path, help="scenario YAML whose 'evaluation' section to use instead of the bag's")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing report in --out")
    ap.add_argument("--no-plots", action="store_true", help="report.json and report.md only")
    ap.add_argument("--animation-frames", default=None, metavar="N",
                    help="most frames of the bird's-eye animation run.gif, one a second of driving (default 600; 0: none)")
    ap.add_argument("--reindex", action="store_true",
                    help="first rebuild the bag's summary and metadata.yaml (scripts/reindex.py), e.g. after a killed recorder")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.scoring.bag_report import evaluate_bag

    return cli.run(lambda: evaluate_bag(args.bag, out=args.out, config=args.config, overwrite=args.overwrite,
                                        plots=not args.no_plots, frames=args.animation_frames, reindex=args.reindex))


if __name__ == "__main__":
    sys.exit(main())
