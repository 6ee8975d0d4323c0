"""Run an experiment from Python: the face's third entry point (docs/experiments.md).

:func:`run_experiment` is ``scripts/experiment_intelligence.py`` or ``scripts/experiment_sensitivity.py``
without the command line: the same options (each door builds its parser with the functions here, so
their names and defaults are defined once), the same checks and outputs, and the tables it wrote
returned as rows::

    result = evoscen.run_experiment("intelligence", out="runs/compare", suts=["mobil", "nilsson"],
                                    seeds=10, first_seed=882000, jobs=2)
    for row in result.tables["paired"]: print(row["sut_a"], row["sut_b"], row["delta_d_mean"])

A bad option is one :class:`~evoscen_sim.errors.InputError` line naming it, before anything runs.
"""

from __future__ import annotations

import argparse
import csv
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from evoscen import cli

KINDS = ("intelligence", "sensitivity")
"""The experiments :func:`run_experiment` runs: SUTs compared on the same seeds; SUTs against their mutants."""


def intelligence_parser(doc: str | None = None) -> argparse.ArgumentParser:
    """The options of the intelligence experiment (``scripts/experiment_intelligence.py``)."""
    ap = cli.parser("experiment_intelligence.py", doc, ranks_by="D")
    cli.add_out(ap, "runs/experiment_intelligence")
    cli.add_config(ap)
    ap.add_argument("--suts", default="nilsson,mobil,stackelberg", help="comma-separated SUT models")
    cli.add_seeds(ap, count=5, what="seeds per SUT")
    cli.add_steps(ap, 3000)
    ap.add_argument("--mix", default="4:3:3", help="BV policy mix competitive:mutual:cooperative (default 4:3:3)")
    ap.add_argument("--bvs", default="20", help="number of BVs (default 20)")
    cli.add_jobs(ap)
    return ap


def sensitivity_parser(doc: str | None = None) -> argparse.ArgumentParser:
    """The options of the sensitivity experiment (``scripts/experiment_sensitivity.py``)."""
    from evoscen_experiments.sensitivity_experiment import DEFAULT_DESIGN, EPISODE_STEPS, EPISODES, SEEDS, STEPS

    ap = cli.parser("experiment_sensitivity.py", doc, ranks_by="D")
    cli.add_out(ap, "runs/experiment_sensitivity")
    cli.add_config(ap)
    ap.add_argument("--base", default="mobil", help="comma-separated intact SUT models (default mobil)")
    ap.add_argument("--challenge", default="nade", help="challenge.mode of every run, over the config's: nade "
                    "(default: the challenge scenario, docs/challenges.md), naturalistic or none")
    ap.add_argument("--mutants", default="all", help="'all' or comma-separated mutant names of the library")
    ap.add_argument("--scenarios", default="evolving,level0,nilsson,mobil",
                    help="comma-separated: evolving (the config's BV driver) and/or BV driver names")
    ap.add_argument("--design", help=f"episodes (--episodes short runs of --episode-steps) or long (--seeds runs of "
                                     f"--steps); default: the design whose flags are given, else {DEFAULT_DESIGN}")
    ap.add_argument("--episodes", help=f"episodes design: episodes (seeds) per SUT variant and scenario "
                                       f"(default {EPISODES})")
    ap.add_argument("--episode-steps", help=f"episodes design: steps per episode (default {EPISODE_STEPS})")
    ap.add_argument("--seeds", help=f"long design: seeds per SUT variant and scenario (default {SEEDS})")
    ap.add_argument("--steps", help=f"long design: steps per run (default {STEPS})")
    ap.add_argument("--first-seed", default="0", help="first seed (default 0; with --compare-designs the episodes')")
    ap.add_argument("--long-first-seed", help="with --compare-designs: the long design's first seed (default: the "
                                              "seed after the episodes')")
    ap.add_argument("--blocks", help="seed blocks: this many blocks of --block-size seeds each, one after the other "
                                     "from --first-seed (replaces --episodes/--seeds; default: one block)")
    ap.add_argument("--block-size", help="seeds (episodes, or long runs) per block (default: the design's "
                                         f"--episodes {EPISODES} or --seeds {SEEDS})")
    ap.add_argument("--seed-blocks", help="explicit seed blocks 'A:B,C:D' (seeds A..B and C..D, both ends included, "
                                          "disjoint); replaces --first-seed, --blocks, --block-size; with "
                                          "--sequential one design per block, its budget at most the block's seeds")
    ap.add_argument("--compare-designs", action="store_true",
                    help="run both designs at equal SUT steps and compare their detection")
    add_sequential(ap, "sequential verdicts: rounds of --round-size paired episodes (seeds from --first-seed on, "
                       "or from each --seed-blocks block's first), "
                       "each (base, mutant) comparison stopped at its verdict (worse, better, equivalent on D, "
                       "the comparative score) or unresolved at --budget")
    cli.add_jobs(ap)
    return ap


def add_sequential(ap: argparse.ArgumentParser, what: str) -> None:
    """The sequential design's options (``--sequential``, its help ``what``, and ``--budget``, ``--round-size``,
    ``--delta``, ``--spending``), shared by the sensitivity experiment and the leaderboard."""
    from evoscen_experiments.sensitivity_sequential import BUDGET, DELTA, ROUND_SIZE, SPENDING_DEFAULT

    ap.add_argument("--sequential", action="store_true", help=what)
    ap.add_argument("--budget", help=f"with --sequential: most paired episodes per comparison (default {BUDGET})")
    ap.add_argument("--round-size", help=f"with --sequential: paired episodes between looks (default {ROUND_SIZE})")
    ap.add_argument("--delta", help=f"with --sequential: equivalence margin on D (default {DELTA})")
    ap.add_argument("--spending", help=f"with --sequential: alpha spending, pocock or obrien_fleming "
                                       f"(default {SPENDING_DEFAULT})")


def _mains() -> dict[str, tuple[Callable[[], argparse.ArgumentParser], Callable[[argparse.Namespace], int]]]:
    from evoscen_experiments import intelligence_experiment, sensitivity_experiment

    return {"intelligence": (intelligence_parser, intelligence_experiment.main),
            "sensitivity": (sensitivity_parser, sensitivity_experiment.main)}


@dataclass
class ExperimentResult:
    """What an experiment left: its exit status, its directory and the CSV tables it wrote there, each a
    list of rows (column -> text, as in the file), by file name without ``.csv``."""

    kind: str
    status: int
    out: Path
    tables: dict[str, list[dict[str, str]]] = field(default_factory=dict)


def argv_of(options: dict[str, object]) -> list[str]:
    """Keyword options as the command line: ``first_seed=5`` -> ``--first-seed 5``, a list -> its items joined
    by commas, ``True`` -> the flag alone, ``False`` or None -> left out."""
    argv: list[str] = []
    for key, value in options.items():
        flag = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            argv.append(flag)
        elif isinstance(value, (list, tuple)):
            argv += [flag, ",".join(str(v) for v in value)]
        else:
            argv += [flag, str(value)]
    return argv


def run_experiment(kind: str, *, out: str | Path, **options: object) -> ExperimentResult:
    """Run the experiment ``kind`` (one of :data:`KINDS`) into ``out`` with the options of its script
    (``suts=["mobil", "nilsson"]``, ``seeds=10``, ``first_seed=882000``, ``jobs=2``, ...); return its status
    and tables. An interrupted experiment continues where it stopped when run again into the same ``out``."""
    from evoscen_sim.errors import InputError

    mains = _mains()
    if kind not in mains:
        raise InputError(f"experiment {kind!r}: expected one of {', '.join(KINDS)}")
    make_parser, main = mains[kind]
    parser = cli.one_line_errors(make_parser())
    args = parser.parse_args(["--out", str(out), *argv_of(options)])
    status = main(args)
    tables = {}
    for path in sorted(Path(out).glob("*.csv")):
        with path.open(newline="", encoding="utf-8") as f:
            tables[path.stem] = list(csv.DictReader(f))
    return ExperimentResult(kind, int(status or 0), Path(out), tables)
