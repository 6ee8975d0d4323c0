#!/usr/bin/env python3
"""The background traffic's make-up beside highD's, measured from recorded bags (docs/bv-profiles.md).

    python scripts/traffic_makeup.py [--makeup highd] [--seeds 7001 7002 ...] [--steps 3000] [--sut mobil]
                                     [--bv-driver learned] [--out DIR] [--bench ROUNDS] [--json OUT]
                                     [--set KEY=VALUE ...]
    python scripts/traffic_makeup.py --bags BAG [BAG ...] [--json OUT]

Records one bag per seed in process (``bvs.makeup`` of ``--makeup``), reads each back
(:func:`evoscen_eval.scoring.rundata.read_run`) and prints, pooled over the seeds (``--bags BAG ...``: of
these recorded bags instead, nothing run):

* what highD measures, measured as docs/fidelity.md does (:mod:`evoscen_eval.naturalistic.fidelity_highd`, one
  definition for both): each BV trip cut into 420-m pieces, the pieces' mean speeds (mean, sd, p5,
  p50, p95), all and per class (truck: longer than 7 m); BV lane changes per vehicle-km, all and
  per class;
* this script's own: the share of trucks among the pieces (pieces count vehicles as a fixed section
  of road does, in proportion to the distance driven), the trips and the slots; per class the
  merges from the merge lane (completed ``evoscen/lane_change`` events from lane 0) and the lane
  changes without them (highD's recordings are mostly without an on-ramp); BV-BV collisions per
  BV slot-hour; trucks' steps in the leftmost lane; the BVs within ±100 m of the SUT, the run
  report's ``traffic`` section (:func:`evoscen_eval.scoring.metrics.evaluate`: per 30-s window, the lowest
  window mean over the seeds);
* with ``--bench N``: in-process steps/s (recording off; N rounds of 300 steps alternating the two,
  best of each) of this make-up and of ``uniform`` on the first seed, and their ratio.

Beside each, highD's figure at 120 km/h (Krajewski et al., *The highD Dataset*, ITSC 2018), from the
aggregates shipped with evoscen_eval (:func:`evoscen_eval.naturalistic.fidelity_highd.load_reference`). Bad input:
``error: ...``, exit 2.
"""

from __future__ import annotations

import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None):
    p = cli.parser("traffic_makeup.py", __doc__, ranks_by="fidelity")
    p.add_argument("--makeup", default="highd", help="bvs.makeup (default highd)")
    p.add_argument("--seeds", nargs="+", type=int, default=[7001, 7002, 7003, 7004, 7005, 7006])
    cli.add_steps(p, 3000)
    p.add_argument("--sut", default="mobil", help="sut.model (default mobil)")
    p.add_argument("--bv-driver", default=None, help="bvs.driver (default: the config's)")
    p.add_argument("--out", type=Path, default=None, help="keep the bags here (default: a temporary directory)")
    p.add_argument("--bags", nargs="+", type=Path, default=None, metavar="BAG",
                   help="measure these recorded bags instead of recording (e.g. an earlier --out's)")
    p.add_argument("--bench", dest="bench_rounds", default="0", metavar="ROUNDS",
                   help="also time this make-up against uniform: ROUNDS alternated rounds of 300 steps, best of each")
    p.add_argument("--json", dest="json_out", metavar="JSON", type=Path, default=None,
                   help="also write the figures as JSON here")
    p.add_argument("--set", dest="overrides", action="extend", nargs="+", default=[], metavar="KEY=VALUE",
                   help="scenario overrides, e.g. models.truck.threshold_mps2=0.4 (repeatable)")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments.traffic_runs import traffic_makeup

    return cli.run(lambda: traffic_makeup(**vars(args)))


if __name__ == "__main__":
    sys.exit(main())
