#!/usr/bin/env python3
"""Benchmark: in-process simulation speed, recorded-bag size, and SUMO for reference.

    python scripts/bench.py [--steps 5000] [--repeats 5] [--bag-steps 10000] [--no-sumo]

Prints, for the shipped default scenario (1 SUT + 20 BVs, level-0 drivers, dt 0.1 s):

* in-process steps/s with recording off (best and median of ``--repeats`` timed runs of
  ``--steps`` steps after a warm-up; the JIT kernels are compiled before timing);
* a ``--bag-steps`` recorded run: steps/s with recording on and the bag's size;
* when the optional ``libsumo`` is installed (``pip install -r requirements-bench.txt``),
  SUMO's stepping rate on the same road and traffic volume, measured in this same
  process (``scripts/sumo_baseline.py``), and the ratio evoscen / SUMO.

Targets (issue #2): >= 5,000 steps/s in-process with recording off; a 10,000-step bag
<= 25 MB. Figures, not assertions: machines are shared and noisy.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import _bootstrap  # noqa: F401


def time_inprocess(steps: int, repeats: int, warmup: int = 300) -> list[float]:
    """Steps/s of ``repeats`` timed runs (fresh scenario each, recording off)."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config import load_scenario_config

    cfg = load_scenario_config(None)
    rates = []
    for _ in range(repeats):
        sc = build_scenario(cfg)
        for _ in range(warmup):
            sc.step()
        t0 = time.perf_counter()
        for _ in range(steps):
            sc.step()
        rates.append(steps / (time.perf_counter() - t0))
    return rates


def recorded_run(steps: int) -> dict:
    """One recorded run of ``steps`` steps: steps/s and bag size."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": steps})
    with tempfile.TemporaryDirectory() as tmp:
        summary = run_inprocess(cfg, bag_dir=Path(tmp) / "bag")
        return {"steps": summary.steps, "steps_per_s": summary.steps_per_s,
                "bag_mb": summary.bag_bytes / 1e6, "messages": summary.message_count}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=5000, help="timed steps per repeat (default 5000)")
    ap.add_argument("--repeats", type=int, default=5, help="timed repeats (default 5)")
    ap.add_argument("--bag-steps", type=int, default=10000, help="steps of the recorded run (default 10000; 0 = skip)")
    ap.add_argument("--no-sumo", action="store_true", help="skip the SUMO reference even if libsumo is installed")
    ap.add_argument("--json", action="store_true", help="also print the figures as one JSON line")
    args = ap.parse_args(argv)
    for name in ("steps", "repeats", "bag_steps"):
        if getattr(args, name) < (0 if name == "bag_steps" else 1):
            print(f"error: --{name.replace('_', '-')} = {getattr(args, name)}: expected a positive integer", file=sys.stderr)
            return 2

    out: dict = {"python": sys.version.split()[0]}
    rates = time_inprocess(args.steps, args.repeats)
    out["inprocess_best_steps_per_s"] = max(rates)
    out["inprocess_median_steps_per_s"] = statistics.median(rates)
    print(f"evoscen in-process, 1 SUT + 20 BVs (level-0), recording off, {args.steps} steps x {args.repeats}:")
    print(f"  best {max(rates):8.0f} steps/s   median {statistics.median(rates):8.0f} steps/s   "
          f"(target >= 5000)")
    if args.bag_steps:
        rec = recorded_run(args.bag_steps)
        out["recorded"] = rec
        print(f"evoscen in-process, recording on, {rec['steps']} steps:")
        print(f"  {rec['steps_per_s']:8.0f} steps/s   bag {rec['bag_mb']:.2f} MB, {rec['messages']} messages   (target <= 25 MB)")
    if not args.no_sumo:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from sumo_baseline import measure_sumo_steps_per_second, sumo_available

        ok, why = sumo_available()
        if ok:
            sumo = measure_sumo_steps_per_second(steps=args.steps, vehicles=21, seed=0, in_process=True)
            out["sumo"] = sumo
            out["ratio_evoscen_over_sumo"] = out["inprocess_median_steps_per_s"] / sumo["steps_per_s"]
            print(f"SUMO reference ({sumo['sumo_version']}, libsumo, same road, {sumo['mean_vehicles']:.1f} vehicles, "
                  f"Krauss, dt 0.1 s), {sumo['steps']} steps:")
            print(f"  {sumo['steps_per_s']:8.0f} steps/s")
            print(f"ratio evoscen / SUMO (median): {out['ratio_evoscen_over_sumo']:.2f}")
        else:
            print(f"SUMO reference skipped: {why} (pip install -r requirements-bench.txt)")
    if args.json:
        print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
