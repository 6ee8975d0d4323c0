#!/usr/bin/env python3
"""Where a step's time goes: the compiled kernels' own work, their calls' overhead, and the Python around them.

    python scripts/profile_kernels.py [--cases highd-level0,uniform-level0,highd-learned,uniform-learned,batched]
                                      [--steps 3000] [--worlds 16] [--no-sumo]

For each case (one world under a make-up with level-0 or learned BVs, as ``bench.py``'s make-up section; or
``batched``: ``--worlds`` scored worlds without a bag stepped in lockstep, MOBIL SUT, learned BVs, as ``bench.py
--batched``), after a warm-up, every call of a compiled kernel made from Python is timed, and a sample of them is
run again from a compiled loop on copies of its arguments (compute). Prints per step: wall = compute + call
overhead + Python, and the kernels that take most; then, with libsumo (requirements-bench.txt), its rate on the
same road in this process, each case in libsumo's steps, and the world-step that 5x libsumo's vehicle-steps/s on two
processes allows (docs/performance.md "Where a step's time goes"; :mod:`evoscen_experiments.kernel_profile`). The wrappers add ~0.3 us to each call.
Exit status: 0, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("profile_kernels.py", __doc__)
    ap.add_argument("--cases", default="highd-level0,uniform-level0,highd-learned,uniform-learned,batched",
                    help="comma-separated cases (default: all)")
    ap.add_argument("--steps", default="3000", help="profiled steps per case (default 3000; per world when batched)")
    ap.add_argument("--worlds", default="16", help="worlds of the batched case (default 16)")
    ap.add_argument("--no-sumo", action="store_true", help="skip libsumo's rate even if libsumo is installed")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import kernel_profile

    return cli.run(lambda: kernel_profile.profile_kernels(args.cases, args.steps, args.worlds, not args.no_sumo))


if __name__ == "__main__":
    sys.exit(main())
