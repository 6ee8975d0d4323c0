#!/usr/bin/env python3
"""The traffic's fidelity against highD's shipped aggregates (docs/fidelity.md).

    python scripts/fidelity_highd.py BAG [BAG ...] [--out DIR]
    python scripts/fidelity_highd.py --seeds N [--first-seed 7001] [--steps 3000] [--sut mobil]
                                     [--config FILE] [--set KEY=VALUE ...] [--out DIR]
        [--piece-m 420] [--min-piece-m 420] [--truck-length 7] [--include-sut] [--reference FILE]

Measures the background vehicles of recorded runs (each BAG a bag directory, an ``.mcap`` file or a
``run_scenario.py`` output directory with ``bag/``) or of ``--seeds`` runs made here in process (no
bag), the way highD sees its vehicles: every trip cut into 420-m pieces, per piece the mean speed and
the minimum THW, DHW and TTC, per class (truck: longer than 7 m) and all; lane changes per vehicle-km,
per class and by density. Each distribution is compared with highD's (the recordings with a 120 km/h
limit; R. Krajewski, J. Bock, L. Kloeker, L. Eckstein, "The highD Dataset", IEEE ITSC 2018) by
S = 1 - JS(highD || simulation), log base 2, over highD's bins.

Prints the table and writes ``OUT/fidelity_highd.json``, ``OUT/fidelity_highd.md`` and one PNG per
distribution (default ``runs/fidelity_highd``). Exit status: 0 done, 2 bad input (one line ``error: ...``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli


def parse_args(argv: list[str] | None):
    p = cli.one_line_errors(cli.parser("fidelity_highd.py", __doc__, ranks_by="fidelity"))
    p.add_argument("bags", nargs="*", type=Path, metavar="BAG", help="bags (or run directories) to measure")
    cli.add_out(p, "runs/fidelity_highd")
    g = p.add_argument_group("runs made here, in process (instead of or besides bags)")
    g.add_argument("--seeds", default=None, metavar="N", help="number of seeds to run")
    g.add_argument("--first-seed", default="7001", help="first seed (default 7001)")
    cli.add_steps(g, 3000)
    g.add_argument("--sut", default="mobil", help="SUT model (default mobil)")
    cli.add_config(g)
    g.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key")
    m = p.add_argument_group("measurement (docs/fidelity.md)")
    m.add_argument("--piece-m", default="420", metavar="M", help="piece length (default 420 m)")
    m.add_argument("--min-piece-m", default=None, metavar="M",
                   help="a trip's remainder at least this long is a piece too (default: --piece-m, i.e. never)")
    m.add_argument("--truck-length", default="7", metavar="M", help="a vehicle longer than this is a truck (default 7 m)")
    m.add_argument("--include-sut", action="store_true", help="also measure the SUT (default: BVs only)")
    m.add_argument("--reference", type=Path, default=None,
                   help="highD aggregates JSON (default: the copy shipped with evoscen_eval)")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    def work() -> int:
        from evoscen_experiments.traffic_runs import fidelity_highd

        return fidelity_highd(**vars(parse_args(argv)))

    return cli.run(work)


if __name__ == "__main__":
    sys.exit(main())
