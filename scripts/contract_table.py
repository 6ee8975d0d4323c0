#!/usr/bin/env python3
"""Print the topic contract as Markdown, or rewrite it into docs/topics.md (``--write``).

The contract section of docs/topics.md sits between ``<!-- contract:begin -->`` and
``<!-- contract:end -->`` and must equal ``evoscen_contract.topics.contract_markdown()``
(tests/test_readme.py checks it): after changing the contract, run ``python scripts/contract_table.py --write``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401
from evoscen_contract.contract import EXIT_OK

BEGIN, END = "<!-- contract:begin -->", "<!-- contract:end -->"
PAGE = Path(__file__).resolve().parents[1] / "docs" / "topics.md"


def contract_section(text: str) -> str:
    """The text between the contract markers of ``text`` (stripped)."""
    if BEGIN not in text or END not in text:
        raise ValueError(f"docs/topics.md: contract markers {BEGIN} ... {END} not found")
    return text.split(BEGIN, 1)[1].split(END, 1)[0].strip()


def main(argv: list[str] | None = None) -> int:
    from evoscen_contract.topics import contract_markdown

    ap = argparse.ArgumentParser(prog="contract_table.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="rewrite the section in docs/topics.md")
    args = ap.parse_args(argv)
    table = contract_markdown().strip()
    if not args.write:
        print(table)
        return EXIT_OK
    text = PAGE.read_text(encoding="utf-8")
    old = contract_section(text)
    head, rest = text.split(BEGIN, 1)
    PAGE.write_text(f"{head}{BEGIN}\n{table}\n{END}{rest.split(END, 1)[1]}", encoding="utf-8")
    print(f"{PAGE}: contract table {'unchanged' if old == table else 'updated'}")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
