#!/usr/bin/env python3
"""Export a recorded run's time range, or every critical-event clip of a run or campaign, as an
OpenSCENARIO 1.2 or a CommonRoad scenario (docs/export.md).

    python scripts/export_scenario.py BAG [--from T] [--to T] --format xosc|commonroad [--out DIR] [--check]
    python scripts/export_scenario.py RUN_OR_CAMPAIGN_DIR --format xosc|commonroad [--check]

BAG is a bag directory (or its ``.mcap`` file): a run's ``OUT/bag`` or a clip's ``clips/<n>-<kind>-<k>/bag``.
``--from``/``--to`` are run times in seconds (default: the bag's first and last state). A directory
holding ``clips.json`` (a campaign run) or ``runs/*/clips.json`` (a campaign's output) exports
every clip listed, each into ``<clip>/export/``. ``--check``: the ASAM Quality Checker on an
OpenSCENARIO file, and the independent collision check (shapely on the exported boxes) against
evoscen's collision events; exit 1 when either fails. Bad input: one ``error:`` line, exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (the workspace's packages on sys.path)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="export_scenario.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", help="bag directory or .mcap file; or a campaign run / campaign output directory")
    ap.add_argument("--from", dest="t_from", help="run time of the first state exported (s; default: the bag's first)")
    ap.add_argument("--to", dest="t_to", help="run time of the last state exported (s; default: the bag's last)")
    ap.add_argument("--format", dest="fmt", default="xosc", help="xosc (OpenSCENARIO 1.2) or commonroad (default xosc)")
    ap.add_argument("--out", help="output directory (default: 'export' beside the bag)")
    ap.add_argument("--name", default="scenario", help="file name without suffix (default scenario)")
    ap.add_argument("--truck-length-m", default="7.0", help="vehicles longer than this are trucks (default 7.0 m)")
    ap.add_argument("--check", action="store_true", help="run the ASAM checker (xosc) and the independent collision check")
    return ap.parse_args(argv)


def _number(flag: str, value: str | None) -> float | None:
    from evoscen_sim.errors import InputError

    if value is None:
        return None
    try:
        out = float(value)
    except ValueError:
        raise InputError(f"{flag}: {value!r}: expected a number (s)") from None
    if out != out or out in (float("inf"), float("-inf")):
        raise InputError(f"{flag}: {value!r}: expected a finite number")
    return out


def clip_bags(path: Path) -> list[Path] | None:
    """The clips' bags listed under a campaign run (``clips.json``) or a campaign output, else None."""
    listings = [path / "clips.json"] if (path / "clips.json").is_file() else sorted(path.glob("runs/*/clips.json"))
    if not listings:
        return None
    bags = []
    for listing in listings:
        for clip in json.loads(listing.read_text(encoding="utf-8")):
            bags.append(listing.parent / clip["clip"])
    return bags


def export_one(bag: Path, t_from, t_to, fmt: str, out: Path, name: str, truck: float, check: bool) -> bool:
    """Export one range; print what was written (and checked); True when every check passed."""
    from evoscen_eval import scenario_export as X

    ex = X.load_range(bag, t_from, t_to, truck_min_length_m=truck)
    path = X.write_xosc(ex, out, name) if fmt == "xosc" else X.write_commonroad(ex, out, name)
    pieces = sum(len(t.pieces) for t in ex.tracks)
    trucks = sum(t.klass == "truck" for t in ex.tracks)
    print(f"{path}: {len(ex.tracks)} vehicles ({trucks} trucks), {pieces} pieces, {ex.states} states "
          f"(t = {ex.t_from_s:.1f} .. {ex.t_from_s + ex.duration_s:.1f} s, dt {ex.dt_s:g} s)")
    if not check:
        return True
    ok = True
    xosc_path = path if fmt == "xosc" else X.write_xosc(ex, out / ".check", name)
    if fmt == "xosc":
        errors = X.check_xosc(path)
        print(f"ASAM quality checker: {len(errors)} error(s)")
        for e in errors:
            print(f"  {e}")
        ok = not errors
    agree, lines = X.compare_collisions(ex, xosc_path)
    for line in lines:
        print(line)
    return ok and agree


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.scenario_export import FORMATS
    from evoscen_sim.errors import InputError

    try:
        if args.fmt not in FORMATS:
            raise InputError(f"--format: {args.fmt!r}: expected one of {', '.join(FORMATS)}")
        t_from, t_to = _number("--from", args.t_from), _number("--to", args.t_to)
        truck = _number("--truck-length-m", args.truck_length_m)
        if truck <= 0:
            raise InputError(f"--truck-length-m: {args.truck_length_m}: expected a length > 0 (m)")
        bag = Path(args.bag)
        if not bag.exists():
            raise InputError(f"{bag}: no such bag, bag directory or campaign directory")
        clips = clip_bags(bag) if bag.is_dir() else None
        ok = True
        if clips is not None:
            if t_from is not None or t_to is not None or args.out is not None:
                raise InputError(f"{bag}: --from/--to/--out: not for a campaign directory (each clip is exported "
                                 "whole into <clip>/export/)")
            for clip in clips:
                ok &= export_one(clip, None, None, args.fmt, clip.parent / "export", args.name, truck, args.check)
            print(f"{len(clips)} clip(s) exported")
        else:
            out = Path(args.out) if args.out else (bag if bag.is_dir() else bag.parent).parent / "export"
            ok = export_one(bag, t_from, t_to, args.fmt, out, args.name, truck, args.check)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:
        print(f"error: {exc.filename or args.out}: cannot write the export: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK if ok else 1  # a check failed (docs/export.md)


if __name__ == "__main__":
    sys.exit(main())
