"""A run's time range, or every critical-event clip of a run or campaign, exported with its checks and
summary: ``scripts/export_scenario.py``'s work (docs/export.md; the files themselves are written by
:mod:`evoscen_eval.scenes.scenario_export`).

:func:`export_command` exports one bag's range (given, or around a collision or exposure: ``--event``,
:mod:`evoscen_eval.scenes.event_ranges`; and compares a run started from it, ``--compare-start``) or each
clip listed under a campaign run or output (``clips.json``), printing what was written and checked and,
for a campaign, a summary line per clip and a total; a damaged bag and a range holding the traffic
window's shift are ``warning:`` lines on stderr. It returns 0, or 1 when a check failed; bad input is a
one-line :class:`~evoscen_sim.errors.InputError`. Nothing is left beside the export but its files.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from evoscen_contract.contract import EXIT_OK
from evoscen_sim.errors import InputError

CHECK_FAILED = 1
"""The exit status when a check of the export failed (docs/export.md)."""


def number(flag: str, value: str | None) -> float | None:
    """The finite number ``value`` of ``flag`` (None stays None)."""
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


def _check(ex, path: Path, fmt: str, name: str, res: dict) -> None:
    """``--check`` of one export: the ASAM checker (xosc) or commonroad-io's read-back, then the
    independent collision check; the figures go into ``res``."""
    from evoscen_eval.scenes import scenario_export as X

    if fmt != "xosc":  # the box check reads an OpenSCENARIO file: one written where nothing is left behind
        with tempfile.TemporaryDirectory(prefix="evoscen-check-") as tmp:
            return _check_files(ex, path, X.write_xosc(ex, tmp, name), fmt, res)
    return _check_files(ex, path, path, fmt, res)


def _check_files(ex, path: Path, xosc_path: Path, fmt: str, res: dict) -> None:
    """:func:`_check` on the written ``path`` and an OpenSCENARIO file of the same range, ``xosc_path``."""
    from evoscen_eval.scenes import scenario_export as X

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


def export_one(bag: Path, t_from, t_to, fmt: str, out: Path, name: str, truck: float, check: bool) -> dict:
    """Export one range; print what was written (and checked), and as warnings what the bag reader
    found damaged (:func:`~evoscen_eval.scoring.bag_report.bag_warnings`, as ``evaluate.py``) and the
    shifts the range holds. Returns the figures of the summary (``ok``: every check passed)."""
    from evoscen_eval.scenes import scenario_export as X
    from evoscen_eval.scenes.event_ranges import shift_warning
    from evoscen_eval.scoring.bag_report import bag_warnings

    t0 = time.perf_counter()
    ex = X.load_range(bag, t_from, t_to, truck_min_length_m=truck)
    # a clip holds no run_end event: that is no damage (its range is printed below)
    bag_warnings(bag, [w for w in ex.warnings if "has no run_end event" not in w], option=None)
    shifted = shift_warning(ex.t_from_s, ex.t_from_s + ex.duration_s, ex.shifts)
    if shifted:
        print(f"warning: {shifted}", file=sys.stderr)
    path = X.write_xosc(ex, out, name) if fmt == "xosc" else X.write_commonroad(ex, out, name)
    pieces = sum(len(t.pieces) for t in ex.tracks)
    trucks = sum(t.klass == "truck" for t in ex.tracks)
    print(f"{path}: {len(ex.tracks)} vehicles ({trucks} trucks), {pieces} pieces, {ex.states} states "
          f"(t = {ex.t_from_s:.1f} .. {ex.t_from_s + ex.duration_s:.1f} s, dt {ex.dt_s:g} s)")
    res = {"path": path, "vehicles": len(ex.tracks), "states": ex.states, "ok": True, "asam_errors": None,
           "read_back": None, "collisions": None}
    if check:
        _check(ex, path, fmt, name, res)
    res["seconds"] = time.perf_counter() - t0
    return res


def compare_start(bag: Path, t_from, truck: float, run_bag: Path) -> bool:
    """Print how the first state of ``run_bag`` compares with the range's first state; True when equal
    within 0.01 m and 0.01 m/s (docs/export.md "Starting evoscen from an exported scenario")."""
    from evoscen_eval.scenes import scenario_export as X

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


def export_clips(root: Path, clips: list[tuple[Path, str]], fmt: str, name: str, truck: float, check: bool) -> bool:
    """Export every clip whole into ``<clip>/export/``; print a summary line per clip and the total.
    True when every check passed."""
    rows = []
    for clip, kind in clips:
        rows.append((clip, kind, export_one(clip, None, None, fmt, clip.parent / "export", name, truck, check)))
    print(f"summary ({fmt}{', checked' if check else ''}):")
    for clip, kind, res in rows:
        print("  " + summary_line(str(clip.parent.relative_to(root) if clip.is_relative_to(root) else clip.parent),
                                  kind, res))
    kinds = Counter(kind for _clip, kind, _res in rows)
    results = [r for *_x, r in rows]
    total = (f"{len(rows)} clip(s) exported ({', '.join(f'{n} {k}' for k, n in sorted(kinds.items()))}) "
             f"in {sum(r['seconds'] for r in results):.0f} s")
    if check:
        total += (f"; {sum(r['ok'] for r in results)} passed, {sum(not r['ok'] for r in results)} failed"
                  f"; collisions: {sum(r['collisions'][0] for r in results)} in "
                  f"{sum(r['collisions'][0] > 0 for r in results)} clip(s), "
                  f"{sum(r['collisions'][1] for r in results)} clip(s) agree")
        if fmt == "xosc":
            total += f"; ASAM errors: {sum(r['asam_errors'] for r in results)}"
    print(total)
    return all(r["ok"] for r in results)


def event_window(bag: Path, event: str, around: str | None) -> tuple[float, float]:
    """``--event``/``--around``: the range around the run's collision or exposure ``event``, on the side of
    every shift that holds it (:func:`~evoscen_eval.scenes.event_ranges.event_range`); prints which event
    and range, and a line when the range was moved off a shift."""
    from evoscen_eval.scenes import event_ranges as R
    from evoscen_eval.scoring.rundata import read_run

    half = R.AROUND_S if around is None else number("--around", around)
    if half <= 0:
        raise InputError(f"--around: {around}: expected seconds > 0")
    run = read_run(bag)
    picked = R.pick_event(R.critical_events(run), event)
    lo, hi, note = R.event_range(picked, half, (float(run.time_s[0]), float(run.time_s[-1])), R.shifts_of(run),
                                 float(run.dt_s))
    print(f"event {picked.number}: {picked.label}; range {lo:.1f} .. {hi:.1f} s"
          + ("" if note else f" ({half:g} s either side, within the bag)"))
    if note:
        print(note)
    return lo, hi


def export_command(bag: str, *, fmt: str = "xosc", t_from: str | None = None, t_to: str | None = None,
                   out: str | None = None, name: str = "scenario", truck_length_m: str = "7.0",
                   compare_start_bag: str | None = None, check: bool = False, event: str | None = None,
                   around: str | None = None) -> int:
    """``scripts/export_scenario.py`` (its docstring): the arguments as the command line gives them
    (text); returns 0, or 1 when a check failed. An export that cannot be written is a one-line
    InputError naming the file."""
    from evoscen_eval.scenes.scenario_export import FORMATS

    try:
        if fmt not in FORMATS:
            raise InputError(f"--format: {fmt!r}: expected one of {', '.join(FORMATS)}")
        if event is not None and (t_from is not None or t_to is not None):
            raise InputError("--event: not with --from/--to (the range is the event's, --around seconds either side)")
        if around is not None and event is None:
            raise InputError("--around: needs --event N (the seconds kept on either side of that event)")
        start, end = number("--from", t_from), number("--to", t_to)
        truck = number("--truck-length-m", truck_length_m)
        if truck <= 0:
            raise InputError(f"--truck-length-m: {truck_length_m}: expected a length > 0 (m)")
        path = Path(bag)
        if not path.exists():
            raise InputError(f"{path}: no such bag, bag directory or campaign directory")
        clips = clip_bags(path) if path.is_dir() else None
        if clips is not None:
            if compare_start_bag is not None:
                raise InputError(f"{path}: --compare-start: expected a bag, not a campaign directory")
            if start is not None or end is not None or out is not None or event is not None:
                raise InputError(f"{path}: --from/--to/--event/--out: not for a campaign directory (each clip is "
                                 "exported whole into <clip>/export/)")
            ok = export_clips(path, clips, fmt, name, truck, check)
        else:
            if event is not None:
                start, end = event_window(path, event, around)
            where = Path(out) if out else (path if path.is_dir() else path.parent).parent / "export"
            ok = export_one(path, start, end, fmt, where, name, truck, check)["ok"]
            if compare_start_bag is not None:
                ok &= compare_start(path, start, truck, Path(compare_start_bag))
    except OSError as exc:
        raise InputError(f"{exc.filename or out}: cannot write the export: {exc.strerror or exc}") from None
    return EXIT_OK if ok else CHECK_FAILED
