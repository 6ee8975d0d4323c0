#!/usr/bin/env python3
"""Score a recorded run from its bag alone: report.json, report.md and plots.

    python scripts/evaluate.py BAG [--out DIR] [--config FILE] [--overwrite] [--no-plots] [--reindex]
                                   [--animation-frames N]

BAG is a bag directory (``metadata.yaml`` + ``.mcap``) or its ``.mcap`` file. The evaluation
settings are the ones recorded in the bag (the run's scenario); ``--config FILE`` scores with
the ``evaluation`` section of another scenario YAML instead. The scores equal the ones the
evaluator node (or the in-process runner) wrote during the run. A truncated or corrupt bag is
evaluated up to the damage, with one warning saying how many steps were read and naming the
command that rebuilds such a bag (``scripts/reindex.py BAG``); ``--reindex`` runs it first.

``--out`` defaults to ``<the bag's directory>/../report_offline``; an existing non-empty
directory is replaced only with ``--overwrite``. ``--animation-frames N`` sets the frames of the
bird's-eye animation ``run.gif`` (default 120; 0: none; ``--no-plots`` writes none). Exit status: 0 done, 2 bad input, 5 the report could not be
written (a full disk, a read-only file system: one line naming the file).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_HOST_FAULT, EXIT_OK


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="evaluate.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", type=Path, help="bag directory or .mcap file")
    ap.add_argument("--out", type=Path, help="report directory (default: BAG/../report_offline)")
    ap.add_argument("--config", type=Path, help="scenario YAML whose 'evaluation' section to use instead of the bag's")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing report in --out")
    ap.add_argument("--no-plots", action="store_true", help="report.json and report.md only")
    ap.add_argument("--animation-frames", default=None, metavar="N",
                    help="frames of the bird's-eye animation run.gif (default 120; 0: none)")
    ap.add_argument("--reindex", action="store_true",
                    help="first rebuild the bag's summary and metadata.yaml (scripts/reindex.py), e.g. after a killed recorder")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.scoring.report import write_stream_report
    from evoscen_eval.scoring.rundata import score_bag
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    from evoscen_eval.scoring.animation import ANIMATION_FRAMES

    try:
        frames = ANIMATION_FRAMES if args.animation_frames is None else int(args.animation_frames)
        if frames < 0:
            raise ValueError
    except ValueError:
        print(f"error: --animation-frames: {args.animation_frames!r}: expected a whole number >= 0", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        override = load_scenario_config(args.config).evaluation if args.config is not None else None
        bag_path = args.bag
        if not bag_path.exists():
            raise InputError(f"bag {str(bag_path)!r}: no such bag directory or .mcap file")
        if args.reindex:
            from evoscen_record.reindex import reindex_bag

            r = reindex_bag(bag_path)
            print(f"reindexed: {r.messages} messages, {r.steps} world states recovered", file=sys.stderr)
        run = score_bag(bag_path, override)  # one pass: memory independent of the run's length
        if not args.reindex and not _finished(bag_path):
            hint = f"; to rebuild its summary and metadata.yaml: python scripts/reindex.py {bag_path} (or --reindex)"
            damaged = [k for k, w in enumerate(run.warnings) if "truncated or corrupt" in w]
            if damaged:
                run.warnings[damaged[0]] += hint
            else:
                run.warnings.append(f"bag {str(bag_path)!r} is not finished (no summary section or no "
                                    f"metadata.yaml: the recorder was killed?)" + hint)
        bag_dir = bag_path if bag_path.is_dir() else bag_path.parent
        out = args.out if args.out is not None else bag_dir.resolve().parent / "report_offline"
        if out.exists() and (not out.is_dir() or any(out.iterdir())):
            if not args.overwrite or not out.is_dir():
                raise InputError(f"--out {out}: exists and is not empty; choose another --out or pass --overwrite")
            shutil.rmtree(out)
        for warning in run.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        from evoscen_sim.errors import HostFault

        try:
            report = write_stream_report(run.stream, run.info, run.warnings, out, plots=not args.no_plots,
                                         source=str(bag_path), lane_segments=run.lane_segments,
                                         animation_frames=frames)
        except HostFault as fault:  # a full disk, a read-only file system
            print(f"error: {fault.line()}", file=sys.stderr)
            return EXIT_HOST_FAULT
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    from evoscen_eval.scoring.report import score_line

    print(f"{report['run']['steps']} steps; {score_line(report)}")
    d = report.get("comparative")
    if d:  # docs/evaluation.md §10
        print(f"comparative: {d['score']:.4f} (progress {d['progress']['score']:.4f}, safety {d['safety']['score']:.4f}, "
              f"lane-change time {d['lane_change_time']['score']:.4f}, interaction {d['interaction']['score']:.4f})")
    print(f"report: {out / 'report.md'}")
    return EXIT_OK


def _finished(bag_path: Path) -> bool:
    """The bag has its metadata.yaml (for a directory) and its MCAP summary: readers open it."""
    from evoscen_record.bag_reader import open_bag_reader
    from evoscen_sim.errors import InputError

    if bag_path.is_dir() and not (bag_path / "metadata.yaml").is_file():
        return False
    try:
        open_bag_reader(bag_path).close()
    except InputError:
        return False
    return True


if __name__ == "__main__":
    sys.exit(main())
