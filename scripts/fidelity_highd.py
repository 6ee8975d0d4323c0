#!/usr/bin/env python3
"""The traffic's fidelity against highD's shipped aggregates (docs/fidelity.md).

    python scripts/fidelity_highd.py BAG [BAG ...] [--out DIR]
    python scripts/fidelity_highd.py --seeds N [--first-seed 7001] [--steps 3000] [--sut mobil]
                                     [--config FILE] [--set KEY=VALUE ...] [--out DIR]
        [--piece-m 420] [--min-piece-m 420] [--truck-length 7] [--include-sut] [--reference FILE]

Measures the background vehicles of recorded runs (each BAG a bag directory, an ``.mcap`` file or a
``run_scenario.py`` output directory with ``bag/``) or of ``--seeds`` runs made here in process (no
bag), the way highD sees its vehicles: every trip cut into 420-m pieces, per piece the mean speed and
the minimum THW, DHW and TTC, per class (truck: longer than 7 m) and all; lane changes per vehicle-km,
per class and by density. Each distribution is compared with highD's (the recordings with a 120 km/h
limit; R. Krajewski, J. Bock, L. Kloeker, L. Eckstein, "The highD Dataset", IEEE ITSC 2018) by
S = 1 - JS(highD || simulation), log base 2, over highD's bins.

Prints the table and writes ``OUT/fidelity_highd.json``, ``OUT/fidelity_highd.md`` and one PNG per
distribution (default ``runs/fidelity_highd``). Exit status: 0 done, 2 bad input (one line ``error: ...``).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, status 2
        print(f"error: {message}", file=sys.stderr)
        sys.exit(EXIT_BAD_INPUT)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = _Parser(prog="fidelity_highd.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("bags", nargs="*", type=Path, metavar="BAG", help="bags (or run directories) to measure")
    ap.add_argument("--out", type=Path, default=Path("runs/fidelity_highd"),
                    help="output directory (default runs/fidelity_highd)")
    g = ap.add_argument_group("runs made here, in process (instead of or besides bags)")
    g.add_argument("--seeds", default=None, metavar="N", help="number of seeds to run")
    g.add_argument("--first-seed", default="7001", help="first seed (default 7001)")
    g.add_argument("--steps", default="3000", help="steps per run (default 3000)")
    g.add_argument("--sut", default="mobil", help="SUT model (default mobil)")
    g.add_argument("--config", type=Path, help="scenario YAML (default: the shipped default)")
    g.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a scenario key")
    m = ap.add_argument_group("measurement (docs/fidelity.md)")
    m.add_argument("--piece-m", default="420", metavar="M", help="piece length (default 420 m)")
    m.add_argument("--min-piece-m", default=None, metavar="M",
                   help="a trip's remainder at least this long is a piece too (default: --piece-m, i.e. never)")
    m.add_argument("--truck-length", default="7", metavar="M", help="a vehicle longer than this is a truck (default 7 m)")
    m.add_argument("--include-sut", action="store_true", help="also measure the SUT (default: BVs only)")
    m.add_argument("--reference", type=Path, default=None,
                   help="highD aggregates JSON (default: the copy shipped with evoscen_eval)")
    return ap.parse_args(argv)


def _length(flag: str, text: str) -> float:
    from evoscen_sim.errors import InputError

    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{flag} {text!r}: expected a length > 0 (m)")
    return value


def resolve_bag(run: Path) -> Path:
    """A bag path from BAG: the bag itself, or a run directory's ``bag/``."""
    from evoscen_record.bag_reader import bag_or_run_dir

    return bag_or_run_dir(run, "")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments.experiments import positive_int
    from evoscen_eval.naturalistic.fidelity_highd import (Measures, PieceConfig, compare, load_reference, markdown_table,
                                             plot_histograms, run_measures, to_json)
    from evoscen_eval.scoring.rundata import read_run
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    try:
        piece = _length("--piece-m", args.piece_m)
        min_piece = _length("--min-piece-m", args.min_piece_m) if args.min_piece_m is not None else piece
        if min_piece > piece:
            raise InputError(f"--min-piece-m {args.min_piece_m!r}: expected a length <= --piece-m ({piece:g} m)")
        config = PieceConfig(piece_m=piece, min_piece_m=min_piece, truck_length_m=_length("--truck-length", args.truck_length),
                             include_sut=args.include_sut)
        reference = load_reference(args.reference)
        seeds = positive_int("--seeds", args.seeds) if args.seeds is not None else 0
        first = positive_int("--first-seed", args.first_seed, 0)
        steps = positive_int("--steps", args.steps)
        if not args.bags and not seeds:
            raise InputError("BAG: expected one or more bags (or run directories), or --seeds N to run here")
        overrides: dict[str, str] = {}
        for item in args.set:
            key, sep, value = item.partition("=")
            if not sep or not key.strip():
                raise InputError(f"--set {item!r}: expected KEY=VALUE")
            overrides[key.strip()] = value.strip()

        def cfg_for(seed: int):
            return load_scenario_config(args.config, {**overrides, "sut.model": args.sut, "seed": str(seed),
                                                      "steps": str(steps), "recording.enabled": "false"})

        if seeds:
            cfg_for(first)  # validated before anything runs
        bags = [resolve_bag(b) for b in args.bags]
        parts = []
        for bag in bags:
            parts.append(run_measures(read_run(bag), config, source=str(bag)))
            print(f"{bag}: {parts[-1].pieces} pieces", file=sys.stderr)
        if seeds:
            from evoscen_bringup.inprocess import run_inprocess

            for seed in range(first, first + seeds):
                summary = run_inprocess(cfg_for(seed), bag_dir=None, evaluate=True, plots=False, keep_run=True)
                parts.append(run_measures(summary.run, config, source=f"seed {seed}"))
                print(f"seed {seed}: {parts[-1].pieces} pieces", file=sys.stderr)
        measures = Measures.concat(parts)
        for w in measures.warnings:
            print(f"warning: {w}", file=sys.stderr)
        result = compare(measures, reference)
        result["settings"] = {"piece_m": piece, "min_piece_m": min_piece, "truck_length_m": config.truck_length_m,
                              "include_sut": args.include_sut, "bags": [str(b) for b in bags],
                              "seeds": list(range(first, first + seeds)) if seeds else [],
                              "steps": steps if seeds else None, "sut": args.sut if seeds else None,
                              "overrides": overrides}
        table = markdown_table(result)
        try:
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / "fidelity_highd.json").write_text(to_json(result), encoding="utf-8")
            (args.out / "fidelity_highd.md").write_text(
                f"# Traffic against highD\n\n{table}\nhighD: {result['citation']}\n", encoding="utf-8")
            plots = plot_histograms(result, args.out)
        except OSError as exc:
            raise InputError(f"--out {args.out}: cannot write: {exc.strerror or exc}") from None
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(table, end="")
    print(f"{measures.pieces} pieces of {piece:g} m from {len(measures.runs)} runs; highD: {result['citation']}")
    print(f"results: {args.out / 'fidelity_highd.json'}, {args.out / 'fidelity_highd.md'}, {len(plots)} plots")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
