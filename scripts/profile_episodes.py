#!/usr/bin/env python3
"""Where an experiment episode's time goes: set-up, warm-up, stepping, scoring — one process, no Ray.

    python scripts/profile_episodes.py [--scenario evolving|level0|nilsson|mobil] [--seeds 2]
                                       [--mutants all|NAME,...] [--episode-steps 300]

Runs, for each of ``--seeds`` seeds (from 96000), MOBIL and its mutants (``--mutants``, default
all ten) as the sensitivity experiment runs its episodes (no bag, scored), two ways, alternated
seed by seed so that both see the same load of a shared machine:

* **per run**: every episode built from scratch — the scenario file parsed, the warm-up run, the
  BV drivers of every BV node built (how each episode was computed before shared starts);
* **shared start**: the file parsed once, the warm-up and the BV driver built once per seed and
  copied for every variant, one driver of all BVs (:mod:`evoscen_bringup.starts`; what the
  experiments do now).

Prints per episode the wall time of each phase (timers around the functions that do it) and the
speed-up, and checks that both ways give the same reports (byte for byte as JSON): a figure for
docs/performance.md "Experiments" (:func:`evoscen_experiments.profiling.profile`). Exit status: 0,
1 when the reports differ, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401
from evoscen import cli
from evoscen_experiments.profiling import SCENARIOS


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("profile_episodes.py", __doc__, ranks_by="speed")
    ap.add_argument("--scenario", default="evolving", help=f"one of {', '.join(SCENARIOS)} (default evolving)")
    ap.add_argument("--seeds", default="2", help="seeds, each run both ways (default 2)")
    ap.add_argument("--mutants", default="all", help="'all' or comma-separated mutants of MOBIL")
    ap.add_argument("--episode-steps", default="300", help="steps per episode (default 300)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import profiling

    return cli.run(lambda: profiling.profile_episodes(args.scenario, args.seeds, args.mutants, args.episode_steps))


if __name__ == "__main__":
    sys.exit(main())
