#!/usr/bin/env python3
"""Benchmark of the HighD loader and the behaviour extraction on a HighD-sized recording.

    python scripts/bench_fidelity.py [--vehicles 1000] [--frames 20000] [--rows 1000000] [--seed 0] [--keep DIR]

Generates a synthetic recording of HighD's size (default: 1,000 vehicles over 20,000 frames at
25 Hz, 1,000,000 track rows), writes it in HighD's three-file format with evoscen's writer, then
loads it and extracts the behaviour samples in a FRESH process and prints the wall time and the
peak resident memory of that process (targets: < 10 s, < 2 GiB; :mod:`evoscen_experiments.bench_fidelity`).
Randomness comes from one seeded numpy Generator (``--seed``). Exit status: 0 both targets met,
1 not, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("bench_fidelity.py", __doc__)
    ap.add_argument("--vehicles", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", type=Path, help="write the recording here and keep it (default: a temporary directory)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import bench_fidelity

    return cli.run(lambda: bench_fidelity.run(args.vehicles, args.frames, args.rows, args.seed, args.keep))


if __name__ == "__main__":
    sys.exit(main())
