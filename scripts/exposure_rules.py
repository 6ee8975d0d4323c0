#!/usr/bin/env python3
"""Exposures and collisions per episode by rule, for each SUT on the same episodes.

    python scripts/exposure_rules.py --suts stackelberg,mobil,nilsson --seeds 472000:472099 \
        [--episode-steps 300] [--set KEY=VALUE ...] [--out FILE.json]

Each seed is one episode of the shipped default scenario (``--set`` overrides a key, e.g.
``models.stackelberg.target_gap_rule=end_of_game``), run in process and scored as a report scores it
(docs/evaluation.md §3: the exposure rules front_ttc, hard_braking, rear, cut_in, beside, tailgating).
An exposure counts once under each rule that named it. Prints per SUT the mean per episode with its
95 % Student-t interval and n, and each collision (seed, time, the other vehicle, its kind). Exit
status 0, 2 for bad input.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("exposure_rules.py", __doc__)  # counts exposures by rule: ranks nothing
    ap.add_argument("--suts", required=True, help="comma-separated SUT models")
    ap.add_argument("--seeds", required=True, help="episodes' seeds: blocks A:B[,C:D] (both ends included)")
    ap.add_argument("--episode-steps", default="300", help="steps per episode (default 300)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a scenario key for every run")
    ap.add_argument("--out", type=Path, help="write every episode's figures as JSON here")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_experiments import exposures_by_rule

    return cli.run(lambda: exposures_by_rule.main(parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
