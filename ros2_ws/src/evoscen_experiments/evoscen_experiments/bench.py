"""The benchmark of ``scripts/bench.py``: in-process step rates, a recorded run's bag, the SUT models' and
the learned BVs' costs, an experiment's throughput beside the core's rate, and SUMO's rate for reference,
each printed beside a reference measured in the same process (docs/performance.md).

The node graph's figures are in :mod:`evoscen_experiments.bench_graph`. Figures, not assertions: the
machines are shared and noisy.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from evoscen_experiments.bench_runs import INPROCESS_WARMUP, timed_runs  # the step-rate loop (bench_makeups uses it too)

EXPERIMENT_SEED = 95000
"""First seed of the benchmark's experiment designs (any: the throughput does not depend on it)."""

COUNT_OPTIONS = ("steps", "repeats", "bag_steps", "graph_steps", "graph_repeats", "experiment_episodes", "jobs")
"""The benchmark's counts: each at least 1 (``bag_steps`` at least 0, 0 = skip)."""


def child_env() -> dict[str, str]:
    """This process's environment with its import path on ``PYTHONPATH``, for a child ``python -c``: the
    child imports the packages as this process does (``scripts/_bootstrap.py`` puts them on ``sys.path``)."""
    paths = [p for p in sys.path if p] + [os.environ.get("PYTHONPATH", "")]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in paths if p)}


def time_inprocess(steps: int, repeats: int, driver: str, warmup: int = INPROCESS_WARMUP) -> list[float]:
    """Steps/s of ``repeats`` timed runs (fresh scenario each, recording off)."""
    from evoscen_sim.config.scenario_config import load_scenario_config

    return timed_runs(load_scenario_config(None, {"bvs.driver": driver}), steps, repeats, warmup)[0]


def core_rate(steps: int, repeats: int, driver: str = "learned") -> float:
    """The core's median in-process rate (steps/s; one BV driver of all BVs, recording off, default SUT)."""
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"bvs.driver": driver, "bvs.nodes": "single"})
    return statistics.median(timed_runs(cfg, steps, repeats)[0])


def recorded_run(steps: int, driver: str) -> dict:
    """One recorded run of ``steps`` steps: steps/s and bag size."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": steps, "bvs.driver": driver})
    with tempfile.TemporaryDirectory() as tmp:
        summary = run_inprocess(cfg, bag_dir=Path(tmp) / "bag")
        return {"steps": summary.steps, "steps_per_s": summary.steps_per_s,
                "bag_mb": summary.bag_bytes / 1e6, "messages": summary.message_count}


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
    from evoscen_bv.lane_change_decision import OBS_DIM, observation_grid
    from evoscen_sim.config.scenario_config import load_scenario_config

    out: dict = {}
    for driver in ("level0", "learned"):
        # one driver of all BVs (bvs.nodes: single): the batched cost measured below is that driver's
        rates, sc = timed_runs(load_scenario_config(None, {"bvs.driver": driver, "bvs.nodes": "single"}),
                               steps, repeats)
        out[f"{driver}_steps_per_s"] = statistics.median(rates)
    # the learned driver itself: under the highD make-up (the default) it drives the cars inside the
    # make-up's driver (evoscen_bv.truck.MakeupDriver), the trucks keep theirs
    drv = getattr(sc.bv_driver, "car_driver", sc.bv_driver)
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
                layer.weight.copy_(torch.as_tensor(np.array(w.T)))  # a copy: the actor's arrays are read-only
                layer.bias.copy_(torch.as_tensor(np.array(b)))
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


def checked_options(args) -> tuple[list[str], list[str]]:
    """The mutants of ``--experiment-mutants`` and the partitions of ``--bv-nodes``, after every count of
    :data:`COUNT_OPTIONS` is checked (else a one-line InputError naming the option)."""
    from evoscen_sim.errors import InputError
    from evoscen_sut.mutants import LIBRARY

    for name in COUNT_OPTIONS:
        lowest = 0 if name == "bag_steps" else 1
        if getattr(args, name) < lowest:
            raise InputError(f"--{name.replace('_', '-')} = {getattr(args, name)}: expected "
                             f"{'an integer >= 0 (0 = skip)' if lowest == 0 else 'a positive integer'}")
    mutants = [m.strip() for m in args.experiment_mutants.split(",") if m.strip()]
    if len(set(mutants)) != len(mutants) or any(m not in LIBRARY for m in mutants):
        raise InputError(f"--experiment-mutants = {args.experiment_mutants!r}: expected distinct comma-separated "
                         f"mutant names from {', '.join(LIBRARY)}")
    partitions = [p.strip() for p in args.bv_nodes.split(",") if p.strip()]
    for p in partitions:
        if not (p in ("single", "by_policy") or (p.isdigit() and 1 <= int(p) <= 32)):
            raise InputError(f"--bv-nodes = {args.bv_nodes!r}: expected comma-separated by_policy, single or "
                             "numbers in [1, 32]")
    return mutants, partitions


def run(args) -> None:
    """The benchmark of ``scripts/bench.py`` with its options ``args`` (an argparse namespace): the figures
    its options ask for, printed (and with ``args.json`` one JSON line of them all)."""
    from evoscen_experiments import bench_batched, bench_graph, bench_makeups

    mutants, partitions = checked_options(args)
    makeups = bench_makeups.parse_makeups(args.makeups)
    batched = bench_batched.parse_sizes(getattr(args, "batched", ""))
    drv = args.bv_driver
    out: dict = {"python": sys.version.split()[0], "bv_driver": drv}
    rates = time_inprocess(args.steps, args.repeats, drv)
    out["inprocess_best_steps_per_s"] = max(rates)
    out["inprocess_median_steps_per_s"] = statistics.median(rates)
    print(f"evoscen in-process, 1 SUT + 20 BVs ({drv}), recording off, {args.steps} steps x {args.repeats}:")
    print(f"  best {max(rates):8.0f} steps/s   median {statistics.median(rates):8.0f} steps/s   "
          f"(target >= 5000)")
    if makeups:
        out["makeups"] = bench_makeups.report(makeups, bench_makeups.DRIVERS if args.learned else ("level0",),
                                              args.steps, args.repeats, not args.no_sumo)
    if args.bag_steps:
        rec = recorded_run(args.bag_steps, drv)
        out["recorded"] = rec
        print(f"evoscen in-process ({drv} BVs), recording on, {rec['steps']} steps:")
        print(f"  {rec['steps_per_s']:8.0f} steps/s   bag {rec['bag_mb']:.2f} MB, {rec['messages']} messages   (target <= 25 MB)")
    if args.mode == "graph":
        bench_graph.report(args, out, partitions, lambda n: time_inprocess(n, 1, drv)[0],
                           lambda: out.get("recorded") or recorded_run(args.graph_steps, drv))
    if args.sut_models:
        costs = sut_model_costs(args.steps, drv)
        out["sut_models"] = costs
        print(f"SUT models (in-process, 20 {drv} BVs, {args.steps} steps; target >= 3000 steps/s each):")
        for name, c in costs.items():
            print(f"  {name:12s} {c['decision_us']:7.1f} us/decision   {c['steps_per_s']:8.0f} steps/s")
    if args.learned:
        out["learned"] = _report_learned(learned_bv_costs(args.steps, args.repeats), args.steps, args.repeats)
    if args.experiment:
        out["experiment"] = _report_experiment(experiment_throughput(args.experiment_episodes, mutants, args.jobs,
                                                                     args.steps, args.repeats))
    if batched:
        out.update(bench_batched.report(batched, args.steps, args.jobs, not args.no_sumo))
    if not args.no_sumo:
        _report_sumo(out, args.steps)
    if args.json:
        print(json.dumps(out))


def _report_learned(lc: dict, steps: int, repeats: int) -> dict:
    print(f"learned BVs (shipped policies, 20 BVs, one batched forward per step; {steps} steps x {repeats}):")
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
    return lc


def _report_experiment(ex: dict) -> dict:
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
    return ex


def _report_sumo(out: dict, steps: int) -> None:
    """SUMO's rate on the same road and traffic volume, in this process, and the ratio evoscen / SUMO."""
    from evoscen_experiments.sumo_baseline import measure_sumo_steps_per_second, sumo_available

    ok, why = sumo_available()
    if not ok:
        print(f"SUMO reference skipped: {why} (pip install -r requirements-bench.txt)")
        return
    sumo = measure_sumo_steps_per_second(steps=steps, vehicles=21, seed=0, in_process=True)
    out["sumo"] = sumo
    out["ratio_evoscen_over_sumo"] = out["inprocess_median_steps_per_s"] / sumo["steps_per_s"]
    print(f"SUMO reference ({sumo['sumo_version']}, libsumo, same road, {sumo['mean_vehicles']:.1f} vehicles, "
          f"Krauss, dt 0.1 s), {sumo['steps']} steps:")
    print(f"  {sumo['steps_per_s']:8.0f} steps/s")
    print(f"ratio evoscen / SUMO (median): {out['ratio_evoscen_over_sumo']:.2f}")


def campaign_throughput(runs: int, steps: int, cpus: int, reference: int, sut: str) -> None:
    """``scripts/bench_campaign.py``: a campaign of ``runs`` runs (``steps`` steps, SUT ``sut``, other seeds)
    on a local Ray of ``cpus`` workers, from nothing (Ray started, workers warmed up, results written),
    between two single-process references of ``reference`` runs (the same seeds, after a warm-up run);
    prints the rates and the ratio campaign / (reference × workers) (docs/campaigns.md)."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_experiments.campaign import run_campaign
    from evoscen_experiments.campaign_spec import expand, load_spec
    from evoscen_sim.config.scenario_config import load_scenario_config

    over = {"steps": str(steps), "sut.model": sut, "recording.enabled": "false"}
    run_inprocess(load_scenario_config(None, {**over, "seed": "100000"}), bag_dir=None, evaluate=True, plots=False)

    def single() -> float:
        """Runs/s of ``reference`` runs one after another in this process (the same seeds each time)."""
        t0 = time.perf_counter()
        for i in range(reference):
            cfg = load_scenario_config(None, {**over, "seed": str(100001 + i)})
            run_inprocess(cfg, bag_dir=None, evaluate=True, plots=False)
        return reference / (time.perf_counter() - t0)

    before = single()
    with tempfile.TemporaryDirectory() as tmp:
        spec_path = Path(tmp) / "bench.yaml"
        spec_path.write_text(f"name: bench\nsteps: {steps}\nseeds: {{first: 0, count: {runs}}}\n"
                             f"set: {{sut.model: {sut}}}\n", encoding="utf-8")
        result = run_campaign(expand(load_spec(spec_path)), Path(tmp) / "out", cpus=cpus)
    after = single()
    ref = (before + after) / 2
    rate = result.computed / result.wall_s
    print(f"bench_campaign: {runs} runs x {steps} steps, SUT {sut}, {cpus} Ray workers")
    print(f"  single process: {ref:.3f} runs/s, the mean of {before:.3f} before and {after:.3f} after the campaign "
          f"({reference} runs each, after a warm-up run)")
    print(f"  campaign:       {rate:.3f} runs/s ({result.computed} runs in {result.wall_s:.1f} s, Ray start-up "
          f"and worker warm-up included; {len(result.failed)} failed)")
    print(f"  ratio campaign / (single x {cpus}): {rate / (ref * cpus):.2f} (target >= 0.85; against "
          f"the reference before {rate / (before * cpus):.2f}, after {rate / (after * cpus):.2f})")
