#!/usr/bin/env python3
"""Print the topic contract as Markdown, or rewrite it into README.md (``--write``).

The README's contract section sits between ``<!-- contract:begin -->`` and
``<!-- contract:end -->`` and must equal ``evoscen_contract.topics.contract_markdown()``
(a test checks it): after changing the contract, run ``python scripts/contract_table.py --write``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401
from evoscen_contract.contract import EXIT_OK

BEGIN, END = "<!-- contract:begin -->", "<!-- contract:end -->"
README = Path(__file__).resolve().parents[1] / "README.md"


def readme_section(text: str) -> str:
    """The text between the contract markers of ``text`` (stripped)."""
    if BEGIN not in text or END not in text:
        raise ValueError(f"README.md: contract markers {BEGIN} ... {END} not found")
    return text.split(BEGIN, 1)[1].split(END, 1)[0].strip()


def main(argv: list[str] | None = None) -> int:
    from evoscen_contract.topics import contract_markdown

    ap = argparse.ArgumentParser(prog="contract_table.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="rewrite the section in README.md")
    args = ap.parse_args(argv)
    table = contract_markdown().strip()
    if not args.write:
        print(table)
        return EXIT_OK
    text = README.read_text(encoding="utf-8")
    old = readme_section(text)
    README.write_text(text.replace(old, table, 1), encoding="utf-8")
    print(f"{README}: contract table {'unchanged' if old == table else 'updated'}")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
