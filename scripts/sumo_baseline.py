#!/usr/bin/env python3
"""SUMO baseline: stepping rate of SUMO (libsumo) on the evoscen highway-merge scenario.

    python scripts/sumo_baseline.py [--steps 3000] [--vehicles 21] [--seed 0] [--warmup-steps 200]
                                    [--json] [--in-process]

The same road and traffic volume as evoscen's default scenario, built with netconvert; only
``libsumo.simulationStep`` is timed, after the warm-up. SUMO is optional
(``pip install -r requirements-bench.txt``); the scenario mapping and the timing are described in
:mod:`evoscen_experiments.sumo_baseline`. Exit status: 0, 2 SUMO not available or the run failed.
"""

from __future__ import annotations

import sys

import _bootstrap  # noqa: F401
from evoscen import cli


def parse_args(argv: list[str] | None):
    ap = cli.parser("sumo_baseline.py", "SUMO (libsumo) stepping rate on the evoscen merge scenario")
    ap.add_argument("--steps", type=int, default=3000, help="timed steps (default 3000)")
    ap.add_argument("--vehicles", type=int, default=21, help="vehicles on the road (default 21 = 20 BV + SUT)")
    ap.add_argument("--seed", type=int, default=0, help="SUMO --seed (default 0)")
    ap.add_argument("--warmup-steps", type=int, default=200, help="untimed warm-up steps (default 200)")
    ap.add_argument("--json", action="store_true", help="print one JSON line instead of text")
    ap.add_argument("--in-process", action="store_true", help="run libsumo in this process (no child)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import sumo_baseline

    return cli.run(lambda: sumo_baseline.run(args.steps, args.vehicles, args.seed, args.warmup_steps,
                                             args.json, args.in_process))


if __name__ == "__main__":
    sys.exit(main())
