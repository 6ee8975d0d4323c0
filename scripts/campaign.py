#!/usr/bin/env python3
"""Run a campaign: every run of a YAML spec on Ray, each once (docs/campaigns.md).

    python scripts/campaign.py SPEC [--out DIR] [--address ADDR] [--cpus N] [--retries N]

The spec (see ``examples/campaigns/``) gives the scenario, the seeds, fixed overrides and a
grid of axes (scenario keys, ``mutant``); every cell runs on every seed as one Ray task of one
CPU. Results go to ``--out`` (default ``runs/campaigns/<name>``): ``runs/<key>/result.json``
and ``report.json`` per run, ``results.parquet`` (one row per run) and ``summary.md`` (per-cell
means with 95 % intervals; paired differences with ``compare``). A run whose result exists is
never recomputed: run the same command again after Ctrl-C to continue. ``--address`` joins a
running Ray cluster (``ray start --head``); by default Ray starts here with ``--cpus`` workers
(default: every CPU). Exit status: 0 done, 2 bad input, 3 some runs failed, 5 a fault of the host
(a full disk, an unwritable output: one line; the run it hit is not marked done, the same command
continues once it is gone), 130 interrupted.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("campaign.py", __doc__, ranks_by="D")  # summary.md compares cells by the compared score
    ap.add_argument("spec", type=Path, help="campaign spec (YAML)")
    ap.add_argument("--out", type=Path, help="output directory (default runs/campaigns/<spec name>)")
    ap.add_argument("--address", help="join this Ray cluster (e.g. 10.0.0.5:6379 or 'auto') instead of starting one")
    ap.add_argument("--cpus", default=str(os.cpu_count() or 1), help="workers of the local Ray (default: CPU count)")
    ap.add_argument("--retries", default="3", help="retries of a run whose worker dies (default 3)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import campaign_driver

    return cli.run(lambda: campaign_driver.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
