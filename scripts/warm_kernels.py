#!/usr/bin/env python3
"""Compile evoscen's kernels into numba's cache, so that the first run or experiment does not.

    python scripts/warm_kernels.py [--steps 300]

Runs short in-process scenarios (learned BVs under both traffic make-ups, level-0 BVs, each built-in SUT
decision model, scored; nothing recorded) that call every per-step kernel with the argument types the runs
use: each is compiled once here, or loaded from the cache when already there
(:mod:`evoscen.warm_kernels`). ``make build`` runs it after a rebuild (which drops the cache). Prints each
run's time and the number of kernels compiled or loaded. Exit status: 0, 2 bad input.
"""

from __future__ import annotations

import sys

import _bootstrap  # noqa: F401
from evoscen import cli
from evoscen.warm_kernels import STEPS


def main(argv: list[str] | None = None) -> int:
    ap = cli.one_line_errors(cli.parser("warm_kernels.py", __doc__))
    cli.add_steps(ap, STEPS)

    def work() -> int:
        from evoscen.warm_kernels import warm

        args = ap.parse_args(argv)
        warm(cli.positive_int("--steps", args.steps))
        return 0

    return cli.run(work)


if __name__ == "__main__":
    sys.exit(main())
