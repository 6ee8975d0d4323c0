"""Does the test keep testing? The traffic around the SUT over whole runs (docs/method.md §1).

``scripts/experiment_traffic.py`` parses the command line and calls :func:`main`: the SUT on a block of
seeds in-process (no bag, :func:`one_run`), and from each run's report and states the BVs within ±100 m
per 30-s window, the SUT's jumps (:func:`sut_jumps`), where its exposures fall, BV–BV collisions per
BV-hour, window entries and shifts (:func:`figures`); with ``--compare-steps`` the paired difference of
intelligence between two run lengths (length independence, docs/evaluation.md).
"""

from __future__ import annotations

import json
import sys

import numpy as np
from evoscen_contract.contract import EVENT_COLLISION, EVENT_REENTRY, EVENT_SHIFT, EXIT_OK

from evoscen_experiments.stats import fmt_ci, mean_ci


def sut_jumps(s: np.ndarray, lane: np.ndarray, target: np.ndarray, sut: int, dt_s: float,
              max_speed_mps: float, shifts: dict[int, float]) -> int:
    """States in which the SUT moved other than by driving: its arc length changed by more than it can drive
    in a step once the window's shift is undone, or it came to a lane that was neither its lane nor its
    target lane; ``s``, ``lane``, ``target`` are (states × vehicles); ``shifts``: the ``shift_m`` of each
    ``evoscen/shift`` event by its step (the state it led to)."""
    jumps = 0
    for k in range(1, s.shape[0]):
        ds = s[k, sut] - s[k - 1, sut] + shifts.get(k, 0.0)
        moved = not (-1e-6 <= ds <= max_speed_mps * dt_s + 1e-6)
        lane_ok = lane[k, sut] in (lane[k - 1, sut], target[k - 1, sut])
        jumps += bool(moved or not lane_ok)
    return jumps


def one_run(cfg) -> dict:  # a ScenarioConfig
    """One run in-process: its traffic figures, jumps, exposures, BV–BV collisions, entries, shifts and scores."""
    from evoscen_bringup.inprocess import run_inprocess

    summary = run_inprocess(cfg, bag_dir=None, evaluate=True, keep_run=True)
    rep, run = summary.report, summary.run
    cols = run.columns
    sut = int(run.sut_index)
    ids = np.asarray(run.ids)
    n_bv = ids.size - 1
    steps = int(rep["safety"]["steps"])
    bv_bv = [e for e in run.events_named(EVENT_COLLISION) if int(ids[sut]) not in e["ids"]]
    starts = [int(x["start_state"]) for x in rep["safety"]["exposure_list"]]
    return {
        "seed": cfg.seed, "steps": steps,
        "per_window": rep["traffic"]["per_window_mean_bvs"], "mean_bvs": rep["traffic"]["mean_bvs"],
        "jumps": sut_jumps(np.asarray(cols["s"]), np.asarray(cols["lane"]), np.asarray(cols["target_lane"]), sut,
                           float(run.dt_s), cfg.vehicle.max_speed_mps,
                           {int(e["step"]): float(e["shift_m"]) for e in run.events_named(EVENT_SHIFT)}),
        "exposures": len(starts), "exposures_first_10pct": sum(1 for k in starts if k < 0.1 * steps),
        "bv_bv_collisions": len(bv_bv), "bv_hours": n_bv * steps * float(run.dt_s) / 3600.0,
        "entries": len(run.events_named(EVENT_REENTRY)), "shifts": len(run.events_named(EVENT_SHIFT)),
        "intelligence": rep["intelligence"]["score"],
        "efficiency": rep["intelligence"]["weighted"]["efficiency"],
    }


def figures(sut: str, runs: list[dict], steps: int, overrides: dict[str, str]) -> tuple[dict, int, float]:
    """The figures over the runs (the JSON ``--json`` writes, without the length comparison), the exposures in
    the runs' first 10 % and the BV-hours."""
    width = min(len(r["per_window"]) for r in runs)
    per_window = [float(np.mean([r["per_window"][w] for r in runs])) for w in range(width)]
    exposures = sum(r["exposures"] for r in runs)
    early = sum(r["exposures_first_10pct"] for r in runs)
    bv_hours = sum(r["bv_hours"] for r in runs)
    return {
        "sut": sut, "seeds": [r["seed"] for r in runs], "steps": steps, "overrides": overrides,
        "per_window_mean_bvs": per_window, "min_window_mean_bvs": min(per_window) if per_window else None,
        "mean_window_mean_bvs": float(np.mean(per_window)) if per_window else None,
        "min_window_any_run_bvs": min(min(r["per_window"]) for r in runs if r["per_window"]) if width else None,
        "sut_jumps": sum(r["jumps"] for r in runs),
        "exposures": exposures, "exposures_first_10pct_share": early / exposures if exposures else None,
        "bv_bv_collisions": sum(r["bv_bv_collisions"] for r in runs),
        "bv_bv_collisions_per_bv_hour": sum(r["bv_bv_collisions"] for r in runs) / bv_hours if bv_hours else None,
        "entries_per_run": float(np.mean([r["entries"] for r in runs])),
        "shifts_per_run": float(np.mean([r["shifts"] for r in runs])),
        "intelligence": mean_ci([r["intelligence"] for r in runs]),
        "runs": runs,
    }, early, bv_hours


def main(args) -> int:
    """The experiment of the parsed options (``scripts/experiment_traffic.py``; text values, checked here): the
    runs (one progress line each on stderr), the figures printed and, with ``args.json``, written. Returns the
    exit status; InputError (one line) on bad input, before anything runs."""
    from evoscen_sim.config.scenario_config import load_scenario_config

    from evoscen_experiments.experiments import key_values, positive_int

    seeds = positive_int("--seeds", args.seeds)
    first = positive_int("--first-seed", args.first_seed, 0)
    steps = positive_int("--steps", args.steps)
    other = positive_int("--compare-steps", args.compare_steps) if args.compare_steps is not None else None
    overrides = key_values("--set", args.set)

    def cfg_for(seed: int, n: int):
        return load_scenario_config(args.config, {**overrides, "sut.model": args.sut, "seed": str(seed),
                                                  "steps": str(n), "recording.enabled": "false"})

    cfg_for(first, steps)  # validated before anything runs
    runs = []
    for seed in range(first, first + seeds):
        runs.append(one_run(cfg_for(seed, steps)))
        print(f"seed {seed}: BVs within 100 m {runs[-1]['mean_bvs']:.1f}, exposures {runs[-1]['exposures']}, "
              f"jumps {runs[-1]['jumps']}", file=sys.stderr)
    longer = [one_run(cfg_for(seed, other)) for seed in range(first, first + seeds)] if other else None
    out, early, bv_hours = figures(args.sut, runs, steps, overrides)
    print(f"SUT {args.sut}, {seeds} seeds from {first}, {steps} steps" + (f", {overrides}" if overrides else ""))
    print("BVs within ±100 m per 30-s window (mean over seeds): " + ", ".join(f"{x:.1f}" for x in out["per_window_mean_bvs"]))
    if out["min_window_mean_bvs"] is None:  # a run shorter than one window has no window figures
        print(f"no complete 30-s window: a run of {steps} steps is shorter than one")
    else:
        print(f"lowest window mean: {out['min_window_mean_bvs']:.1f}; mean of the window means: "
              f"{out['mean_window_mean_bvs']:.1f}; lowest window of any single run: {out['min_window_any_run_bvs']:.1f}")
    print(f"SUT jumps: {out['sut_jumps']}")
    share = out["exposures_first_10pct_share"]
    print(f"SUT exposures: {out['exposures']}, in the first 10 % of the run: {early}"
          + (f" ({100 * share:.0f} %)" if share is not None else ""))
    print(f"BV-BV collisions: {out['bv_bv_collisions']} in {bv_hours:.1f} BV-hours"
          + (f" ({out['bv_bv_collisions_per_bv_hour']:.3f} per BV-hour)" if bv_hours else ""))
    print(f"window entries per run: {out['entries_per_run']:.1f}, shifts per run: {out['shifts_per_run']:.1f}")
    print(f"intelligence: {fmt_ci(*out['intelligence'])} (n = {seeds})")
    if longer is not None:
        diff = [b["intelligence"] - a["intelligence"] for a, b in zip(runs, longer)]
        out["compare_steps"] = other
        out["intelligence_longer"] = mean_ci([r["intelligence"] for r in longer])
        out["intelligence_difference"] = mean_ci(diff)
        print(f"intelligence over {other} steps: {fmt_ci(*out['intelligence_longer'])}; paired difference "
              f"({other} − {steps}): {fmt_ci(*out['intelligence_difference'])} (n = {seeds})")
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=1, default=float))
    return EXIT_OK
