"""A recorded run scored from its bag alone, its report written: ``scripts/evaluate.py``'s work
(docs/evaluation.md; a damaged bag: docs/recording.md, "Reindexing").

:func:`evaluate_bag` scores the bag in one pass under its recorded evaluation settings (or another
scenario's), says in a warning when the bag is not finished (and which command rebuilds it), writes
report.json, report.md and the plots, and prints the scores. Bad input is a one-line
:class:`~evoscen_sim.errors.InputError`; a report that cannot be written a
:class:`~evoscen_sim.errors.HostFault` naming the file.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

from evoscen_contract.contract import EXIT_OK
from evoscen_sim.errors import InputError


def animation_frames(text: str | None) -> int:
    """``--animation-frames``: a whole number >= 0 (None: the default, :data:`ANIMATION_FRAMES`)."""
    from evoscen_eval.scoring.animation import ANIMATION_FRAMES

    try:
        frames = ANIMATION_FRAMES if text is None else int(text)
        if frames < 0:
            raise ValueError
    except ValueError:
        raise InputError(f"--animation-frames: {text!r}: expected a whole number >= 0") from None
    return frames


def finished(bag_path: Path) -> bool:
    """The bag has its metadata.yaml (for a directory) and its MCAP summary: readers open it."""
    from evoscen_record.bag_reader import open_bag_reader

    if bag_path.is_dir() and not (bag_path / "metadata.yaml").is_file():
        return False
    try:
        open_bag_reader(bag_path).close()
    except InputError:
        return False
    return True


def _note_unfinished(bag_path: Path, warnings: list[str], option: str | None = "--reindex") -> None:
    """Name the command that rebuilds an unfinished bag in its warning (a new one if the reader had none);
    ``option``: the caller's own option that runs it (None: none)."""
    hint = (f"; to rebuild its summary and metadata.yaml: python scripts/reindex.py {bag_path}"
            + (f" (or {option})" if option else ""))
    damaged = [k for k, w in enumerate(warnings) if "truncated or corrupt" in w]
    if damaged:
        warnings[damaged[0]] += hint
    else:
        warnings.append(f"bag {str(bag_path)!r} is not finished (no summary section or no "
                        f"metadata.yaml: the recorder was killed?)" + hint)


def bag_warnings(bag_path: Path, warnings: list[str], *, reindexed: bool = False,
                 option: str | None = "--reindex") -> list[str]:
    """The warnings a reader gave on ``bag_path``, an unfinished bag's naming the command that rebuilds it
    (``option``: the caller's option that runs it), as ``evaluate.py`` prints them (``warning: ...`` on
    stderr, one line each). Returns ``warnings`` (completed in place)."""
    if not reindexed and not finished(bag_path):
        _note_unfinished(bag_path, warnings, option)
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return warnings


def evaluate_bag(bag_path: Path, *, out: Path | None = None, config: Path | None = None, overwrite: bool = False,
                 plots: bool = True, frames: str | None = None, reindex: bool = False) -> int:
    """Score the run in ``bag_path`` (a bag directory or its .mcap file) and write its report to ``out``
    (default ``<the bag's directory>/../report_offline``; a non-empty one replaced only with
    ``overwrite``), with the ``evaluation`` section of the scenario file ``config`` if given; with
    ``reindex`` the bag is rebuilt first (:func:`evoscen_record.reindex.reindex_bag`). Prints the scores
    and where the report is; returns :data:`EXIT_OK`."""
    from evoscen_eval.scoring.report import write_stream_report
    from evoscen_eval.scoring.report_text import score_lines
    from evoscen_eval.scoring.rundata import score_bag
    from evoscen_sim.config.scenario_config import load_scenario_config

    n_frames = animation_frames(frames)
    override = load_scenario_config(config).evaluation if config is not None else None
    if not bag_path.exists():
        raise InputError(f"bag {str(bag_path)!r}: no such bag directory or .mcap file")
    if reindex:
        from evoscen_record.reindex import reindex_bag

        r = reindex_bag(bag_path)
        print(f"reindexed: {r.messages} messages, {r.steps} world states recovered", file=sys.stderr)
    run = score_bag(bag_path, override)  # one pass: memory independent of the run's length
    bag_dir = bag_path if bag_path.is_dir() else bag_path.parent
    out = out if out is not None else bag_dir.resolve().parent / "report_offline"
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        if not overwrite or not out.is_dir():
            raise InputError(f"--out {out}: exists and is not empty; choose another --out or pass --overwrite")
        shutil.rmtree(out)
    bag_warnings(bag_path, run.warnings, reindexed=reindex)
    report = write_stream_report(run.stream, run.info, run.warnings, out, plots=plots, source=str(bag_path),
                                 lane_segments=run.lane_segments, animation_frames=n_frames)
    print(f"{report['run']['steps']} steps scored")
    for line in score_lines(report):  # D first (docs/evaluation.md §10)
        print(line)
    print(f"report: {out / 'report.md'}")
    return EXIT_OK
