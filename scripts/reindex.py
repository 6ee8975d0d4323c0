#!/usr/bin/env python3
"""Recover a bag whose recorder was killed: rebuild the MCAP summary and metadata.yaml.

    python scripts/reindex.py BAG [--no-keep-original]

BAG is a bag directory or its .mcap file. Like rosbag2's ``ros2 bag reindex`` (which rebuilds
metadata.yaml), and more: an MCAP file cut short lacks its summary section, so it is read record
by record from its start and rewritten with every message of its complete chunks (same bytes,
same times); the damaged file is kept as ``<file>.orig`` unless ``--no-keep-original``.
Prints what was recovered (messages, steps, topics). Exit status: 0 done, 2 not a bag / not MCAP.
See docs/recording.md; the work is :func:`evoscen_record.reindex.reindex_and_report`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("reindex.py", __doc__)
    ap.add_argument("bag", type=Path, help="bag directory or .mcap file")
    ap.add_argument("--no-keep-original", action="store_true", help="do not keep the damaged file as <file>.orig")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_record.reindex import reindex_and_report

    return cli.run(lambda: reindex_and_report(args.bag, keep_original=not args.no_keep_original))


if __name__ == "__main__":
    sys.exit(main())
