#!/usr/bin/env python3
"""Print the topic contract as Markdown, or rewrite it into docs/topics.md (``--write``).

The contract section of docs/topics.md sits between ``<!-- contract:begin -->`` and
``<!-- contract:end -->`` and must equal ``evoscen_contract.topics.contract_markdown()``
(tests/test_readme.py checks it): after changing the contract, run ``python scripts/contract_table.py --write``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import _bootstrap  # noqa: F401
from evoscen import cli

PAGE = Path(__file__).resolve().parents[1] / "docs" / "topics.md"


def parse_args(argv: list[str] | None):
    p = cli.parser("contract_table.py", __doc__)
    p.add_argument("--write", action="store_true", help="rewrite the section in docs/topics.md")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_contract.topics import contract_markdown, write_contract_section

    def work() -> None:
        if args.write:
            print(f"{PAGE}: contract table {'updated' if write_contract_section(PAGE) else 'unchanged'}")
        else:
            print(contract_markdown().strip())

    return cli.run(work)


if __name__ == "__main__":
    sys.exit(main())
