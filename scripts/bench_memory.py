#!/usr/bin/env python3
"""Peak memory of a scored in-process run at two run lengths: is it independent of the length?

    python scripts/bench_memory.py [--steps N1 N2] [--bvs N] [--tracemalloc N]
    python scripts/bench_memory.py --worlds 1000 --steps 300 300

Each run is a fresh process (``run_inprocess`` with scoring, no bag, no plots) that prints its
peak RSS (``ru_maxrss``) after the simulation and after the scoring. The script prints, per
length, the peaks and the RSS per step above an idle baseline (the same process with 1 step),
then the marginal bytes per step between the two lengths and the ratio of the peaks.

``--tracemalloc N`` instead runs N steps with :mod:`tracemalloc` and prints the allocation
sites that hold the most memory at the end of the simulation and the peak of the scoring
(:func:`evoscen_experiments.bench_run_costs.memory`). ``--worlds N`` instead steps N scored worlds in lockstep in one
process (MOBIL and its mutants, 12 per seed, ``N1`` steps) and prints its peak against one world's and the memory per
world (:func:`evoscen_experiments.bench_run_costs.worlds_memory`).
Figures only; nothing is asserted (benchmarks print figures).
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("bench_memory.py", __doc__)
    ap.add_argument("--steps", type=int, nargs=2, default=[5000, 20000], metavar=("N1", "N2"),
                    help="the two run lengths (default 5000 20000)")
    ap.add_argument("--bvs", type=int, default=20, help="background vehicles (default 20)")
    ap.add_argument("--tracemalloc", type=int, metavar="N", help="allocation sites of an N-step run instead")
    ap.add_argument("--worlds", type=int, metavar="N",
                    help="instead: N scored worlds stepped in lockstep in one process against one (--steps: N1)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import bench_run_costs

    if args.worlds is not None:
        if args.worlds < 1 or args.steps[0] < 1:
            print(f"error: --worlds {args.worlds} --steps {args.steps[0]}: expected at least 1 of each", file=sys.stderr)
            return 2
        return cli.run(lambda: bench_run_costs.worlds_memory(args.worlds, args.steps[0]))
    return cli.run(lambda: bench_run_costs.memory(args.steps, args.bvs, args.tracemalloc))


if __name__ == "__main__":
    sys.exit(main())
