#!/usr/bin/env python3
"""Realism figures of learned BVs per run-time profile (docs/bv-profiles.md).

    python scripts/bv_realism.py [--profiles driver safety_net] [--seeds 1 2 3 4 5]
                                 [--steps 3000] [--sut level0] [--config FILE] [--policy-dir DIR] [--json OUT]
                                 [--cut-in-headway H] [--lane-hold S] [--traffic window|loop]

Runs every (profile, seed) in process (``bvs.driver: learned``, no bag) and prints, per
profile, the pooled figures of :func:`evoscen_eval.naturalistic.bv_realism.bv_realism`: BV lane changes
per vehicle-km, BV-BV collisions per vehicle-hour, SUT collisions, and the BVs' time-headway
distribution, with highD's published figure beside each one that has one
(:data:`evoscen_eval.naturalistic.bv_realism.HIGHD_REFERENCE`; lane changes: 0.295 per vehicle-km at 120 km/h).
``--traffic`` sets ``traffic.mode`` (window: the traffic moves with the SUT; loop: vehicles
re-enter at the road's start), so the same seeds compare both. Bad input prints one line
``error: ...`` and exits 2.
"""

from __future__ import annotations

import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None):
    p = cli.parser("bv_realism.py", __doc__, ranks_by="fidelity")
    p.add_argument("--profiles", nargs="+", default=["driver", "safety_net"])
    p.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3, 4, 5])
    cli.add_steps(p, 3000)
    p.add_argument("--sut", default=None, help="SUT model (default: the config's)")
    cli.add_config(p)
    p.add_argument("--policy-dir", default=None,
                   help="models.learned.policy_dir: shipped (default), v0.1.0, or a train_bv.py --out directory")
    p.add_argument("--cut-in-headway", type=float, default=None, metavar="H",
                   help="measure with the profiles' cut-in closing headway h replaced by H s (0: the method's plain 10 m)")
    p.add_argument("--lane-hold", type=float, default=None, metavar="S",
                   help="models.learned.lane_hold_s (default: the config's, 20 s; 0: no hold)")
    p.add_argument("--cut-in-decel", type=float, default=None, metavar="B",
                   help="models.learned.cut_in_decel_mps2 (default: the config's, 0: the linear cut-in gap only)")
    p.add_argument("--standing-at-once", choices=("true", "false"), default=None,
                   help="models.learned.standing_leader_at_once (default: the config's)")
    p.add_argument("--traffic", choices=("window", "loop"), default=None,
                   help="traffic.mode: window (the traffic moves with the SUT) or loop (re-entry at the road's start; "
                        "with the uniform make-up, which the loop needs: bvs.makeup: uniform); default: the config's")
    p.add_argument("--hard-brake", choices=("true", "false"), default=None,
                   help="models.learned.hard_brake: the SUT's leader brakes hard now and then (default: the config's)")
    p.add_argument("--json", dest="json_out", metavar="JSON", type=Path, default=None, help="also write the figures as JSON here")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments.traffic_runs import bv_realism

    return cli.run(lambda: bv_realism(**vars(args)))


if __name__ == "__main__":
    sys.exit(main())
