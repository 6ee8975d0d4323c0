"""Batched worlds in ``scripts/bench.py --batched 1,8,64``: many scored worlds without a bag stepped in lockstep in
each of ``--jobs`` processes (:func:`evoscen_bringup.inprocess.run_plans`; MOBIL SUT, learned BVs, the shipped
make-up), in vehicle-steps/s beside libsumo's single-process rate on the same road (docs/performance.md "Many worlds
at once"). Each process builds its worlds first (their warm-ups untimed) and runs one short world (kernels loaded),
then times the lockstep run; the figure is all processes' vehicle-steps over the longest of their times. Figures only; nothing is asserted.
"""

from __future__ import annotations

import time

FIRST_SEED = 1035000
"""The first seed of the batched worlds (any: the rate does not depend on it); each process its own seeds."""


def parse_sizes(text: str) -> list[int]:
    """The batch sizes of ``--batched`` (comma-separated, distinct, each at least 1; empty: none), else a one-line
    InputError naming the option."""
    from evoscen_sim.errors import InputError

    if not str(text).strip():
        return []
    try:
        sizes = [int(t) for t in str(text).split(",")]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < 1 or len(set(sizes)) != len(sizes):
        raise InputError(f"--batched = {text!r}: expected distinct comma-separated batch sizes, each at least 1")
    return sizes


def batched_plans(size: int, steps: int, first_seed: int) -> tuple[list, object]:
    """``size`` scored worlds without a bag (seeds ``first_seed`` on, MOBIL SUT, learned BVs, ``steps`` steps) built from
    one start cache, and one more short world (20 steps) to run first, untimed, so that the kernels are loaded from
    numba's cache before a clock starts: (the plans, the short world's plan)."""
    from evoscen_bringup.plan import plan_of
    from evoscen_bringup.starts import StartCache
    from evoscen_experiments.experiments import config_loader

    load = config_loader(None)
    cache = StartCache(size=max(size, 1))

    def plan(seed: int, n: int):
        cfg = load({"sut.model": "mobil", "bvs.driver": "learned", "seed": str(seed), "steps": str(n),
                    "recording.enabled": "false"})
        return plan_of(cfg, recorded=False, scenario=cache.scenario(cfg, partitioned=False))

    return [plan(first_seed + k, steps) for k in range(size)], plan(first_seed + size, 20)


def batch_rate(size: int, steps: int, first_seed: int) -> tuple[int, float]:
    """In this process: :func:`batched_plans` built, the short world run, then the worlds stepped in lockstep;
    (their vehicle-steps, the lockstep run's seconds)."""
    from evoscen_bringup.inprocess import run_plans

    plans, warm = batched_plans(size, steps, first_seed)
    vehicle_steps = sum(p.scenario.world.n * steps for p in plans)
    run_plans([warm])
    t0 = time.perf_counter()
    failed = [r for r in run_plans(plans) if isinstance(r, Exception)]
    wall = time.perf_counter() - t0
    if failed:
        raise RuntimeError(f"batched bench: {len(failed)} world(s) failed: {failed[0]}")
    return vehicle_steps, wall


def measure(sizes: list[int], steps: int, jobs: int) -> list[dict]:
    """Per batch size: ``jobs`` processes, each :func:`batch_rate` of its own seeds at once; vehicle-steps/s over the
    longest process's time."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    out = []
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
        for size in sizes:
            seeds = [FIRST_SEED + 100_000 * j + 1_000 * size for j in range(jobs)]
            done = list(pool.map(batch_rate, [size] * jobs, [steps] * jobs, seeds))
            vehicle_steps = sum(v for v, _ in done)
            wall = max(w for _, w in done)
            out.append({"batch": size, "jobs": jobs, "worlds": size * jobs, "steps": steps,
                        "vehicle_steps": vehicle_steps, "wall_s": wall, "vehicle_steps_per_s": vehicle_steps / wall})
    return out


def report(sizes: list[int], steps: int, jobs: int, sumo: bool) -> dict:
    """:func:`measure`, with libsumo's single-process vehicle-steps/s on the same road (``sumo``), printed."""
    rows = measure(sizes, steps, jobs)
    out: dict = {"batched": rows}
    print(f"batched worlds (MOBIL SUT, learned BVs, shipped make-up, scored, no bag), lockstep in each of {jobs} "
          f"process(es), {steps} steps:")
    ref = None
    if sumo:
        from evoscen_experiments.sumo_baseline import measure_sumo_steps_per_second, sumo_available

        ok, why = sumo_available()
        if ok:
            s = measure_sumo_steps_per_second(steps=max(steps, 1000), vehicles=21, seed=0, in_process=True)
            ref = s["steps_per_s"] * s["mean_vehicles"]
            out["sumo_vehicle_steps_per_s"] = ref
        else:
            print(f"  SUMO skipped: {why}")
    for r in rows:
        ratio = f"   {r['vehicle_steps_per_s'] / ref:.2f} of libsumo's" if ref else ""
        r["over_sumo"] = r["vehicle_steps_per_s"] / ref if ref else None
        print(f"  batch {r['batch']:>4} x {r['jobs']}: {r['vehicle_steps_per_s']:10.0f} vehicle-steps/s "
              f"({r['worlds']} worlds in {r['wall_s']:.1f} s){ratio}")
    if ref:
        print(f"  libsumo, one process, same road: {ref:.0f} vehicle-steps/s (target: batched >= 5x)")
    return out
