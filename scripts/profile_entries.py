#!/usr/bin/env python3
"""What the traffic window's entries cost a step: tries per step and the time of one try.

    python scripts/profile_entries.py [--seed 3] [--driver level0|learned] [--blocks 4] [--block-steps 1500]
                                      [--repeats 3000]

Runs the default scenario (recording off, one BV driver) and prints, per block of ``--block-steps``
steps, the entry tries per step (:meth:`evoscen_sim.physics.window.TrafficWindow._enter` calls:
vehicles that left the window, each trying to enter again) and the block's time per step; then the time
of one try that finds no place (the first vehicle outside the window at the end, tried ``--repeats``
times from the same state and random stream, best of three). Figures for docs/performance.md; run it on
two versions to compare them (the same seed gives the same world; :func:`evoscen_experiments.profiling.entries`).
Exit status: 0, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("profile_entries.py", __doc__, ranks_by="speed")
    ap.add_argument("--seed", default="3", help="the scenario's seed (default 3)")
    ap.add_argument("--driver", default="level0", help="the BVs' driver: level0 or learned (default level0)")
    ap.add_argument("--blocks", default="4", help="blocks of steps (default 4)")
    ap.add_argument("--block-steps", default="1500", help="steps per block (default 1500)")
    ap.add_argument("--repeats", default="3000", help="tries of the timed entry, each of three rounds (default 3000)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import profiling

    return cli.run(lambda: profiling.profile_entries(args.seed, args.driver, args.blocks, args.block_steps,
                                                     args.repeats))


if __name__ == "__main__":
    sys.exit(main())
