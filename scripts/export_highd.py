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

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="export_highd.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap) or the .mcap file")
    ap.add_argument("outdir", type=Path, help="directory for the three HighD files")
    ap.add_argument("--recording-id", default="1", metavar="NN", help="HighD recording id (file prefix NN_, default 01)")
    ap.add_argument("--frame-rate", default="25", metavar="HZ", help="frames per second of the export (default 25, HighD's)")
    ap.add_argument("--overwrite", action="store_true", help="replace existing NN_*.csv files in OUTDIR")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.naturalistic.fidelity import run_recording
    from evoscen_eval.naturalistic.highd import write_recording
    from evoscen_eval.naturalistic.highd_export import ExportOptions
    from evoscen_sim.errors import InputError

    try:
        if not args.recording_id.isdigit() or not 1 <= int(args.recording_id) <= 99:
            raise InputError(f"--recording-id {args.recording_id!r}: expected an integer in [1, 99]")
        try:
            rate = float(args.frame_rate)
        except ValueError:
            rate = float("nan")
        if not 0 < rate <= 1000:
            raise InputError(f"--frame-rate {args.frame_rate!r}: expected a number of frames per second in (0, 1000]")
        rec = run_recording(args.bag, ExportOptions(frame_rate_hz=rate, recording_id=int(args.recording_id)))
        for w in rec.warnings:
            print(f"warning: {w}", file=sys.stderr)
        paths = write_recording(args.outdir, rec, overwrite=args.overwrite)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    n_sut = int((rec.tracks_meta["evoscenRole"] == 1).sum())
    print(f"exported {args.bag} -> {paths['tracks'].parent}: {rec.num_rows} rows, {len(rec.tracks_meta['id'])} tracks "
          f"({n_sut} of the SUT), {int(rec.tracks['frame'].max())} frames at {rec.frame_rate_hz:g} Hz")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
