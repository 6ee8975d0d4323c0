#!/usr/bin/env python3
"""What recording costs an in-process run, and what the recorder's write path costs.

    python scripts/bench_recording.py [--steps N] [--repeats R] [--bv-driver level0|learned]

Two figures, each against a reference measured in the same process (these machines are
shared and noisy: compare ratios, not absolute rates):

1. **Recorded / unrecorded** (issue 14's figure): ``run_inprocess`` of the default scenario for
   ``--steps`` steps without a bag, with one written inline (between the steps) and with one
   written by the forked writer process (``bag_writer="process"``, the default where more than
   one CPU is usable; docs/recording.md), the three alternated ``--repeats`` times; steps/s of
   each (wall time from the call until the bag is closed) and the ratios (median over the
   repeats). Target: >= 0.5. The two bags of a repeat are compared byte for byte.
2. **The write path**: the messages of one recorded run, read back from its bag, written again
   by :class:`evoscen_record.recorder.BagRecorder` three ways: the default (the recorder keeps the
   open chunk, ``mcap_internals.ChunkMessages``), ``chunk_writes=False`` (one ``pack`` per message record into
   the library's chunk builder, ``mcap_internals.FastMessages``) and ``fast_writes=False`` (the mcap library's
   own ``Writer.add_message``); microseconds per message of each (best of two, bag opening and
   closing included), their ratio to the library's, and whether the files are byte-identical.

Figures only; nothing is asserted (benchmarks print figures; the tests assert the bytes;
:func:`evoscen_experiments.bench_run_costs.recording`). Exit status: 0, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("bench_recording.py", __doc__, ranks_by="speed")
    ap.add_argument("--steps", type=int, default=3000, help="steps per run (default 3000)")
    ap.add_argument("--repeats", type=int, default=5, help="alternated unrecorded/recorded pairs (default 5)")
    ap.add_argument("--bv-driver", choices=("level0", "learned"), default="level0")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import bench_run_costs

    return cli.run(lambda: bench_run_costs.recording(args.steps, args.repeats, args.bv_driver))


if __name__ == "__main__":
    sys.exit(main())
