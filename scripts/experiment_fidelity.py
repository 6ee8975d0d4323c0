#!/usr/bin/env python3
"""Fidelity experiment (docs/method.md §5.3, §6.3): our runs' BVs against naturalistic HighD traffic.

    python scripts/experiment_fidelity.py --highd DIR [--recordings 01,02] --bags RUN [RUN ...]
        [--out DIR] [--overwrite] [--leader-range M] [--min-speed MPS] [--max-ttc S]
        [--include-sut] [--bandwidth scott|silverman|FACTOR] [--grid-1d N] [--grid-2d N]

HighD may not be redistributed, so evoscen ships none: obtain it from
https://www.highd-dataset.com and point ``--highd`` at the directory holding its
``NN_recordingMeta.csv``, ``NN_tracksMeta.csv`` and ``NN_tracks.csv`` (``--recordings``
picks some; default all). Each RUN is a bag (directory or ``.mcap``) or a run directory of
``run_scenario.py`` (its ``bag/``). Both sources go through the same behaviour extraction;
the four distributions — (DHW, speed), (THW, speed), TTC of mandatory lane changes, speed of
voluntary ones — are compared as KDEs on a common grid by the Jensen–Shannon divergence
(log base 2) and the similarity S = (1 - JS)·100 %.

Writes ``OUT/fidelity.csv``, ``OUT/fidelity.md`` and the four plots ``OUT/*.png`` (default
``runs/fidelity``) and prints the table. Exit status: 0 done, 2 bad input (one line
``error: ...``; also without ``--highd``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK

HIGHD_MISSING = ("--highd DIR is required: HighD data cannot be redistributed, so evoscen ships none; obtain the "
                 "dataset from https://www.highd-dataset.com (free for non-commercial research) and pass the directory "
                 "holding its NN_recordingMeta.csv, NN_tracksMeta.csv and NN_tracks.csv files")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="experiment_fidelity.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--highd", type=Path, help="directory of HighD recordings (required; obtain HighD yourself)")
    ap.add_argument("--recordings", help="comma-separated recording ids, e.g. 01,02 (default: all in --highd)")
    ap.add_argument("--bags", type=Path, nargs="+", metavar="RUN", help="bags (or run directories) of our runs")
    ap.add_argument("--out", type=Path, default=Path("runs/fidelity"), help="output directory (default runs/fidelity)")
    ap.add_argument("--overwrite", action="store_true", help="replace an earlier result in --out")
    g = ap.add_argument_group("behaviour extraction (the same for both sources)")
    g.add_argument("--leader-range", default="100", metavar="M", help="a preceding vehicle counts within this DHW (default 100 m)")
    g.add_argument("--min-speed", default="5", metavar="MPS", help="car-following samples from vehicles at least this fast (default 5 m/s)")
    g.add_argument("--max-ttc", default="30", metavar="S", help="mandatory lane changes with TTC above this are counted, not sampled (default 30 s)")
    g.add_argument("--include-sut", action="store_true", help="also sample the SUT of our runs (default: BVs only)")
    k = ap.add_argument_group("KDE")
    k.add_argument("--bandwidth", default="scott", help="scott (default), silverman, or a kernel factor > 0")
    k.add_argument("--grid-1d", default="512", metavar="N", help="grid nodes of the 1-D KDEs (default 512)")
    k.add_argument("--grid-2d", default="128", metavar="N", help="grid nodes per axis of the 2-D KDEs (default 128)")
    return ap.parse_args(argv)


def _number(flag: str, text: str, *, integer: bool = False, lo: float = 0.0, inclusive: bool = False) -> float:
    """``text`` as a number > ``lo`` (>= with ``inclusive``); InputError naming the flag otherwise."""
    from evoscen_sim.errors import InputError

    try:
        value = int(text) if integer else float(text)
    except ValueError:
        value = None
    if value is None or value != value or value == float("inf") or not (value >= lo if inclusive else value > lo):
        kind = "an integer" if integer else "a number"
        raise InputError(f"{flag} {text!r}: expected {kind} {'>=' if inclusive else '>'} {lo:g}")
    return value


def resolve_bag(run: Path) -> Path:
    """A bag path from RUN: the bag itself, or a run directory's ``bag/``."""
    from evoscen_record.bag_reader import bag_or_run_dir

    return bag_or_run_dir(run, "--bags ")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.naturalistic.behaviour import BehaviourConfig
    from evoscen_eval.naturalistic.fidelity import bag_samples, compare_behaviour, highd_samples, markdown_table, plot_rows, write_csv
    from evoscen_eval.naturalistic.highd import find_recordings, recording_paths
    from evoscen_eval.naturalistic.similarity import KdeConfig
    from evoscen_sim.errors import InputError

    try:
        if args.highd is None:
            raise InputError(HIGHD_MISSING)
        if not args.bags:
            raise InputError("--bags RUN [RUN ...] is required: the bags (or run directories) of our runs to compare")
        behaviour = BehaviourConfig(leader_range_m=_number("--leader-range", args.leader_range),
                                    min_speed_mps=_number("--min-speed", args.min_speed, inclusive=True),
                                    max_ttc_s=_number("--max-ttc", args.max_ttc),
                                    include_sut=args.include_sut)
        bandwidth = args.bandwidth if args.bandwidth in ("scott", "silverman") else _number("--bandwidth", args.bandwidth)
        kde = KdeConfig(bandwidth=bandwidth, grid_points_1d=int(_number("--grid-1d", args.grid_1d, integer=True, lo=2)),
                        grid_points_2d=int(_number("--grid-2d", args.grid_2d, integer=True, lo=2)))
        available = find_recordings(args.highd)
        if args.recordings:
            wanted = [r.strip() for r in args.recordings.split(",") if r.strip()]
            for r in wanted:
                if not r.isdigit():
                    raise InputError(f"--recordings {args.recordings!r}: {r!r} is not a recording number (e.g. 01,02)")
                if not recording_paths(args.highd, r)["tracks"].exists():
                    raise InputError(f"--recordings: {recording_paths(args.highd, r)['tracks']}: file not found "
                                     f"(available: {', '.join(available) or 'none'})")
        else:
            wanted = available
            if not wanted:
                raise InputError(f"--highd {args.highd}: no HighD recording (NN_tracks.csv) in this directory")
        bags = [resolve_bag(b) for b in args.bags]
        csv_path = args.out / "fidelity.csv"
        if csv_path.exists() and not args.overwrite:
            raise InputError(f"--out {args.out}: holds an earlier result (fidelity.csv); choose another --out or pass --overwrite")
        print(f"HighD: {len(wanted)} recording{'s' if len(wanted) != 1 else ''} from {args.highd}", file=sys.stderr)
        natural = highd_samples(args.highd, wanted, behaviour)
        print(f"simulation: {len(bags)} bag{'s' if len(bags) != 1 else ''}", file=sys.stderr)
        simulated, warnings = bag_samples(bags, behaviour)
        for w in warnings:
            print(f"warning: {w}", file=sys.stderr)
        rows = compare_behaviour(natural, simulated, kde)
        try:
            args.out.mkdir(parents=True, exist_ok=True)
            write_csv(rows, csv_path)
            table = markdown_table(rows, natural, simulated)
            (args.out / "fidelity.md").write_text("# Fidelity against HighD\n\n" + table, encoding="utf-8")
            plots = plot_rows(rows, args.out)
        except OSError as exc:
            raise InputError(f"--out {args.out}: cannot write: {exc.strerror or exc}") from None
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(table, end="")
    print(f"results: {csv_path}, {args.out / 'fidelity.md'}, {len(plots)} plots in {args.out}")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
