#!/usr/bin/env python3
"""Write the README's results table from the results file its marker names (make readme-table).

    python scripts/readme_table.py [--check]

The table sits in README.md between ``<!-- results-table: results/readme.yaml -->`` and
``<!-- /results-table -->`` (evoscen_experiments.results_table; tests/test_readme.py checks it). ``--check``
writes nothing. Exit status: 0 written (or equal), 1 the README differs (``--check``), 2 bad input
(one ``error:`` line naming the file and the field).
"""

from __future__ import annotations

import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"


def main(argv: list[str] | None = None) -> int:
    p = cli.parser("readme_table.py", __doc__)
    p.add_argument("--check", action="store_true", help="write nothing; exit 1 if README.md's table differs")
    args = p.parse_args(argv)
    from evoscen_experiments.results_table import write_readme_table

    return cli.run(lambda: write_readme_table(README, REPO, check=args.check))


if __name__ == "__main__":
    sys.exit(main())
