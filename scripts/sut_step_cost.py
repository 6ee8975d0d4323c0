#!/usr/bin/env python3
"""CPU time per step of the SUT driver and of the whole scored step, for MOBIL and its mutants.

    python scripts/sut_step_cost.py [--mutants all|NAME,...] [--repeats 2] [--episode-steps 300]

Runs, as the sensitivity experiment runs its episodes (evolving scenario, from a shared start, no bag,
scored, one process, no Ray), MOBIL and each mutant ``--repeats`` times in turn (seeds 96000, 96001,
...), after one untimed round (kernels loaded), and prints per variant the CPU time
(``time.process_time``: less sensitive than wall time to other processes on a shared machine) per
step of the SUT driver's ``act`` and of the scored step loop, and each variant's ``act`` over
MOBIL's: the figures of docs/performance.md "Per-step work of the SUT drivers"
(:func:`evoscen_experiments.profiling.sut_step_lines`). Exit status: 0, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("sut_step_cost.py", __doc__, ranks_by="speed")
    ap.add_argument("--mutants", default="all", help="'all' or comma-separated mutants of MOBIL")
    ap.add_argument("--repeats", default="2", help="timed episodes per variant (default 2)")
    ap.add_argument("--episode-steps", default="300", help="steps per episode (default 300)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import profiling

    return cli.run(lambda: profiling.sut_step_cost(args.mutants, args.repeats, args.episode_steps))


if __name__ == "__main__":
    sys.exit(main())
