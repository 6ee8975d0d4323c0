#!/usr/bin/env python3
"""Export a recorded run's time range, or every critical-event clip of a run or campaign, as an
OpenSCENARIO 1.2 or a CommonRoad scenario (docs/export.md).

    python scripts/export_scenario.py BAG [--from T] [--to T] --format xosc|commonroad [--out DIR] [--check]
    python scripts/export_scenario.py BAG [--from T] --compare-start RUN_BAG
    python scripts/export_scenario.py RUN_OR_CAMPAIGN_DIR --format xosc|commonroad [--check]

BAG is a bag directory (or its ``.mcap`` file): a run's ``OUT/bag`` or a clip's ``clips/<n>-<kind>-<k>/bag``.
``--from``/``--to`` are run times in seconds (default: the bag's first and last state). A directory
holding ``clips.json`` (a campaign run) or ``runs/*/clips.json`` (a campaign's output) exports
every clip listed, each into ``<clip>/export/``, and ends with a summary line per clip and a total.
``--check``: the ASAM Quality Checker on an OpenSCENARIO file, commonroad-io's read-back of a
CommonRoad file (obstacles, time steps), and the independent collision check (shapely on the exported
boxes) against evoscen's collision events; ``--compare-start RUN_BAG``: a run started with
``--start-from`` the export against the range's first state; exit 1 when a check fails. Bad input:
one ``error:`` line, exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
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
    ap.add_argument("--compare-start", metavar="RUN_BAG",
                    help="compare the first state of RUN_BAG (a run started with --start-from the exported file) "
                         "with the range's first state; exit 1 when they differ")
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


def clip_bags(path: Path) -> list[tuple[Path, str]] | None:
    """The clips' bags listed under a campaign run (``clips.json``) or a campaign output, each with its
    kind (collision, exposure), else None."""
    listings = [path / "clips.json"] if (path / "clips.json").is_file() else sorted(path.glob("runs/*/clips.json"))
    if not listings:
        return None
    bags = []
    for listing in listings:
        for clip in json.loads(listing.read_text(encoding="utf-8")):
            bags.append((listing.parent / clip["clip"], str(clip.get("kind", "clip"))))
    return bags


def export_one(bag: Path, t_from, t_to, fmt: str, out: Path, name: str, truck: float, check: bool) -> dict:
    """Export one range; print what was written (and checked). Returns the figures of the summary
    (``ok``: every check passed)."""
    import time

    from evoscen_eval.scenes import scenario_export as X

    t0 = time.perf_counter()
    ex = X.load_range(bag, t_from, t_to, truck_min_length_m=truck)
    path = X.write_xosc(ex, out, name) if fmt == "xosc" else X.write_commonroad(ex, out, name)
    pieces = sum(len(t.pieces) for t in ex.tracks)
    trucks = sum(t.klass == "truck" for t in ex.tracks)
    print(f"{path}: {len(ex.tracks)} vehicles ({trucks} trucks), {pieces} pieces, {ex.states} states "
          f"(t = {ex.t_from_s:.1f} .. {ex.t_from_s + ex.duration_s:.1f} s, dt {ex.dt_s:g} s)")
    res = {"path": path, "vehicles": len(ex.tracks), "states": ex.states, "ok": True, "asam_errors": None,
           "read_back": None, "collisions": None}
    if check:
        xosc_path = path if fmt == "xosc" else X.write_xosc(ex, out / ".check", name)
        if fmt == "xosc":
            errors = X.check_xosc(path)
            print(f"ASAM quality checker: {len(errors)} error(s)")
            for e in errors:
                print(f"  {e}")
            res["asam_errors"] = len(errors)
            res["ok"] = not errors
        else:
            obstacles, steps, problems = X.check_commonroad(ex, path)
            want = sum(len(t.pieces) for t in ex.tracks if t.role != X.C.ROLE_SUT)
            print(f"CommonRoad read back (commonroad-io): {obstacles} obstacles (exported {want}), {steps} time steps "
                  f"(exported {ex.states}); " + ("same" if not problems else "DIFFERENT"))
            for line in problems:
                print(f"  {line}")
            res["read_back"] = (obstacles, want, steps, ex.states)
            res["ok"] = not problems
        agree, lines = X.compare_collisions(ex, xosc_path)
        for line in lines:
            print(line)
        res["collisions"] = (len(ex.collisions), agree)
        res["ok"] = res["ok"] and agree
    res["seconds"] = time.perf_counter() - t0
    return res


def compare_start(bag: Path, t_from, truck: float, run_bag: Path) -> bool:
    """Print how the first state of ``run_bag`` compares with the range's first state; True when equal
    within 0.01 m and 0.01 m/s (docs/export.md "Starting evoscen from an exported scenario")."""
    from evoscen_eval.scenes import scenario_export as X
    from evoscen_sim.errors import InputError

    ex = X.load_range(bag, t_from, None, truck_min_length_m=truck)
    try:
        n, problems = X.compare_start(ex, run_bag, truck)
    except Exception as exc:  # noqa: BLE001 - an unreadable bag is one line (exit 2)
        raise InputError(f"--compare-start: {run_bag}: expected a readable bag ({type(exc).__name__}: {exc})") from None
    print(f"start from the export ({run_bag}): {n} vehicles compared (id, role, class, lane, position within "
          f"{X.START_TOLERANCE_M} m, speed within {X.START_TOLERANCE_MPS} m/s); "
          + ("same" if not problems else f"{len(problems)} difference(s)"))
    for line in problems:
        print(f"  {line}")
    return not problems


def summary_line(label: str, kind: str, res: dict) -> str:
    """One clip's line of the summary printed after a campaign's export (docs/export.md)."""
    parts = [f"{label}: {kind}, {res['vehicles']} vehicles, {res['states']} states"]
    if res["asam_errors"] is not None:
        parts.append(f"ASAM {res['asam_errors']} error(s)")
    if res["read_back"] is not None:
        obstacles, want, steps, states = res["read_back"]
        parts.append(f"read back {obstacles}/{want} obstacles, {steps}/{states} steps")
    if res["collisions"] is not None:
        n, agree = res["collisions"]
        parts.append(f"{n} collision(s) {'agree' if agree else 'DISAGREE'}")
    parts.append(f"{res['seconds']:.1f} s")
    if res["collisions"] is not None:
        parts.append("ok" if res["ok"] else "FAILED")
    return "; ".join(parts)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.scenes.scenario_export import FORMATS
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
            if args.compare_start is not None:
                raise InputError(f"{bag}: --compare-start: expected a bag, not a campaign directory")
            if t_from is not None or t_to is not None or args.out is not None:
                raise InputError(f"{bag}: --from/--to/--out: not for a campaign directory (each clip is exported "
                                 "whole into <clip>/export/)")
            rows = []
            for clip, kind in clips:
                res = export_one(clip, None, None, args.fmt, clip.parent / "export", args.name, truck, args.check)
                rows.append((clip, kind, res))
                ok &= res["ok"]
            print(f"summary ({args.fmt}{', checked' if args.check else ''}):")
            for clip, kind, res in rows:
                print("  " + summary_line(str(clip.parent.relative_to(bag) if clip.is_relative_to(bag) else clip.parent),
                                          kind, res))
            kinds = Counter(kind for _clip, kind, _res in rows)
            total = (f"{len(rows)} clip(s) exported ({', '.join(f'{n} {k}' for k, n in sorted(kinds.items()))}) "
                     f"in {sum(r['seconds'] for *_x, r in rows):.0f} s")
            if args.check:
                total += (f"; {sum(r['ok'] for *_x, r in rows)} passed, {sum(not r['ok'] for *_x, r in rows)} failed"
                          f"; collisions: {sum(r['collisions'][0] for *_x, r in rows)} in "
                          f"{sum(r['collisions'][0] > 0 for *_x, r in rows)} clip(s), "
                          f"{sum(r['collisions'][1] for *_x, r in rows)} clip(s) agree")
                if args.fmt == "xosc":
                    total += f"; ASAM errors: {sum(r['asam_errors'] for *_x, r in rows)}"
            print(total)
        else:
            out = Path(args.out) if args.out else (bag if bag.is_dir() else bag.parent).parent / "export"
            ok = export_one(bag, t_from, t_to, args.fmt, out, args.name, truck, args.check)["ok"]
            if args.compare_start is not None:
                ok &= compare_start(bag, t_from, truck, Path(args.compare_start))
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:
        print(f"error: {exc.filename or args.out}: cannot write the export: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return EXIT_OK if ok else 1  # a check failed (docs/export.md)


if __name__ == "__main__":
    sys.exit(main())
