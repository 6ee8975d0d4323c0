#!/usr/bin/env python3
"""Benchmark: in-process simulation speed, recorded-bag size, and SUMO for reference.

    python scripts/bench.py [--mode inprocess|graph] [--steps 5000] [--repeats 5] [--bag-steps 10000] [--no-sumo]

Prints, for the shipped default scenario (1 SUT + 20 BVs, level-0 drivers, dt 0.1 s):

* in-process steps/s with recording off (best and median of ``--repeats`` timed runs of
  ``--steps`` steps after a warm-up; the JIT kernels are compiled before timing);
* a ``--bag-steps`` recorded run: steps/s with recording on and the bag's size;
* when the optional ``libsumo`` is installed (``pip install -r requirements-bench.txt``),
  SUMO's stepping rate on the same road and traffic volume, measured in this same
  process (``scripts/sumo_baseline.py``), and the ratio evoscen / SUMO.

With ``--mode graph``: the lockstep rate of the node graph (four processes: simulation,
BV, SUT, evaluator; 1 SUT + 20 BVs; the rate of the simulation node's stepping loop, without
start-up) for ``--graph-steps`` steps, and beside it the in-process rate of the same
scenario with recording on (the graph always records) and off.

With ``--sut-models``: the per-decision cost of every registered SUT model (median over a
run of the default scenario) and the in-process rate with it as the SUT.

Targets (issues #2-#4): >= 5,000 steps/s in-process with recording off; a 10,000-step bag
<= 25 MB; the graph >= 1,000 steps/s on a 2-core machine; no SUT model below 3,000 steps/s
in-process. Figures, not assertions: machines are shared and noisy.
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


def graph_run(steps: int) -> dict:
    """One graph run of ``steps`` steps: the simulation node's lockstep rate."""
    from evoscen_bringup.graph_runner import GraphOptions, run_graph
    from evoscen_sim.config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": steps})
    with tempfile.TemporaryDirectory() as tmp:
        stats = Path(tmp) / "stats.json"
        result = run_graph(cfg, Path(tmp), Path(tmp) / "bag",
                           GraphOptions(node_args={"evoscen_sim": {"stats_file": str(stats)}}))
        if result.status != 0 or not stats.exists():
            raise RuntimeError(f"graph run failed: {result.node_status}")
        out = json.loads(stats.read_text())
        out["wall_with_startup_s"] = result.wall_time_s
        return out


def sut_model_costs(steps: int) -> dict[str, dict]:
    """Per-decision cost (median µs) and in-process steps/s of every SUT model."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config import load_scenario_config
    from evoscen_sim.models import model_names

    out = {}
    for name in model_names("sut"):
        sc = build_scenario(load_scenario_config(None, {"sut.model": name}))
        for _ in range(200):
            sc.step()
        costs = []
        t0 = time.perf_counter()
        for _ in range(steps):
            bv = sc.bv_driver.act(sc.world)
            a = time.perf_counter()
            sut = sc.sut.act(sc.world)
            costs.append(time.perf_counter() - a)
            sc.apply(*bv, *sut)
        out[name] = {"decision_us": statistics.median(costs) * 1e6, "steps_per_s": steps / (time.perf_counter() - t0)}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=5000, help="timed steps per repeat (default 5000)")
    ap.add_argument("--repeats", type=int, default=5, help="timed repeats (default 5)")
    ap.add_argument("--bag-steps", type=int, default=10000, help="steps of the recorded run (default 10000; 0 = skip)")
    ap.add_argument("--no-sumo", action="store_true", help="skip the SUMO reference even if libsumo is installed")
    ap.add_argument("--mode", choices=("inprocess", "graph"), default="inprocess",
                    help="graph: also the lockstep rate of the node graph (default: in-process only)")
    ap.add_argument("--graph-steps", type=int, default=5000, help="steps of the graph run (default 5000)")
    ap.add_argument("--sut-models", action="store_true", help="also the per-decision cost of every SUT model")
    ap.add_argument("--json", action="store_true", help="also print the figures as one JSON line")
    args = ap.parse_args(argv)
    for name in ("steps", "repeats", "bag_steps", "graph_steps"):
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
    if args.mode == "graph":
        g = graph_run(args.graph_steps)
        out["graph"] = g
        print(f"evoscen node graph (sim, BV, SUT, evaluator processes; lockstep; recording), {g['steps']} steps:")
        print(f"  {g['steps_per_s']:8.0f} steps/s lockstep   (target >= 1000; {g['wall_with_startup_s']:.1f} s with start-up)")
        rec = out.get("recorded") or recorded_run(args.graph_steps)
        print(f"  same scenario in-process: {rec['steps_per_s']:8.0f} steps/s recording on, "
              f"{out['inprocess_median_steps_per_s']:8.0f} steps/s recording off")
    if args.sut_models:
        costs = sut_model_costs(args.steps)
        out["sut_models"] = costs
        print(f"SUT models (in-process, 20 level-0 BVs, {args.steps} steps; target >= 3000 steps/s each):")
        for name, c in costs.items():
            print(f"  {name:12s} {c['decision_us']:7.1f} us/decision   {c['steps_per_s']:8.0f} steps/s")
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
