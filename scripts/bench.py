#!/usr/bin/env python3
"""Benchmark: in-process simulation speed, recorded-bag size, and SUMO for reference.

    python scripts/bench.py [--mode inprocess|graph] [--steps 5000] [--repeats 5] [--bag-steps 10000] [--no-sumo]
                            [--bv-driver level0|learned] [--bv-nodes single,by_policy] [--node-cpu]

Prints, for the shipped default scenario (1 SUT + 20 BVs, dt 0.1 s) with the BV drivers of
``--bv-driver`` (default ``level0``, the rule-based drivers SUMO is compared with; ``learned``:
the shipped policies, the scenario's default):

* in-process steps/s with recording off (best and median of ``--repeats`` timed runs of
  ``--steps`` steps after a warm-up; the JIT kernels are compiled before timing);
* a ``--bag-steps`` recorded run: steps/s with recording on and the bag's size;
* when the optional ``libsumo`` is installed (``pip install -r requirements-bench.txt``),
  SUMO's stepping rate on the same road and traffic volume, measured in this same
  process (``scripts/sumo_baseline.py``), and the ratio evoscen / SUMO.

With ``--mode graph``: the lockstep rate of the node graph (four processes: simulation,
BV, SUT, evaluator; 1 SUT + 20 BVs; the rate of the simulation node's stepping loop, without
start-up) in ``--graph-repeats`` runs of ``--graph-steps`` steps, each followed at once by an
in-process run (recording off, 10x the steps: about as long) and their ratio — the in-process
figure shows how much of the shared machine the run got; then the best and median graph rate and
the in-process rate of the same scenario with recording on (the graph always records).

Then, in graph mode, the BV-node partitions of ``--bv-nodes`` (``bvs.nodes``; default ``single`` and
``by_policy``) in ``--graph-repeats`` interleaved rounds: the median lockstep rate of each and its
ratio to the first. With ``--bv-driver learned``, ``by_policy`` is three BV nodes (competitive,
mutual, cooperative); with the rule-based ``level0`` it is one. With ``--node-cpu``, also each node's
CPU time per step in each partition (:mod:`node_cpu`: a short and a ``--graph-steps`` run, their
difference), their sum, and the steps/s two cores could give at that CPU cost if nothing else ran.

With ``--learned``: the learned BVs' cost — the in-process rate of the default scenario
with ``bvs.driver: learned`` vs ``level0``, the driver's time per step, and one batched
decision forward pass for all BVs in numpy and in torch (same weights, their max difference).

With ``--experiment``: the throughput of a small sensitivity experiment (MOBIL and the mutants of
``--experiment-mutants`` on ``--experiment-episodes`` seeds of 300 steps after the 200-step warm-up,
learned BVs, no bag) on ``--jobs`` Ray workers, counted in simulated steps, warm-ups included, per
second of wall time (the workers started and warm: a first small design runs before the timed one),
beside the core's rate measured in this same process just before and after (in-process, learned BVs,
one BV driver, recording off): the ratio experiment / (core x workers) is the share of the machine's
stepping the experiment machinery keeps (docs/performance.md "Experiments").

With ``--sut-models``: the per-decision cost of every registered SUT model (median over a
run of the default scenario) and the in-process rate with it as the SUT.

Targets (issues #2-#4): >= 5,000 steps/s in-process with recording off; a 10,000-step bag
<= 25 MB; the graph >= 1,000 steps/s on a 2-core machine; no SUT model below 3,000 steps/s
in-process. Figures, not assertions: machines are shared and noisy.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import _bootstrap  # noqa: F401
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK


def time_inprocess(steps: int, repeats: int, driver: str, warmup: int = 300) -> list[float]:
    """Steps/s of ``repeats`` timed runs (fresh scenario each, recording off)."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"bvs.driver": driver})
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


def recorded_run(steps: int, driver: str) -> dict:
    """One recorded run of ``steps`` steps: steps/s and bag size."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": steps, "bvs.driver": driver})
    with tempfile.TemporaryDirectory() as tmp:
        summary = run_inprocess(cfg, bag_dir=Path(tmp) / "bag")
        return {"steps": summary.steps, "steps_per_s": summary.steps_per_s,
                "bag_mb": summary.bag_bytes / 1e6, "messages": summary.message_count}


def graph_run(steps: int, driver: str, nodes: str = "by_policy") -> dict:
    """One graph run of ``steps`` steps with BV nodes ``nodes`` (``bvs.nodes``): the simulation
    node's lockstep rate and its flow control's waits (``flow_control_wait_s``)."""
    from evoscen_bringup.graph_runner import GraphOptions, run_graph
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": steps, "bvs.driver": driver, "bvs.nodes": nodes})
    with tempfile.TemporaryDirectory() as tmp:
        stats = Path(tmp) / "stats.json"
        result = run_graph(cfg, Path(tmp), Path(tmp) / "bag",
                           GraphOptions(node_args={"evoscen_sim": {"stats_file": str(stats)}}))
        if result.status != 0 or not stats.exists():
            raise RuntimeError(f"graph run failed: {result.node_status}")
        out = json.loads(stats.read_text())
        out["wall_with_startup_s"] = result.wall_time_s
        return out


INPROCESS_PER_GRAPH_STEP = 10
"""In-process steps timed beside each graph step (the in-process runner is ~10-20x faster)."""


def partition_figures(steps: int, repeats: int, driver: str, partitions: list[str]) -> dict:
    """``repeats`` rounds of one graph run per BV-node partition (``bvs.nodes``), interleaved so
    that each round's runs see about the same load; the median rate of each and their ratio to the
    first (docs/architecture.md §5, "BV nodes")."""
    rates: dict[str, list[float]] = {p: [] for p in partitions}
    for _ in range(repeats):
        for p in partitions:
            rates[p].append(graph_run(steps, driver, p)["steps_per_s"])
    med = {p: statistics.median(r) for p, r in rates.items()}
    return {"rates": rates, "median_steps_per_s": med,
            "ratio_to_first": {p: med[p] / med[partitions[0]] for p in partitions}}


def node_cpu_figures(steps: int, driver: str, partitions: list[str]) -> dict:
    """Each node's CPU µs per lockstep step in each partition (:func:`node_cpu.per_step_us`: a run of
    ``steps // 5`` steps and one of ``steps``), the sum over the nodes, and ``2e6 / sum``: the steps/s
    of a 2-core machine that did nothing else and whose cores never waited (an upper bound)."""
    from node_cpu import NodeCpuSampler, per_step_us

    short = max(steps // 5, 100)
    out = {}
    for p in partitions:
        seconds = []
        for n in (short, steps):
            with NodeCpuSampler() as sampler:
                graph_run(n, driver, p)
            seconds.append(sampler.seconds)
        us = per_step_us(seconds[0], seconds[1], short, steps)
        total = sum(us.values())
        out[p] = {"us_per_step": us, "total_us_per_step": total, "two_core_bound_steps_per_s": 2e6 / total}
    return out


def graph_figures(steps: int, repeats: int, driver: str) -> dict:
    """``repeats`` graph runs, each followed at once by an in-process run (recording off).

    A shared machine's load changes from minute to minute; the in-process rate timed right
    after each graph run shows what the machine gave at that moment, and the ratio of the two
    is a second figure to compare runs by (it moves less than either, though the latency-bound
    graph suffers more from a busy machine than the in-process runner does). The in-process run
    has ``INPROCESS_PER_GRAPH_STEP`` times the steps, so that it lasts about as long as the graph
    run and sees the same load.
    """
    runs = []
    for _ in range(repeats):
        g = graph_run(steps, driver)
        g["inprocess_steps_per_s"] = time_inprocess(steps * INPROCESS_PER_GRAPH_STEP, 1, driver)[0]
        g["ratio"] = g["steps_per_s"] / g["inprocess_steps_per_s"]
        runs.append(g)
    rates = [r["steps_per_s"] for r in runs]
    return {"runs": runs, "best_steps_per_s": max(rates), "median_steps_per_s": statistics.median(rates),
            "median_ratio": statistics.median(r["ratio"] for r in runs)}


def sut_model_costs(steps: int, driver: str) -> dict[str, dict]:
    """Per-decision cost (median µs) and in-process steps/s of every SUT model."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.model_registry import model_names

    out = {}
    for name in model_names("sut"):
        sc = build_scenario(load_scenario_config(None, {"sut.model": name, "bvs.driver": driver}))
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


def learned_bv_costs(steps: int, repeats: int) -> dict:
    """Batched learned-BV inference per step (torch vs numpy forward) and the in-process step rate
    of the default scenario with ``bvs.driver`` learned vs level0 (recording off)."""

    from evoscen_bringup.scenario import build_scenario
    from evoscen_bv.lane_change_decision import OBS_DIM, observation_grid
    from evoscen_sim.config.scenario_config import load_scenario_config

    out: dict = {}
    for driver in ("level0", "learned"):
        # one driver of all BVs (bvs.nodes: single): the batched cost measured below is that driver's
        cfg = load_scenario_config(None, {"bvs.driver": driver, "bvs.nodes": "single"})
        rates = []
        for _ in range(repeats):
            sc = build_scenario(cfg)
            for _ in range(300):
                sc.step()
            t0 = time.perf_counter()
            for _ in range(steps):
                sc.step()
            rates.append(steps / (time.perf_counter() - t0))
        out[f"{driver}_steps_per_s"] = statistics.median(rates)
        if driver == "learned":
            drv = sc.bv_driver
            while sc.world.step_index % drv.config.env.decision_interval_steps:
                sc.step()  # act() below then times a decision step (the world does not advance)
            t0 = time.perf_counter()
            for _ in range(steps):
                drv.act(sc.world)
            out["learned_act_us"] = (time.perf_counter() - t0) / steps * 1e6
            t0 = time.perf_counter()
            for _ in range(steps):
                drv.throttle(sc.world)
            out["learned_throttle_us"] = (time.perf_counter() - t0) / steps * 1e6
            idx = drv.vehicles
            t0 = time.perf_counter()
            for _ in range(200):
                grid = observation_grid(sc.world, idx, drv.config.grid).reshape(idx.size, OBS_DIM)
            out["grid_us"] = (time.perf_counter() - t0) / 200 * 1e6
            out.update(_forward_costs(drv, sc.world, grid))
    out["learned_added_percent"] = 100.0 * (out["level0_steps_per_s"] / out["learned_steps_per_s"] - 1.0)
    return out


EXPERIMENT_SEED = 95000
"""First seed of the benchmark's experiment designs (any: the throughput does not depend on it)."""


def core_rate(steps: int, repeats: int, driver: str = "learned") -> float:
    """The core's median in-process rate (steps/s; one BV driver of all BVs, recording off, default SUT)."""
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"bvs.driver": driver, "bvs.nodes": "single"})
    rates = []
    for _ in range(repeats):
        sc = build_scenario(cfg)
        for _ in range(300):
            sc.step()
        t0 = time.perf_counter()
        for _ in range(steps):
            sc.step()
        rates.append(steps / (time.perf_counter() - t0))
    return statistics.median(rates)


def experiment_throughput(episodes: int, mutants: list[str], jobs: int, steps: int, repeats: int,
                          episode_steps: int = 300) -> dict:
    """A small sensitivity design (MOBIL and ``mutants`` on ``episodes`` seeds, ``episode_steps`` each,
    the scenario's warm-up before every run) on ``jobs`` Ray workers: simulated steps per second of
    wall time, warm-ups included, beside the core's rate (:func:`core_rate`, before and after)."""
    import ray
    from evoscen_experiments.campaign import OBJECT_STORE_BYTES
    from evoscen_experiments.experiments import Round, config_loader, run_rounds
    from evoscen_sut.mutants import mutant_overrides

    load = config_loader(None)
    variants = [{"sut.model": "mobil"}] + [mutant_overrides("mobil", m) for m in mutants]

    def design(first: int, n: int) -> list:
        return [Round(f"v{i}", load({**v, "seed": str(seed), "steps": str(episode_steps),
                                     "recording.enabled": "false"}))
                for seed in range(first, first + n) for i, v in enumerate(variants)]

    core_before = core_rate(steps, repeats)
    cfg = design(EXPERIMENT_SEED, 1)[0].cfg
    warm = int(round(cfg.traffic.warmup_s / cfg.dt_s)) if cfg.traffic.mode == "window" else 0
    t_cold = time.perf_counter()
    ray.init(num_cpus=jobs, include_dashboard=False, log_to_driver=False, configure_logging=False,
             object_store_memory=OBJECT_STORE_BYTES)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            # the workers started, their imports done and compiled kernels loaded: one design per worker
            run_rounds(design(EXPERIMENT_SEED, jobs), Path(tmp) / "start", jobs=jobs)
            cold_s = time.perf_counter() - t_cold
            rounds = design(EXPERIMENT_SEED + jobs, episodes)
            t0 = time.perf_counter()
            results = run_rounds(rounds, Path(tmp) / "timed", jobs=jobs)
            wall = time.perf_counter() - t0
    finally:
        ray.shutdown()
    core_after = core_rate(steps, repeats)
    core = statistics.mean([core_before, core_after])
    simulated = len(rounds) * (episode_steps + warm)
    rate = simulated / wall
    busy = sum(r["wall_time_s"] for r in results.values())  # in the workers: set-up, stepping, scoring
    return {"runs": len(rounds), "episodes": episodes, "variants": len(variants), "episode_steps": episode_steps,
            "warmup_steps": warm, "simulated_steps": simulated, "wall_s": wall, "steps_per_s": rate,
            "worker_steps_per_s": simulated / busy, "start_s": cold_s, "jobs": jobs,
            "core_steps_per_s_before": core_before, "core_steps_per_s_after": core_after,
            "core_steps_per_s": core, "ratio_to_core_x_jobs": rate / (core * jobs),
            "worker_ratio_to_core": simulated / busy / core}


def _forward_costs(drv, world, grid) -> dict:
    """One batched decision forward pass for all BVs (each through its own policy): the compiled
    kernel used at run time, plain numpy matmuls, and torch (same weights); max differences."""
    import numpy as np

    col = drv.policy_columns(world, drv.vehicles)
    rows = [np.flatnonzero(col == p) for p in range(len(drv.decision_actors))]
    reps = 1000
    t0 = time.perf_counter()
    for _ in range(reps):
        ref = drv.stack.forward(grid, col)
    out = {"kernel_forward_us": (time.perf_counter() - t0) / reps * 1e6, "batch": int(grid.shape[0])}
    y = np.empty(grid.shape[0])
    t0 = time.perf_counter()
    for _ in range(reps):
        for p, actor in enumerate(drv.decision_actors):
            y[rows[p]] = actor.forward(grid[rows[p]])[:, 0]
    out["numpy_forward_us"] = (time.perf_counter() - t0) / reps * 1e6
    out["max_abs_diff_numpy_kernel"] = float(np.max(np.abs(y - ref)))
    try:
        import torch
        from evoscen_bv.td3 import build_actor
    except ImportError:
        return out
    torch.set_num_threads(1)
    nets = []
    for a in drv.decision_actors:
        net = build_actor(a.state_dim, 1, a.max_action, a.W1.shape[1])
        with torch.no_grad():
            for layer, w, b in ((net.l1, a.W1, a.b1), (net.l2, a.W2, a.b2), (net.l3, a.W3, a.b3)):
                layer.weight.copy_(torch.as_tensor(w.T))
                layer.bias.copy_(torch.as_tensor(b))
        nets.append(net)
    x = torch.as_tensor(grid, dtype=torch.float32)
    with torch.no_grad():
        t0 = time.perf_counter()
        for _ in range(reps):
            for p, net in enumerate(nets):
                y[rows[p]] = net(x[rows[p]]).numpy()[:, 0]
        out["torch_forward_us"] = (time.perf_counter() - t0) / reps * 1e6
    out["max_abs_diff_torch_kernel"] = float(np.max(np.abs(y - ref)))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=5000, help="timed steps per repeat (default 5000)")
    ap.add_argument("--repeats", type=int, default=5, help="timed repeats (default 5)")
    ap.add_argument("--bag-steps", type=int, default=10000, help="steps of the recorded run (default 10000; 0 = skip)")
    ap.add_argument("--no-sumo", action="store_true", help="skip the SUMO reference even if libsumo is installed")
    ap.add_argument("--mode", choices=("inprocess", "graph"), default="inprocess",
                    help="graph: also the lockstep rate of the node graph (default: in-process only)")
    ap.add_argument("--graph-steps", type=int, default=5000, help="steps of each graph run (default 5000)")
    ap.add_argument("--graph-repeats", type=int, default=3, help="graph runs (default 3)")
    ap.add_argument("--bv-nodes", default="single,by_policy",
                    help="graph: also compare these BV-node partitions (bvs.nodes), comma-separated, the first "
                         "the reference (default single,by_policy; with --bv-driver learned by_policy is three BV "
                         "nodes, with level0 one; empty: skip)")
    ap.add_argument("--node-cpu", action="store_true",
                    help="graph: also each node's CPU time per step in each --bv-nodes partition")
    ap.add_argument("--sut-models", action="store_true", help="also the per-decision cost of every SUT model")
    ap.add_argument("--learned", action="store_true",
                    help="also the learned BVs' inference cost and the in-process rate with learned vs level-0 BVs")
    ap.add_argument("--experiment", action="store_true",
                    help="also the throughput of a small sensitivity experiment beside the core's rate")
    ap.add_argument("--experiment-episodes", type=int, default=8,
                    help="--experiment: seeds (episodes per variant; default 8)")
    ap.add_argument("--experiment-mutants", default="tailgating,blind_behind,stale",
                    help="--experiment: mutants of MOBIL run beside it (default tailgating,blind_behind,stale)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="--experiment: Ray workers (default: CPU count)")
    ap.add_argument("--bv-driver", choices=("level0", "learned"), default="level0",
                    help="the BVs' drivers in every figure but --learned's (default level0)")
    ap.add_argument("--json", action="store_true", help="also print the figures as one JSON line")
    args = ap.parse_args(argv)
    for name in ("steps", "repeats", "bag_steps", "graph_steps", "graph_repeats", "experiment_episodes", "jobs"):
        lowest = 0 if name == "bag_steps" else 1
        if getattr(args, name) < lowest:
            print(f"error: --{name.replace('_', '-')} = {getattr(args, name)}: expected "
                  f"{'an integer >= 0 (0 = skip)' if lowest == 0 else 'a positive integer'}", file=sys.stderr)
            return EXIT_BAD_INPUT
    mutants = [m.strip() for m in args.experiment_mutants.split(",") if m.strip()]
    from evoscen_sut.mutants import LIBRARY

    if len(set(mutants)) != len(mutants) or any(m not in LIBRARY for m in mutants):
        print(f"error: --experiment-mutants = {args.experiment_mutants!r}: expected distinct comma-separated "
              f"mutant names from {', '.join(LIBRARY)}", file=sys.stderr)
        return EXIT_BAD_INPUT

    partitions = [p.strip() for p in args.bv_nodes.split(",") if p.strip()]
    for p in partitions:
        if not (p in ("single", "by_policy") or (p.isdigit() and 1 <= int(p) <= 32)):
            print(f"error: --bv-nodes = {args.bv_nodes!r}: expected comma-separated by_policy, single or numbers "
                  "in [1, 32]", file=sys.stderr)
            return EXIT_BAD_INPUT
    drv = args.bv_driver
    out: dict = {"python": sys.version.split()[0], "bv_driver": drv}
    rates = time_inprocess(args.steps, args.repeats, drv)
    out["inprocess_best_steps_per_s"] = max(rates)
    out["inprocess_median_steps_per_s"] = statistics.median(rates)
    print(f"evoscen in-process, 1 SUT + 20 BVs ({drv}), recording off, {args.steps} steps x {args.repeats}:")
    print(f"  best {max(rates):8.0f} steps/s   median {statistics.median(rates):8.0f} steps/s   "
          f"(target >= 5000)")
    if args.bag_steps:
        rec = recorded_run(args.bag_steps, drv)
        out["recorded"] = rec
        print(f"evoscen in-process ({drv} BVs), recording on, {rec['steps']} steps:")
        print(f"  {rec['steps_per_s']:8.0f} steps/s   bag {rec['bag_mb']:.2f} MB, {rec['messages']} messages   (target <= 25 MB)")
    if args.mode == "graph":
        out["graph"] = graph_figures(args.graph_steps, args.graph_repeats, drv)
        runs = out["graph"]["runs"]
        print(f"evoscen node graph (sim, BV, SUT, evaluator processes; {drv} BVs; lockstep; recording), "
              f"{args.graph_steps} steps x {len(runs)}, each followed by an in-process run (recording off, "
              f"{args.graph_steps * INPROCESS_PER_GRAPH_STEP} steps, about as long):")
        for i, r in enumerate(runs, 1):
            print(f"  run {i}: {r['steps_per_s']:8.0f} steps/s lockstep ({r['wall_with_startup_s']:.1f} s with start-up)"
                  f"   in-process {r['inprocess_steps_per_s']:8.0f} steps/s   graph / in-process {r['ratio']:.3f}")
        g = out["graph"]
        print(f"  best {g['best_steps_per_s']:8.0f} steps/s   median {g['median_steps_per_s']:8.0f} steps/s lockstep   "
              f"(target >= 1000)   median graph / in-process {g['median_ratio']:.3f}")
        rec = out.get("recorded") or recorded_run(args.graph_steps, drv)
        print(f"  same scenario in-process: {rec['steps_per_s']:8.0f} steps/s recording on, "
              f"{out['inprocess_median_steps_per_s']:8.0f} steps/s recording off")
        if partitions:
            pf = partition_figures(args.graph_steps, args.graph_repeats, drv, partitions)
            out["graph"]["partitions"] = pf
            print(f"BV nodes (bvs.nodes; {drv} BVs), {args.graph_steps} steps x {args.graph_repeats}, interleaved:")
            for p in partitions:
                runs_text = " ".join(f"{r:.0f}" for r in pf["rates"][p])
                print(f"  {p:10s} median {pf['median_steps_per_s'][p]:8.0f} steps/s lockstep   "
                      f"{pf['ratio_to_first'][p] * 100:5.1f} % of {partitions[0]}   (runs: {runs_text})")
            if args.node_cpu:
                nc = node_cpu_figures(args.graph_steps, drv, partitions)
                out["graph"]["node_cpu"] = nc
                print(f"CPU per lockstep step by node (difference of a {max(args.graph_steps // 5, 100)}- and a "
                      f"{args.graph_steps}-step run; user + system, all threads):")
                for p in partitions:
                    nodes = "  ".join(f"{k} {v:.0f}" for k, v in sorted(nc[p]["us_per_step"].items()))
                    print(f"  {p:10s} {nc[p]['total_us_per_step']:6.0f} us in all ({nodes}); two cores doing nothing "
                          f"else: <= {nc[p]['two_core_bound_steps_per_s']:.0f} steps/s")
    if args.sut_models:
        costs = sut_model_costs(args.steps, drv)
        out["sut_models"] = costs
        print(f"SUT models (in-process, 20 {drv} BVs, {args.steps} steps; target >= 3000 steps/s each):")
        for name, c in costs.items():
            print(f"  {name:12s} {c['decision_us']:7.1f} us/decision   {c['steps_per_s']:8.0f} steps/s")
    if args.learned:
        lc = learned_bv_costs(args.steps, args.repeats)
        out["learned"] = lc
        print(f"learned BVs (shipped policies, 20 BVs, one batched forward per step; {args.steps} steps x {args.repeats}):")
        print(f"  in-process {lc['learned_steps_per_s']:8.0f} steps/s learned vs {lc['level0_steps_per_s']:8.0f} level-0: "
              f"{lc['learned_added_percent']:+.0f} % step time   (target <= 50 %)")
        print(f"  controller (every step) {lc['learned_throttle_us']:.1f} us; a decision step (every 10th: grid, forward, "
              f"rule constraints, controller) {lc['learned_act_us']:.1f} us, of which the grid {lc['grid_us']:.1f} us")
        line = (f"  decision forward pass, {lc['batch']} BVs, 3 policies: compiled kernel {lc['kernel_forward_us']:.1f} us, "
                f"numpy {lc['numpy_forward_us']:.1f} us")
        if "torch_forward_us" in lc:
            line += f", torch {lc['torch_forward_us']:.1f} us"
        print(line)
        print(f"  max |difference| to the kernel: numpy {lc['max_abs_diff_numpy_kernel']:.1e}"
              + (f", torch (float32) {lc['max_abs_diff_torch_kernel']:.1e}" if "torch_forward_us" in lc else ""))
    if args.experiment:
        ex = experiment_throughput(args.experiment_episodes, mutants, args.jobs, args.steps, args.repeats)
        out["experiment"] = ex
        print(f"experiment throughput (sensitivity design: MOBIL + {ex['variants'] - 1} mutants x {ex['episodes']} "
              f"episodes x {ex['episode_steps']} steps + {ex['warmup_steps']} warm-up steps, learned BVs, "
              f"{ex['jobs']} Ray workers, started and warm; {ex['start_s']:.1f} s to start them):")
        print(f"  {ex['runs']} runs, {ex['simulated_steps']:,} simulated steps (warm-ups included) in "
              f"{ex['wall_s']:.1f} s: {ex['steps_per_s']:8.0f} steps/s")
        print(f"  core in this process (learned BVs, one driver, recording off): {ex['core_steps_per_s_before']:.0f} "
              f"before, {ex['core_steps_per_s_after']:.0f} after; experiment / (core x {ex['jobs']} workers) = "
              f"{ex['ratio_to_core_x_jobs']:.2f}   (target >= 0.60)")
        print(f"  in the workers (the runs' own wall time: set-up, stepping, scoring): "
              f"{ex['worker_steps_per_s']:8.0f} steps/s per worker = {ex['worker_ratio_to_core']:.2f} of the core")
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
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
