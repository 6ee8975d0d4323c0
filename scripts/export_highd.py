#!/usr/bin/env python3
"""Write a recorded run (bag) as a HighD-format recording.

    python scripts/export_highd.py BAG OUTDIR [--recording-id NN] [--frame-rate HZ] [--overwrite]

Writes ``OUTDIR/NN_recordingMeta.csv``, ``NN_tracksMeta.csv`` and ``NN_tracks.csv`` (HighD's
three files), so HighD tooling runs on simulated traffic. The run is drawn on a straight
virtual road (arc length s -> x, lateral offset d -> y, image coordinates, our traffic on the
lower lanes, drivingDirection 2), resampled to ``--frame-rate`` (25 Hz, HighD's) by linear
interpolation; a vehicle that re-enters becomes a new track; the SUT is exported like every
vehicle and marked in tracksMeta's extra column ``evoscenRole`` (1). docs/experiments.md §3 has
every convention. Exit status: 0 done, 2 bad input (one line ``error: ...``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None):
    p = cli.parser("export_highd.py", __doc__)
    p.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap) or the .mcap file")
    p.add_argument("outdir", type=Path, help="directory for the three HighD files")
    p.add_argument("--recording-id", default="1", metavar="NN", help="HighD recording id (file prefix NN_, default 01)")
    p.add_argument("--frame-rate", default="25", metavar="HZ", help="frames per second of the export (default 25, HighD's)")
    p.add_argument("--overwrite", action="store_true", help="replace existing NN_*.csv files in OUTDIR")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.naturalistic.fidelity import export_bag

    return cli.run(lambda: export_bag(args.bag, args.outdir, recording_id=args.recording_id,
                                      frame_rate=args.frame_rate, overwrite=args.overwrite))


if __name__ == "__main__":
    sys.exit(main())
