#!/usr/bin/env python3
"""Write the README's results table from the results file its marker names (make readme-table).

    python scripts/readme_table.py [--check]

The table sits in README.md between ``<!-- results-table: results/readme.yaml -->`` and
``<!-- /results-table -->`` (evoscen_experiments.results_table; tests/test_readme.py checks it). ``--check``
writes nothing. Exit status: 0 written (or equal), 1 the README differs (``--check``), 2 bad input
(one ``error:`` line naming the file and the field).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK
from evoscen_experiments.results_table import results_file, rewrite_readme
from evoscen_sim.errors import InputError

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="readme_table.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="write nothing; exit 1 if README.md's table differs")
    args = ap.parse_args(argv)
    try:
        text = README.read_text(encoding="utf-8")
        new = rewrite_readme(text, REPO)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:
        print(f"error: {README}: cannot read: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.check:
        if new != text:
            print(f"README.md: the results table differs from {results_file(text)}: run make readme-table",
                  file=sys.stderr)
            return 1
        return EXIT_OK
    if new != text:
        README.write_text(new, encoding="utf-8")
    print(f"README.md: results table {'updated' if new != text else 'unchanged'}")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
