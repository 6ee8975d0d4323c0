#!/usr/bin/env python3
"""Recover a bag whose recorder was killed: rebuild the MCAP summary and metadata.yaml.

    python scripts/reindex.py BAG [--no-keep-original]

BAG is a bag directory or its .mcap file. Like rosbag2's ``ros2 bag reindex`` (which rebuilds
metadata.yaml), and more: an MCAP file cut short lacks its summary section, so it is read record
by record from its start and rewritten with every message of its complete chunks (same bytes,
same times); the damaged file is kept as ``<file>.orig`` unless ``--no-keep-original``.
Prints what was recovered (messages, steps, topics). Exit status: 0 done, 2 not a bag / not MCAP.
See docs/recording.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="reindex.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("bag", type=Path, help="bag directory or .mcap file")
    ap.add_argument("--no-keep-original", action="store_true", help="do not keep the damaged file as <file>.orig")
    args = ap.parse_args(argv)
    from evoscen_record.reindex import reindex_bag
    from evoscen_sim.errors import InputError

    try:
        r = reindex_bag(args.bag, keep_original=not args.no_keep_original)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:
        print(f"error: bag {str(args.bag)!r}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    last = "-" if r.last_step_ns is None else f"{r.last_step_ns / 1e9:.1f} s"
    print(f"recovered {r.messages} messages, {r.steps} world states (last at {last}) from {r.chunks} chunks "
          + ("(the file was complete)" if not r.stopped else f"(read stopped at: {r.stopped})"))
    for topic, n in r.topic_counts.items():
        print(f"  {topic}: {n}")
    print(f"bag: {r.mcap_path.parent}" + (f"  (damaged file kept as {r.original.name})" if r.original else ""))
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
