"""The fidelity experiment (docs/method.md §5.3, §6.3; docs/fidelity.md): our runs' BVs against HighD.

``scripts/experiment_fidelity.py`` parses the command line and calls :func:`main`: the options checked
(:func:`behaviour_config`, :func:`kde_config`, :func:`recordings`), HighD and our bags through the same
behaviour extraction (:mod:`evoscen_eval.naturalistic.fidelity`), the four distributions compared by the
Jensen–Shannon divergence, and ``fidelity.csv``, ``fidelity.md`` and the plots written.
"""

from __future__ import annotations

import sys
from pathlib import Path

from evoscen_contract.contract import EXIT_OK
from evoscen_sim.errors import InputError

HIGHD_MISSING = ("--highd DIR is required: HighD data cannot be redistributed, so evoscen ships none; obtain the "
                 "dataset from https://www.highd-dataset.com (free for non-commercial research) and pass the directory "
                 "holding its NN_recordingMeta.csv, NN_tracksMeta.csv and NN_tracks.csv files")


def number(flag: str, text: str, *, integer: bool = False, lo: float = 0.0, inclusive: bool = False) -> float:
    """``text`` as a number > ``lo`` (>= with ``inclusive``); InputError naming the flag otherwise."""
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        value = None
    if value is None or value != value or value == float("inf") or not (value >= lo if inclusive else value > lo):
        kind = "an integer" if integer else "a number"
        raise InputError(f"{flag} {text!r}: expected {kind} {'>=' if inclusive else '>'} {lo:g}")
    return value


def behaviour_config(args):
    """The behaviour extraction of ``--leader-range``, ``--min-speed``, ``--max-ttc``, ``--include-sut``."""
    from evoscen_eval.naturalistic.behaviour import BehaviourConfig

    return BehaviourConfig(leader_range_m=number("--leader-range", args.leader_range),
                           min_speed_mps=number("--min-speed", args.min_speed, inclusive=True),
                           max_ttc_s=number("--max-ttc", args.max_ttc),
                           include_sut=args.include_sut)


def kde_config(args):
    """The KDE of ``--bandwidth``, ``--grid-1d``, ``--grid-2d``."""
    from evoscen_eval.naturalistic.similarity import KdeConfig

    bandwidth = args.bandwidth if args.bandwidth in ("scott", "silverman") else number("--bandwidth", args.bandwidth)
    return KdeConfig(bandwidth=bandwidth, grid_points_1d=int(number("--grid-1d", args.grid_1d, integer=True, lo=2)),
                     grid_points_2d=int(number("--grid-2d", args.grid_2d, integer=True, lo=2)))


def recordings(highd: Path, text: str | None) -> list[str]:
    """The HighD recordings of ``--recordings`` (comma-separated numbers; None or empty: all in ``highd``);
    InputError of one line for a bad number, a missing recording or none at all."""
    from evoscen_eval.naturalistic.highd import find_recordings, recording_paths

    available = find_recordings(highd)
    if not text:
        if not available:
            raise InputError(f"--highd {highd}: no HighD recording (NN_tracks.csv) in this directory")
        return available
    wanted = [r.strip() for r in text.split(",") if r.strip()]
    for r in wanted:
        if not r.isdigit():
            raise InputError(f"--recordings {text!r}: {r!r} is not a recording number (e.g. 01,02)")
        if not recording_paths(highd, r)["tracks"].exists():
            raise InputError(f"--recordings: {recording_paths(highd, r)['tracks']}: file not found "
                             f"(available: {', '.join(available) or 'none'})")
    return wanted


def main(args) -> int:
    """The experiment of the parsed options (``scripts/experiment_fidelity.py``; text values, checked here): the
    samples of both sources compared, the files written into ``args.out``, the table printed. Returns the exit
    status; InputError (one line) on bad input or an output that cannot be written."""
    from evoscen_eval.naturalistic.fidelity import (
        bag_samples,
        compare_behaviour,
        highd_samples,
        markdown_table,
        plot_rows,
        write_csv,
    )
    from evoscen_record.bag_reader import bag_or_run_dir

    if args.highd is None:
        raise InputError(HIGHD_MISSING)
    if not args.bags:
        raise InputError("--bags RUN [RUN ...] is required: the bags (or run directories) of our runs to compare")
    behaviour, kde = behaviour_config(args), kde_config(args)
    wanted = recordings(args.highd, args.recordings)
    bags = [bag_or_run_dir(b, "--bags ") for b in args.bags]  # a bag, or a run directory's bag/
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
    print(table, end="")
    print(f"results: {csv_path}, {args.out / 'fidelity.md'}, {len(plots)} plots in {args.out}")
    return EXIT_OK
