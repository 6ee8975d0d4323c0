"""The command lines of ``scripts/``: one argument module for every door (docs/development.md, "Scripts").

A script is a thin door: it builds its parser here, parses, and calls a package function that does
the work; :func:`run` turns the project's errors into its exit statuses, so every script says a bad
input, a fault of the host or Ctrl-C the same way::

    from evoscen import cli

    def parse_args(argv):
        p = cli.parser("experiment_intelligence.py", __doc__, ranks_by="D")
        cli.add_out(p, "runs/experiment_intelligence")
        cli.add_config(p)
        cli.add_seeds(p, count=5)
        cli.add_jobs(p)
        return p.parse_args(argv)

    def main(argv=None) -> int:
        return cli.run(lambda: intelligence.main(parse_args(argv)))

Values stay text until the package checks them with :func:`positive_int`, :func:`names` and
:func:`seed_blocks` (one-line :class:`~evoscen_sim.errors.InputError` naming the option), so that a
bad value is the same line from a script, a campaign spec or a notebook. Importing this module
imports nothing of evoscen but the contract's exit statuses (docs/recording.md "Endings and exit
statuses"); each helper loads what it needs when called.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path

from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_HOST_FAULT, EXIT_INTERRUPTED, EXIT_OK

SCORES = {
    "D": "Ranks by: D, the comparative score: progress × safety, lane changes and exchange (docs/evaluation.md §10)",
    "I": "Ranks by: I, the method's intelligence, for reproducing the paper (docs/method.md §5)",
    "fidelity": "Measures: the traffic against highD (docs/fidelity.md); it ranks nothing",
    "speed": "Measures: steps per second against a reference run in the same process (docs/performance.md); "
             "it ranks nothing",
}
"""What a door ranks or compares by, or what it measures, in the words its ``--help`` ends with (:func:`parser`)."""


def parser(prog: str, doc: str | None, *, ranks_by: str | None = None) -> argparse.ArgumentParser:
    """An argument parser for the script ``prog``: its description the first paragraph of ``doc`` (the
    script's docstring); with ``ranks_by`` (a key of :data:`SCORES`) its ``--help`` ends with the score
    the script ranks or compares by."""
    if ranks_by is not None and ranks_by not in SCORES:
        raise ValueError(f"ranks_by {ranks_by!r}: expected one of {', '.join(SCORES)}")
    description = (doc or "").strip().split("\n\n")[0] or None
    epilog = f"{SCORES[ranks_by]}." if ranks_by is not None else None
    return argparse.ArgumentParser(prog=prog, description=description, epilog=epilog)


def one_line_errors(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Make ``p`` say a bad command line (an unknown option, a missing or malformed value) as one
    :class:`~evoscen_sim.errors.InputError` instead of its usage and message: parsed inside :func:`run`,
    that is one ``error: ...`` line and status 2. Returns ``p``."""

    def error(message: str):
        from evoscen_sim.errors import InputError

        raise InputError(message)

    p.error = error  # type: ignore[method-assign]
    return p


def add_out(p: argparse.ArgumentParser, default: str, what: str = "output directory") -> None:
    """``--out DIR`` (a Path; default ``default``)."""
    p.add_argument("--out", type=Path, default=Path(default), help=f"{what} (default {default})")


def add_config(p: argparse.ArgumentParser) -> None:
    """``--config FILE``: the base scenario YAML (default: the shipped default scenario)."""
    p.add_argument("--config", type=Path, default=None, help="base scenario YAML (default: the shipped default)")


def add_seeds(p: argparse.ArgumentParser, *, count: int, first: int = 0, what: str = "seeds") -> None:
    """``--seeds N --first-seed S``: the seed block S .. S+N-1 (text; check with :func:`positive_int`)."""
    p.add_argument("--seeds", default=str(count), help=f"number of {what} (default {count})")
    p.add_argument("--first-seed", default=str(first), help=f"first seed (default {first})")


def add_jobs(p: argparse.ArgumentParser, default: int | None = None) -> None:
    """``--jobs N``: Ray workers (default: the CPUs this process may use); ``--batch N``: the runs of one start a
    worker's task steps in lockstep (:func:`evoscen_experiments.experiments.batch_option`)."""
    n = default if default is not None else len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
        else os.cpu_count() or 1
    p.add_argument("--jobs", default=str(n), help=f"parallel workers (default {n})")
    p.add_argument("--batch", default=None, help="runs of one start per worker task, stepped together in lockstep "
                                                  "(default: 16 per task, one after the other)")


def add_steps(p: argparse.ArgumentParser, default: int) -> None:
    """``--steps N`` per run (text; check with :func:`positive_int`)."""
    p.add_argument("--steps", default=str(default), help=f"steps per run (default {default})")


def positive_int(option: str, text: str, lo: int = 1) -> int:
    """The integer ``text`` of ``option``, at least ``lo`` (else a one-line InputError naming it)."""
    from evoscen_experiments.experiments import positive_int as checked

    return checked(option, str(text).strip(), lo)


def names(option: str, text: str, what: str = "names") -> list[str]:
    """The comma-separated ``text`` of ``option``: non-empty, no name twice (else a one-line InputError)."""
    from evoscen_experiments.experiments import distinct_names

    return distinct_names(option, str(text), what)


def seed_blocks(option: str, text: str):
    """``"A:B,C:D"`` of ``option`` as seed blocks (:func:`evoscen_experiments.replication.parse_seed_blocks`)."""
    from evoscen_experiments.replication import parse_seed_blocks

    return parse_seed_blocks(text, option)


def run(work: Callable[[], int | None]) -> int:
    """Call ``work()`` and return its exit status (None: 0); a bad input is one ``error:`` line on stderr
    and status 2, a fault of the host one line and 5, a plug-in that raised one line and 3, Ctrl-C 130."""
    from evoscen_sim.errors import HostFault, InputError, PluginFault

    try:
        status = work()
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except HostFault as exc:
        print(f"error: {exc.line()}", file=sys.stderr)
        return EXIT_HOST_FAULT
    except PluginFault as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_FAULT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK if status is None else int(status)
