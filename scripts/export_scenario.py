#!/usr/bin/env python3
"""Export a recorded run's time range, or every critical-event clip of a run or campaign, as an
OpenSCENARIO 1.2 or a CommonRoad scenario (docs/export.md).

    python scripts/export_scenario.py BAG [--from T] [--to T] --format xosc|commonroad [--out DIR] [--check]
    python scripts/export_scenario.py BAG --event N [--around S] --format xosc|commonroad [--out DIR] [--check]
    python scripts/export_scenario.py BAG [--from T] --compare-start RUN_BAG
    python scripts/export_scenario.py RUN_OR_CAMPAIGN_DIR --format xosc|commonroad [--check]

BAG is a bag directory (or its ``.mcap`` file): a run's ``OUT/bag`` or a clip's ``clips/<n>-<kind>-<k>/bag``.
``--from``/``--to`` are run times in seconds (default: the bag's first and last state); a range holding
the traffic window's shift (every vehicle moved back ~1,700 m) is a warning naming its time. ``--event N``:
the range around the run's collision or exposure N as its report numbers them (the SUT's collisions first,
then its exposures; or ``collision:N``, ``exposure:N``), ``--around S`` seconds either side (default 5),
moved off any shift to the side holding the event (one line says so). A damaged bag is exported up to the
damage, with ``evaluate.py``'s warning. A directory holding ``clips.json`` (a campaign run) or
``runs/*/clips.json`` (a campaign's output) exports every clip listed, each into ``<clip>/export/``, and
ends with a summary line per clip and a total. ``--check``: the ASAM Quality Checker on an OpenSCENARIO
file, commonroad-io's read-back of a CommonRoad file (obstacles, time steps), and the independent collision
check (shapely on the exported boxes) against evoscen's collision events; ``--compare-start RUN_BAG``: a
run started with ``--start-from`` the export against the range's first state; exit 1 when a check fails. Bad input:
one ``error:`` line, exit 2. The work is :func:`evoscen_eval.scenes.exports.export_command`.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (the workspace's packages on sys.path)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("export_scenario.py", __doc__)
    ap.add_argument("bag", help="bag directory or .mcap file; or a campaign run / campaign output directory")
    ap.add_argument("--from", dest="t_from", help="run time of the first state exported (s; default: the bag's first)")
    ap.add_argument("--to", dest="t_to", help="run time of the last state exported (s; default: the bag's last)")
    ap.add_argument("--event", metavar="N", help="the range around the report's collision or exposure N (collisions "
                    "first, then exposures; or collision:N, exposure:N); not with --from/--to")
    ap.add_argument("--around", metavar="S", help="with --event: seconds kept on either side of the event (default 5)")
    ap.add_argument("--format", dest="fmt", default="xosc", help="xosc (OpenSCENARIO 1.2) or commonroad (default xosc)")
    ap.add_argument("--out", help="output directory (default: 'export' beside the bag)")
    ap.add_argument("--name", default="scenario", help="file name without suffix (default scenario)")
    ap.add_argument("--truck-length-m", default="7.0", help="vehicles longer than this are trucks (default 7.0 m)")
    ap.add_argument("--compare-start", metavar="RUN_BAG",
                    help="compare the first state of RUN_BAG (a run started with --start-from the exported file) "
                         "with the range's first state; exit 1 when they differ")
    ap.add_argument("--check", action="store_true", help="run the ASAM checker (xosc) and the independent collision check")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_eval.scenes.exports import export_command

    return cli.run(lambda: export_command(args.bag, fmt=args.fmt, t_from=args.t_from, t_to=args.t_to, out=args.out,
                                          name=args.name, truck_length_m=args.truck_length_m,
                                          compare_start_bag=args.compare_start, check=args.check,
                                          event=args.event, around=args.around))


if __name__ == "__main__":
    sys.exit(main())
