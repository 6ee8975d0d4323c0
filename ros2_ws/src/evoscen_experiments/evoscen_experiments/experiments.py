"""The method's experiments as lists of in-process rounds, run on the campaign engine, summarised with 95 % intervals.

A *round* is one in-process run of a scenario configuration (no bag), scored like every run
(:mod:`evoscen_eval.scoring.metrics`). The experiments (:mod:`evoscen_experiments.intelligence_experiment`,
``complexity_experiment``, ``sensitivity_experiment``, ``leaderboard``) are lists of rounds run by
:func:`run_rounds` on the one execution path of many runs, :mod:`evoscen_experiments.campaign`
(docs/campaigns.md):

* **parallel** — Ray tasks of one CPU, ``jobs`` workers on a local Ray; the rounds that begin from
  the same state (the SUT variants of a seed: :func:`evoscen_bringup.starts.start_key`) go to one
  task together, which computes their warm-up once (docs/performance.md "Experiments");
* **resumable** — each finished round is saved under ``OUT/runs/<key>/`` (``result.json``,
  ``report.json``, ``plot.json``), the key a hash of the round's whole resolved configuration,
  of the code version and of the plug-in the round uses; a round whose result exists is read back
  instead of run again, and a changed setting (steps, model parameters, evaluation settings …),
  changed code or a changed plug-in gives a new key, so a stale result is never reused;
* **summarised** — :func:`mean_ci` gives mean ± the half-width of the 95 % Student-t interval
  over rounds (seeds).

Each round's result holds its ``report.json`` dict plus histograms of the SUT's TTC and speed
(:data:`TTC_BINS`, :data:`SPEED_BINS`) for the distribution plots.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from evoscen_eval.scoring.plot_inputs import SPEED_BINS, TTC_BINS  # noqa: F401 - the histograms' bins (the plots read them here)
from evoscen_sim.config.scenario_config import ScenarioConfig

from evoscen_experiments.stats import difference_words, fmt_ci, markdown_table, mean_ci  # noqa: F401 - the experiments' scripts import them from here


@dataclass(frozen=True)
class Round:
    """One round: a label (the table row it belongs to) and its full configuration."""

    label: str
    cfg: ScenarioConfig

    @functools.cached_property
    def key(self) -> str:
        """The round's campaign key (:func:`evoscen_experiments.campaign_spec.run_key`: configuration, code version,
        plug-ins), worked out once (the experiments look it up many times)."""
        from evoscen_experiments.campaign_spec import code_version, run_key

        return run_key(self.cfg, code_version())


def batch_option(args: Any) -> int | None:
    """An experiment command's ``--batch N`` (:func:`evoscen.cli.add_jobs`): at least 1, else a one-line InputError
    naming it; None when not given."""
    text = getattr(args, "batch", None)
    return None if text is None else positive_int("--batch", str(text).strip())


def run_rounds(rounds: Sequence[Round], out_dir: Path, *, jobs: int = 1,
               progress: Callable[[int, int, str], None] | None = None,
               failures: dict[str, str] | None = None, batch: int | None = None) -> dict[str, dict[str, Any]]:
    """Run the rounds not finished yet on a local Ray of ``jobs`` workers; returns every round's
    result by key (``label``, ``seed``, ``steps``, ``wall_time_s``, ``report``, ``ttc_hist``,
    ``speed_hist``). ``progress(done, total, text)`` as rounds finish (the saved ones first).
    KeyboardInterrupt after Ctrl-C (finished rounds are kept); RuntimeError naming the rounds
    that failed after their retries — unless ``failures`` is given: then each failed round's
    error (one line: the exception's type and first line) goes into it by key, and the
    returned dict has the rounds that finished. ``batch``: at most this many rounds of one start per Ray task,
    stepped in lockstep in its worker; None: :data:`~evoscen_experiments.campaign.BATCH_RUNS` per task, in lockstep
    as :data:`~evoscen_experiments.campaign.LOCKSTEP` says. The results are the same.
    """
    from evoscen_experiments.campaign import load_result, result_path, run_campaign
    from evoscen_experiments.campaign_spec import CampaignRun
    from evoscen_bringup.starts import start_key

    runs = [CampaignRun(rnd.key, (("label", rnd.label),), rnd.cfg.seed, rnd.cfg) for rnd in rounds]
    total = len(runs)
    done = sum(result_path(out_dir, r.key).exists() for r in runs)
    if progress is not None:
        progress(done, total, f"{done} rounds already done")

    def tick(n: int, _total: int, rate: float, steps_per_s: float) -> None:  # over the command's wall
        if progress is not None:
            progress(n, total, f"{rate:.2f} rounds/s, {steps_per_s:,.0f} SUT-steps/s")

    # rounds record no bag: their BVs are driven by one driver (partitioned=False, as campaign._simulate)
    from evoscen_experiments.campaign import BATCH_RUNS, LOCKSTEP

    size, lockstep = (BATCH_RUNS, LOCKSTEP) if batch is None else (int(batch), True)
    result = (run_campaign(runs, out_dir, cpus=jobs, progress=tick, group=lambda r: start_key(r.cfg, partitioned=False),
                           batch_runs=size, lockstep=lockstep) if done < total else None)
    if result is not None and result.interrupted:
        raise KeyboardInterrupt
    if result is not None and result.failed:
        if failures is None:
            raise RuntimeError(f"{len(result.failed)} round(s) failed: {result.failed[0]}")
        for line in result.failed:  # "<key> (<cell>, seed <s>): <error>"
            key, _, rest = line.partition(" ")
            failures[key] = rest.split("): ", 1)[-1]
    out = {}
    for rnd, run in zip(rounds, runs):
        if failures is not None and rnd.key in failures:
            continue
        saved = load_result(out_dir, run.key)
        row = saved["row"]
        out[rnd.key] = {"label": rnd.label, "seed": rnd.cfg.seed, "steps": row["steps"],
                        "wall_time_s": row["wall_time_s"], "report": saved["report"], **saved["plot"]}
    return out


COMPARATIVE_CHALLENGE = "nade"
"""The ``challenge.mode`` of the comparative experiments' runs (sensitivity, leaderboard; their ``--challenge``):
[choice] the challenge scenario, a harder test the same for both members of a pair (docs/challenges.md)."""


def challenge_mode(text: str | None) -> str:
    """The ``--challenge`` option's mode (None: :data:`COMPARATIVE_CHALLENGE`); else a one-line InputError."""
    from evoscen_sim.config.config_schema import CHALLENGE_MODES
    from evoscen_sim.errors import InputError

    mode = COMPARATIVE_CHALLENGE if text is None else str(text).strip()
    if mode not in CHALLENGE_MODES:
        raise InputError(f"--challenge: expected one of {', '.join(CHALLENGE_MODES)}, got {text!r}")
    return mode


def config_loader(path: Path | None, challenge: str | None = None) -> Callable[[Mapping[str, object]], ScenarioConfig]:
    """``load(overrides)``: :func:`~evoscen_sim.config.scenario_config.load_scenario_config` of ``path`` (None:
    the shipped default) with ``overrides`` (and, with ``challenge``, ``challenge.mode`` set to it), the file
    read and parsed once for all the rounds of an experiment (parsing is ~50-80 ms a round; the validation,
    which every round still gets, ~1 ms)."""
    from evoscen_sim.config.config_load import _DEFAULT_CONFIG, config_from_dict, parse_yaml
    from evoscen_sim.limits import MAX_CONFIG_BYTES, read_text_limited
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.share import share_path

    parsed: list = []

    def load(overrides: Mapping[str, object]) -> ScenarioConfig:
        if challenge is not None:
            overrides = {**overrides, "challenge.mode": challenge}
        if not parsed:  # the first round as the one-call loader does it (every error alike), then parsed once
            cfg = load_scenario_config(path, overrides)
            file_path = share_path(_DEFAULT_CONFIG) if path is None else Path(path)
            label = str(path) if path is not None else str(file_path)
            text = read_text_limited(file_path, label, "scenario config file", MAX_CONFIG_BYTES)
            parsed.append((*parse_yaml(text, label), label, file_path.resolve().parent))
            return cfg
        data, lines, label, base_dir = parsed[0]
        return config_from_dict(data, source=label, base_dir=base_dir, overrides=overrides, _lines=lines)

    return load


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


def key_values(option: str, items: Sequence[str]) -> dict[str, str]:
    """The ``KEY=VALUE`` items of a repeated option (``--set``) as a dict, key and value stripped (a one-line
    InputError naming the option on an item without ``=`` or key)."""
    from evoscen_sim.errors import InputError

    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise InputError(f"{option} {item!r}: expected KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


def set_up(out_dir: Path, build: Callable[[], T]) -> T:
    """An experiment's set-up: ``build()`` (argument checks, the rounds), then ``out_dir`` created.

    A one-line :class:`evoscen_sim.errors.InputError` before anything is written: ``build()``'s own, or
    ``out_dir`` cannot be created (the script says it and exits with ``EXIT_BAD_INPUT``).
    """
    from evoscen_sim.errors import InputError

    built = build()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out_dir}: cannot create: {exc.strerror or exc}") from None
    return built


def run_rounds_with_bar(rounds: Sequence[Round], out_dir: Path, *, jobs: int, desc: str,
                        failures: dict[str, str] | None = None, batch: int | None = None
                        ) -> dict[str, dict[str, Any]] | None:
    """:func:`run_rounds` behind a tqdm progress bar (stderr); None after Ctrl-C (finished rounds are kept).
    ``failures``: as for :func:`run_rounds` (failed rounds collected, not fatal)."""
    import sys

    from tqdm import tqdm

    bar = tqdm(total=len(rounds), unit="round", desc=desc, file=sys.stderr)

    def progress(done: int, total: int, text: str) -> None:
        bar.n = done
        bar.set_postfix_str(text)
        bar.refresh()

    try:
        return run_rounds(rounds, out_dir, jobs=jobs, progress=progress, failures=failures, batch=batch)
    except KeyboardInterrupt:
        bar.close()
        print(f"interrupted: finished rounds are kept in {out_dir / 'runs'}; run again to continue",
              file=sys.stderr)
        return None
    except RuntimeError as exc:  # rounds that failed after their retries: named, the rest kept
        bar.close()
        from evoscen_contract.contract import EXIT_FAULT

        print(f"error: {exc}; finished rounds are kept in {out_dir / 'runs'}", file=sys.stderr)
        raise SystemExit(EXIT_FAULT) from None
    finally:
        bar.close()


def write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """A CSV file (``csv`` module quoting)."""
    import csv

    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
