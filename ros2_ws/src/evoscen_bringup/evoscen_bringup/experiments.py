"""Campaigns of in-process rounds: parallel, resumable, summarised with 95 % intervals.

A *round* is one in-process run of a scenario configuration (no bag), scored like every run
(:mod:`evoscen_eval.metrics`). The method's experiments (``scripts/experiment_intelligence.py``,
``scripts/experiment_complexity.py``) are lists of rounds run by :func:`run_rounds`:

* **parallel** — rounds run in ``jobs`` worker processes (one round per process at a time);
* **resumable** — each finished round is saved as ``OUT/rounds/<label>-seed<S>-<hash>.json``,
  where the hash is of the round's whole resolved configuration; a file that exists is read
  back instead of running the round again, and a changed setting (steps, model parameters,
  evaluation settings …) gives a new hash, so a stale result is never reused;
* **summarised** — :func:`mean_ci` gives mean ± the half-width of the 95 % Student-t interval
  over rounds (seeds).

Each saved round holds its ``report.json`` dict plus histograms of the SUT's TTC and speed
(:data:`TTC_BINS`, :data:`SPEED_BINS`) for the distribution plots.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from evoscen_eval.streaming import SPEED_BINS, TTC_BINS  # noqa: F401 - the histograms' bins (the plots read them here)
from evoscen_sim.config import ScenarioConfig, config_to_dict


@dataclass(frozen=True)
class Round:
    """One round: a label (the table row it belongs to) and its full configuration."""

    label: str
    cfg: ScenarioConfig

    @property
    def key(self) -> str:
        """File stem: label, seed and a hash of the whole resolved configuration."""
        text = yaml.safe_dump(config_to_dict(self.cfg), sort_keys=True)
        digest = hashlib.sha1(text.encode("utf-8")).hexdigest()[:10]
        return f"{self.label}-seed{self.cfg.seed}-{digest}"


def run_round(rnd: Round) -> dict[str, Any]:
    """Run and score one round (in this process); returns what is saved for it."""
    from .inprocess import run_inprocess

    summary = run_inprocess(rnd.cfg, bag_dir=None, evaluate=True)
    plot = summary.plot  # the SUT's TTC and speed distributions, over TTC_BINS and SPEED_BINS
    return {
        "label": rnd.label,
        "seed": rnd.cfg.seed,
        "steps": summary.steps,
        "wall_time_s": summary.wall_time_s,
        "report": summary.report,
        "ttc_hist": plot.ttc_hist.tolist(),
        "speed_hist": plot.speed_hist.tolist(),
    }


def _work(args: tuple[Round, str]) -> tuple[str, dict[str, Any]]:
    rnd, path = args
    result = run_round(rnd)
    tmp = Path(path).with_suffix(".json.tmp")
    tmp.write_text(json.dumps(result, allow_nan=False), encoding="utf-8")
    os.replace(tmp, path)  # a round file is complete or absent, never half-written
    return rnd.key, result


def run_rounds(rounds: Sequence[Round], out_dir: Path, *, jobs: int = 1,
               progress: Callable[[int, int, str], None] | None = None) -> dict[str, dict[str, Any]]:
    """Run the rounds not finished yet (``jobs`` processes); returns every round's result by key.

    ``progress(done, total, text)`` is called as rounds finish (the cached ones first).
    """
    rounds_dir = out_dir / "rounds"
    rounds_dir.mkdir(parents=True, exist_ok=True)
    results: dict[str, dict[str, Any]] = {}
    todo: list[tuple[Round, str]] = []
    for rnd in rounds:
        path = rounds_dir / f"{rnd.key}.json"
        saved = _saved_result(path)
        if saved is not None:
            results[rnd.key] = saved
        else:
            todo.append((rnd, str(path)))
    total = len(rounds)
    if progress is not None:
        progress(len(results), total, f"{len(results)} rounds already done")
    if not todo:
        return results
    if jobs <= 1 or len(todo) == 1:
        for item in todo:
            key, result = _work(item)
            results[key] = result
            if progress is not None:
                progress(len(results), total, _brief(result))
        return results
    import multiprocessing as mp

    with mp.get_context("fork").Pool(processes=min(jobs, len(todo)), maxtasksperchild=1) as pool:
        for key, result in pool.imap_unordered(_work, todo):
            results[key] = result
            if progress is not None:
                progress(len(results), total, _brief(result))
    return results


T = TypeVar("T")


def positive_int(name: str, text: str, lo: int = 1) -> int:
    """The integer ``text`` of option ``name``, at least ``lo`` (else a one-line InputError)."""
    from evoscen_sim.errors import InputError

    try:
        value = int(text)
    except ValueError:
        value = lo - 1
    if value < lo:
        raise InputError(f"{name} = {text!r}: expected an integer >= {lo}")
    return value


def distinct_names(option: str, text: str, what: str = "names") -> list[str]:
    """The comma-separated ``text`` of ``option`` as a list: non-empty, no name twice (else a one-line InputError)."""
    from evoscen_sim.errors import InputError

    names = [s.strip() for s in text.split(",") if s.strip()]
    if not names or len(set(names)) != len(names):
        raise InputError(f"{option} {text!r}: expected distinct comma-separated {what}")
    return names


def set_up(out_dir: Path, build: Callable[[], T]) -> T | None:
    """An experiment's set-up: ``build()`` (argument checks, the rounds), then ``out_dir`` created.

    None after a one-line error on stderr (the caller exits with ``EXIT_BAD_INPUT``): an
    :class:`evoscen_sim.errors.InputError`, or an ``OSError`` (``out_dir`` cannot be created).
    """
    import sys

    from evoscen_sim.errors import InputError

    try:
        built = build()
        out_dir.mkdir(parents=True, exist_ok=True)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return None
    except OSError as exc:
        print(f"error: --out {out_dir}: cannot create: {exc.strerror or exc}", file=sys.stderr)
        return None
    return built


def _saved_result(path: Path) -> dict[str, Any] | None:
    """A finished round's saved result; None if there is none or it cannot be read (the round runs again)."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return None


def run_rounds_with_bar(rounds: Sequence[Round], out_dir: Path, *, jobs: int, desc: str
                        ) -> dict[str, dict[str, Any]] | None:
    """:func:`run_rounds` behind a tqdm progress bar (stderr); None after Ctrl-C (finished rounds are kept)."""
    import sys

    from tqdm import tqdm

    bar = tqdm(total=len(rounds), unit="round", desc=desc, file=sys.stderr)

    def progress(done: int, total: int, text: str) -> None:
        bar.n = done
        bar.set_postfix_str(text)
        bar.refresh()

    try:
        return run_rounds(rounds, out_dir, jobs=jobs, progress=progress)
    except KeyboardInterrupt:
        bar.close()
        print(f"interrupted: finished rounds are kept in {out_dir / 'rounds'}; run again to continue",
              file=sys.stderr)
        return None
    finally:
        bar.close()


def _brief(result: dict[str, Any]) -> str:
    r = result["report"]
    c = r["complexity"]["score"]
    return (f"{result['label']} seed {result['seed']}: I={r['intelligence']['score']:.3f}"
            + ("" if c is None else f" C={c:.3f}"))


def mean_ci(values: Sequence[float]) -> tuple[float, float]:
    """Mean and the half-width of its 95 % Student-t interval (``nan`` with fewer than 2 values)."""
    x = np.asarray([v for v in values if v is not None], dtype=float)
    if x.size == 0:
        return math.nan, math.nan
    if x.size < 2:
        return float(x.mean()), math.nan
    from scipy import stats

    half = float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return float(x.mean()), half


def fmt_ci(mean: float, half: float, digits: int = 4) -> str:
    """``mean ± half`` (just the mean when the interval is undefined)."""
    if math.isnan(mean):
        return "–"
    return f"{mean:.{digits}f}" if math.isnan(half) else f"{mean:.{digits}f} ± {half:.{digits}f}"


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """A CSV file (``csv`` module quoting)."""
    import csv

    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
