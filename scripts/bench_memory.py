#!/usr/bin/env python3
"""Peak memory of a scored in-process run at two run lengths: is it independent of the length?

    python scripts/bench_memory.py [--steps N1 N2] [--bvs N] [--tracemalloc N]

Each run is a fresh process (``run_inprocess`` with scoring, no bag, no plots) that prints its
peak RSS (``ru_maxrss``) after the simulation and after the scoring. The script prints, per
length, the peaks and the RSS per step above an idle baseline (the same process with 1 step),
then the marginal bytes per step between the two lengths and the ratio of the peaks.

``--tracemalloc N`` instead runs N steps with :mod:`tracemalloc` and prints the allocation
sites that hold the most memory at the end of the simulation and the peak of the scoring.
Figures only; nothing is asserted (benchmarks print figures).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_OK

CHILD = r"""
import json, resource, sys, time
from evoscen_bringup.inprocess import run_inprocess
from evoscen_sim.config.scenario_config import load_scenario_config
steps, bvs = int(sys.argv[1]), int(sys.argv[2])
over = {"steps": steps, "bvs.count": bvs, "spawn.ramp_vehicles": min(3, bvs)}
cfg = load_scenario_config(None, over)
rss = lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
base = rss()
marks = {}
def progress(k):
    if k == steps:
        marks["sim"] = rss()
t0 = time.perf_counter()
summary = run_inprocess(cfg, bag_dir=None, evaluate=True, progress=progress)
print(json.dumps({"steps": steps, "base": base, "sim": marks.get("sim", 0), "scored": rss(),
                  "wall_s": time.perf_counter() - t0}))
"""

TRACE = r"""
import sys, tracemalloc
from evoscen_bringup import inprocess
from evoscen_sim.config.scenario_config import load_scenario_config
steps, bvs = int(sys.argv[1]), int(sys.argv[2])
cfg = load_scenario_config(None, {"steps": steps, "bvs.count": bvs, "spawn.ramp_vehicles": min(3, bvs)})
snaps = {}
def progress(k):
    if k == steps:
        snaps["sim"] = tracemalloc.take_snapshot()
        tracemalloc.reset_peak()
tracemalloc.start(4)
summary = inprocess.run_inprocess(cfg, bag_dir=None, evaluate=True, progress=progress)
cur, peak = tracemalloc.get_traced_memory()
snaps["scored"] = tracemalloc.take_snapshot()
print(f"traced after scoring: {cur / 2**20:.1f} MiB; peak during scoring: {peak / 2**20:.1f} MiB "
      f"({peak / steps:.0f} B/step)")
for name, snap in snaps.items():
    stats = snap.statistics("lineno")
    total = sum(s.size for s in stats)
    print(f"\n{name}: {total / 2**20:.1f} MiB traced ({total / steps:.0f} B/step); largest sites:")
    for s in stats[:8]:
        fr = s.traceback[0]
        print(f"  {s.size / 2**20:8.2f} MiB  {s.size / steps:7.0f} B/step  {Path(fr.filename).name}:{fr.lineno}")
"""


def measure(steps: int, bvs: int) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(steps), str(bvs)], capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    from pathlib import Path as _P  # noqa: F401

    ap = argparse.ArgumentParser(prog="bench_memory.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, nargs=2, default=[5000, 20000], metavar=("N1", "N2"),
                    help="the two run lengths (default 5000 20000)")
    ap.add_argument("--bvs", type=int, default=20, help="background vehicles (default 20)")
    ap.add_argument("--tracemalloc", type=int, metavar="N", help="allocation sites of an N-step run instead")
    args = ap.parse_args(argv)
    if args.tracemalloc:
        subprocess.run([sys.executable, "-c", "from pathlib import Path\n" + TRACE, str(args.tracemalloc),
                        str(args.bvs)], check=True)
        return EXIT_OK
    idle = measure(1, args.bvs)
    rows = [measure(n, args.bvs) for n in args.steps]
    mib = 2**20
    print(f"bench_memory: in-process run + scoring, {args.bvs} BVs, no bag; RSS = ru_maxrss (peak)")
    print(f"  1-step baseline: peak {idle['scored'] / mib:.1f} MiB")
    for r in rows:
        print(f"  {r['steps']:>7} steps: peak after simulation {r['sim'] / mib:7.1f} MiB, after scoring "
              f"{r['scored'] / mib:7.1f} MiB; above baseline {(r['scored'] - idle['scored']) / r['steps']:7.0f} B/step "
              f"(wall {r['wall_s']:.1f} s)")
    a, b = rows
    dn = b["steps"] - a["steps"]
    print(f"  marginal: simulation {(b['sim'] - a['sim']) / dn:.0f} B/step, with scoring "
          f"{(b['scored'] - a['scored']) / dn:.0f} B/step")
    print(f"  peak ratio {b['steps']}/{a['steps']} steps: {b['scored'] / a['scored']:.2f} "
          f"(length ratio {b['steps'] / a['steps']:.1f})")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
