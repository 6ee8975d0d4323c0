"""The traffic make-ups in ``scripts/bench.py``: one world's step rate under each ``bvs.makeup``, with
level-0 BVs and (``--learned``) learned BVs, beside SUMO on the same road, in steps/s and vehicle-steps/s.

Every configuration runs the shipped default scenario (its SUT, recording off) with one driver of all BVs
(``bvs.nodes: single``). The timed repeats alternate the configurations (highd, uniform, …, SUMO, then again)
so that each sees the same load of a shared machine; a configuration's figure is the median over its
repeats. Vehicle-steps/s = steps/s × the vehicles in the world (the mean over its repeats): SUMO's count
varies as vehicles leave and re-enter, evoscen's world keeps its rows.
"""

from __future__ import annotations

import statistics
import time

DRIVERS = ("level0", "learned")


def parse_makeups(text: str) -> list[str]:
    """The make-ups of ``--makeups`` (comma-separated, distinct; empty: none, the table skipped); else a
    one-line InputError."""
    from evoscen_sim.config.config_schema import MAKEUPS
    from evoscen_sim.errors import InputError

    names = [m.strip() for m in str(text).split(",")]
    if names == [""]:
        return []
    if any(m not in MAKEUPS for m in names) or len(set(names)) != len(names):
        raise InputError(f"--makeups = {text!r}: expected distinct comma-separated make-ups from {', '.join(MAKEUPS)}")
    return names


def vehicle_steps_per_s(steps_per_s: float, vehicles: list[float]) -> float:
    """``steps_per_s`` × the mean of ``vehicles`` (the vehicles in the world of each repeat)."""
    return steps_per_s * statistics.fmean(vehicles)


def ratios(rates: dict[str, float], sumo_steps_per_s: float | None) -> dict[str, float]:
    """The comparisons of ``rates`` (``"makeup/driver"`` -> median steps/s): per make-up evoscen / SUMO
    (level-0 BVs, ``"evoscen_over_sumo/<makeup>"``), per driver ``highd`` / ``uniform``
    (``"highd_over_uniform/<driver>"``), and per make-up the learned BVs' extra step time in percent,
    100 · (level-0 rate / learned rate − 1) (``"learned_added_percent/<makeup>"``); each where both rates exist."""
    out: dict[str, float] = {}
    makeups = sorted({k.split("/")[0] for k in rates})
    for m in makeups:
        if sumo_steps_per_s and f"{m}/level0" in rates:
            out[f"evoscen_over_sumo/{m}"] = rates[f"{m}/level0"] / sumo_steps_per_s
    for d in DRIVERS:
        if f"highd/{d}" in rates and f"uniform/{d}" in rates:
            out[f"highd_over_uniform/{d}"] = rates[f"highd/{d}"] / rates[f"uniform/{d}"]
    for m in makeups:
        if f"{m}/level0" in rates and f"{m}/learned" in rates:
            out[f"learned_added_percent/{m}"] = 100.0 * (rates[f"{m}/level0"] / rates[f"{m}/learned"] - 1.0)
    return out


def measure(makeups: list[str], drivers: tuple[str, ...], steps: int, repeats: int, sumo: bool) -> dict:
    """Steps/s of each (make-up, driver) and of SUMO (``sumo``, libsumo in this process, the world's
    vehicle count), ``repeats`` timed runs each, alternated; with the vehicles, vehicle-steps/s and :func:`ratios`."""
    from evoscen_sim.config.scenario_config import load_scenario_config

    from evoscen_experiments.bench_runs import timed_runs

    cfgs = {f"{m}/{d}": load_scenario_config(None, {"bvs.makeup": m, "bvs.driver": d, "bvs.nodes": "single"})
            for m in makeups for d in drivers}
    runs: dict[str, dict[str, list[float]]] = {k: {"rates": [], "vehicles": []} for k in cfgs}
    sumo_runs: list[dict] = []
    vehicles = 1 + next(iter(cfgs.values())).bvs.count
    skipped = None
    if sumo:
        from evoscen_experiments.sumo_baseline import measure_sumo_steps_per_second, sumo_available

        ok, skipped = sumo_available()
        sumo, skipped = ok, None if ok else skipped
    for _ in range(repeats):
        for key, cfg in cfgs.items():
            rate, sc = timed_runs(cfg, steps, 1)
            runs[key]["rates"] += rate
            runs[key]["vehicles"].append(float(sc.world.n))
        if sumo:
            sumo_runs.append(measure_sumo_steps_per_second(steps=steps, vehicles=vehicles, seed=0, in_process=True))
    out: dict = {"steps": steps, "repeats": repeats, "configs": {}}
    if skipped:
        out["sumo_skipped"] = skipped
    for key, r in runs.items():
        median = statistics.median(r["rates"])
        out["configs"][key] = {"steps_per_s": median, "rates": r["rates"], "vehicles": statistics.fmean(r["vehicles"]),
                               "vehicle_steps_per_s": vehicle_steps_per_s(median, r["vehicles"])}
    sumo_rate = None
    if sumo_runs:
        sumo_rate = statistics.median(s["steps_per_s"] for s in sumo_runs)
        veh = [s["mean_vehicles"] for s in sumo_runs]
        out["sumo"] = {"steps_per_s": sumo_rate, "rates": [s["steps_per_s"] for s in sumo_runs],
                       "vehicles": statistics.fmean(veh), "vehicle_steps_per_s": vehicle_steps_per_s(sumo_rate, veh),
                       "sumo_version": sumo_runs[0]["sumo_version"]}
    out["ratios"] = ratios({k: c["steps_per_s"] for k, c in out["configs"].items()}, sumo_rate)
    return out


def report(makeups: list[str], drivers: tuple[str, ...], steps: int, repeats: int, sumo: bool) -> dict:
    """:func:`measure`, printed as a table and the ratios; returns its figures."""
    t0 = time.perf_counter()
    res = measure(makeups, drivers, steps, repeats, sumo)
    print(f"one world by traffic make-up (default SUT, one BV driver, recording off), {steps} steps x {repeats}, "
          f"alternated ({time.perf_counter() - t0:.0f} s):")
    print(f"  {'configuration':28s} {'steps/s':>9s} {'vehicles':>9s} {'vehicle-steps/s':>16s}")
    rows = [(f"evoscen {k.replace('/', ', ')} BVs", c) for k, c in res["configs"].items()]
    if "sumo" in res:
        rows.append((f"{res['sumo']['sumo_version']} (libsumo)", res["sumo"]))
    for label, c in rows:
        print(f"  {label:28s} {c['steps_per_s']:9.0f} {c['vehicles']:9.1f} {c['vehicle_steps_per_s']:16.0f}")
    for key, value in res["ratios"].items():
        what, which = key.split("/")
        text = {"evoscen_over_sumo": f"evoscen / SUMO ({which}, level-0 BVs): {value:.2f}",
                "highd_over_uniform": f"highd / uniform ({which} BVs): {value:.2f}",
                "learned_added_percent": f"learned BVs' extra step time ({which}): {value:+.0f} %"}[what]
        print(f"  {text}")
    if "sumo_skipped" in res:
        print(f"  SUMO skipped: {res['sumo_skipped']} (pip install -r requirements-bench.txt)")
    return res
