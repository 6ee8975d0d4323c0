"""The background traffic run in process and measured against highD: the work of ``scripts/fidelity_highd.py``
(docs/fidelity.md), ``scripts/bv_realism.py`` and ``scripts/traffic_makeup.py`` (docs/bv-profiles.md).

Each tool takes its script's options as plain values (counts as text, checked here: one-line
:class:`~evoscen_sim.errors.InputError` naming the option), runs its seeds in process
(:func:`evoscen_bringup.inprocess.run_inprocess`), measures them with :mod:`evoscen_eval.naturalistic`
(:mod:`~evoscen_eval.naturalistic.fidelity_highd`, :mod:`~evoscen_eval.naturalistic.bv_realism`,
:mod:`~evoscen_eval.naturalistic.makeup`), prints what the script prints (progress on stderr) and
returns its exit status.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from evoscen_sim.errors import InputError

from evoscen_experiments.experiments import positive_int


def fidelity_highd(*, bags: Sequence[Path] = (), out: Path = Path("runs/fidelity_highd"), seeds: str | None = None,
                   first_seed: str = "7001", steps: str = "3000", sut: str = "mobil", config: Path | None = None,
                   overrides: Sequence[str] = (), piece_m: str = "420", min_piece_m: str | None = None,
                   truck_length: str = "7", include_sut: bool = False, reference: Path | None = None) -> int:
    """Measure ``bags`` (bags or run directories) and ``seeds`` runs made here against highD's aggregates;
    print the table and write ``out/fidelity_highd.json``, ``.md`` and the plots (docs/fidelity.md)."""
    from evoscen_eval.naturalistic.fidelity_highd import Measures, compare, load_reference, piece_config, run_measures, \
        write_results
    from evoscen_eval.scoring.rundata import read_run
    from evoscen_record.bag_reader import bag_or_run_dir
    from evoscen_sim.config.scenario_config import load_scenario_config

    pieces = piece_config(piece_m, min_piece_m, truck_length, include_sut)
    ref = load_reference(reference)
    n_seeds = positive_int("--seeds", seeds) if seeds is not None else 0
    first = positive_int("--first-seed", first_seed, 0)
    n_steps = positive_int("--steps", steps)
    if not bags and not n_seeds:
        raise InputError("BAG: expected one or more bags (or run directories), or --seeds N to run here")
    sets: dict[str, str] = {}
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise InputError(f"--set {item!r}: expected KEY=VALUE")
        sets[key.strip()] = value.strip()

    def cfg_for(seed: int):
        return load_scenario_config(config, {**sets, "sut.model": sut, "seed": str(seed), "steps": str(n_steps),
                                             "recording.enabled": "false"})

    if n_seeds:
        cfg_for(first)  # validated before anything runs
    bag_dirs = [bag_or_run_dir(b) for b in bags]
    parts = []
    for bag in bag_dirs:
        parts.append(run_measures(read_run(bag), pieces, source=str(bag)))
        print(f"{bag}: {parts[-1].pieces} pieces", file=sys.stderr)
    if n_seeds:
        from evoscen_bringup.inprocess import run_inprocess

        for seed in range(first, first + n_seeds):
            summary = run_inprocess(cfg_for(seed), bag_dir=None, evaluate=True, plots=False, keep_run=True)
            parts.append(run_measures(summary.run, pieces, source=f"seed {seed}"))
            print(f"seed {seed}: {parts[-1].pieces} pieces", file=sys.stderr)
    measures = Measures.concat(parts)
    for w in measures.warnings:
        print(f"warning: {w}", file=sys.stderr)
    result = compare(measures, ref)
    result["settings"] = {"piece_m": pieces.piece_m, "min_piece_m": pieces.min_piece_m,
                          "truck_length_m": pieces.truck_length_m, "include_sut": include_sut,
                          "bags": [str(b) for b in bag_dirs], "seeds": list(range(first, first + n_seeds)),
                          "steps": n_steps if n_seeds else None, "sut": sut if n_seeds else None, "overrides": sets}
    table, plots = write_results(result, out)
    print(table, end="")
    print(f"{measures.pieces} pieces of {pieces.piece_m:g} m from {len(measures.runs)} runs; highD: {result['citation']}")
    print(f"results: {out / 'fidelity_highd.json'}, {out / 'fidelity_highd.md'}, {len(plots)} plots")
    return 0


def bv_realism(*, profiles: Sequence[str] = ("driver", "safety_net"), seeds: Sequence[int] = (1, 2, 3, 4, 5),
               steps: str = "3000", sut: str | None = None, config: Path | None = None, policy_dir: str | None = None,
               cut_in_headway: float | None = None, lane_hold: float | None = None, cut_in_decel: float | None = None,
               standing_at_once: str | None = None, traffic: str | None = None, hard_brake: str | None = None,
               json_out: Path | None = None) -> int:
    """Run every (profile, seed) in process with learned BVs and print each profile's pooled realism
    figures beside highD's (:func:`evoscen_eval.naturalistic.bv_realism.realism_table`); with ``json_out``
    also write them, with these options, as JSON (docs/bv-profiles.md)."""
    options = dict(locals())  # the options as given, for the JSON
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_eval.naturalistic.bv_realism import HIGHD_REFERENCE, bv_realism, combine, realism_table
    from evoscen_sim.config.scenario_config import load_scenario_config

    n_steps = positive_int("--steps", steps)
    if cut_in_headway is not None:  # a what-if knob for the measurement only (docs/bv-profiles.md)
        import dataclasses

        from evoscen_bv import profile as prof

        for name, p in list(prof.PROFILES.items()):
            prof.PROFILES[name] = dataclasses.replace(p, cut_in_closing_headway_s=cut_in_headway)
    learned = {"models.learned.policy_dir": policy_dir, "models.learned.lane_hold_s": lane_hold,
               "models.learned.cut_in_decel_mps2": cut_in_decel,
               "models.learned.standing_leader_at_once": None if standing_at_once is None else standing_at_once == "true",
               "traffic.mode": traffic,
               # the highd make-up needs the window (docs/bv-profiles.md)
               "bvs.makeup": "uniform" if traffic == "loop" else None,
               "models.learned.hard_brake": None if hard_brake is None else hard_brake == "true"}
    out: dict[str, dict] = {}
    for profile in profiles:
        figures = []
        for seed in seeds:
            overrides: dict[str, Any] = {"bvs.driver": "learned", "seed": seed, "steps": n_steps,
                                         "models.learned.profile": profile}
            if sut:
                overrides["sut.model"] = sut
            overrides.update({k: v for k, v in learned.items() if v is not None and v != ""})
            cfg = load_scenario_config(config, overrides)
            t0 = time.perf_counter()
            # (a policy directory that cannot be loaded is an InputError of the run)
            f = bv_realism(run_inprocess(cfg, bag_dir=None, evaluate=True, plots=False, keep_run=True).run)
            figures.append(f)
            print(f"{profile} seed {seed}: {f['bv_lane_changes']} BV lane changes, {f['bv_bv_collisions']} BV-BV "
                  f"and {f['sut_collisions']} SUT collisions ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
        out[profile] = combine(figures)
    print(f"traffic.mode: {cfg.traffic.mode}; bvs.makeup: {cfg.bvs.makeup}")
    print(realism_table(out), end="")
    if json_out:
        args = {("json" if k == "json_out" else k): (str(v) if isinstance(v, Path) else v) for k, v in options.items()}
        json_out.write_text(json.dumps({"args": {**args, "steps": n_steps}, "traffic_mode": cfg.traffic.mode,
                                        "figures": out, "highd": HIGHD_REFERENCE}, indent=2))
    return 0


def bench(configs: dict, rounds: int = 15, steps: int = 300, warmup: int = 300) -> dict:
    """Best in-process steps/s of each config (recording off) over ``rounds`` rounds of ``steps`` steps,
    the configs alternated in every round (a shared machine's load hits both alike)."""
    from evoscen_bringup.scenario import build_scenario

    scenarios = {name: build_scenario(cfg) for name, cfg in configs.items()}
    for sc in scenarios.values():
        for _ in range(warmup):
            sc.step()
    best = dict.fromkeys(configs, 0.0)
    for _ in range(rounds):
        for name, sc in scenarios.items():
            t0 = time.perf_counter()
            for _ in range(steps):
                sc.step()
            best[name] = max(best[name], steps / (time.perf_counter() - t0))
    return best


def traffic_makeup(*, makeup: str = "highd", seeds: Sequence[int] = (7001, 7002, 7003, 7004, 7005, 7006),
                   steps: str = "3000", sut: str = "mobil", bv_driver: str | None = None, out: Path | None = None,
                   bags: Sequence[Path] | None = None, bench_rounds: str = "0", json_out: Path | None = None,
                   overrides: Sequence[str] = ()) -> int:
    """Record one bag per seed in process (``bvs.makeup`` of ``makeup``; in ``out``, else a temporary
    directory), or read ``bags``, and print the make-up's pooled figures beside highD's as JSON
    (:mod:`evoscen_eval.naturalistic.makeup`); ``bench_rounds`` > 0 also times it against ``uniform``."""
    import tempfile

    import yaml
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_eval.naturalistic.makeup import figures, highd_figures, pooled
    from evoscen_eval.scoring.rundata import read_run
    from evoscen_sim.config.scenario_config import load_scenario_config

    n_steps = positive_int("--steps", steps)
    rounds = positive_int("--bench", bench_rounds, 0)

    def config(seed: int, name: str):
        over = {"bvs.makeup": name, "seed": seed, "steps": n_steps, "sut.model": sut}
        if bv_driver:
            over["bvs.driver"] = bv_driver
        for item in overrides:
            key, _, value = item.partition("=")
            over[key] = yaml.safe_load(value)
        return load_scenario_config(None, over)

    runs, recorded_makeups = [], []
    for bag in bags or []:
        try:
            run = read_run(bag)
            recorded_makeups.append(((run.scenario or {}).get("bvs") or {}).get("makeup", "uniform"))
            runs.append(figures(run))
        except InputError as exc:
            raise InputError(f"--bags: {exc}") from None
    with tempfile.TemporaryDirectory() as tmp:
        root = out if out is not None else Path(tmp)
        for seed in [] if bags else seeds:
            cfg = config(seed, makeup)
            t0 = time.perf_counter()
            bag = root / f"{makeup}_{seed}"
            # (a policy directory or a map is checked when the run builds its world and drivers)
            summary = run_inprocess(cfg, bag_dir=bag, evaluate=True)
            f = figures(read_run(bag), summary.report)
            runs.append(f)
            print(f"seed {seed}: {f['truck_slots']} trucks of {f['slots']}, "
                  f"lane changes {int(f['measures'].trip_lane_changes.sum())}, "
                  f"{f['bv_bv_collisions']} BV-BV collisions ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    result = pooled(runs)
    if rounds and not bags:
        rates = bench({makeup: config(seeds[0], makeup), "uniform": config(seeds[0], "uniform")}, rounds=rounds)
        result["steps_per_s"] = rates[makeup]
        result["steps_per_s_uniform"] = rates["uniform"]
        result["steps_per_s_ratio"] = rates[makeup] / rates["uniform"]
    head = ({"bags": [str(b) for b in bags], "makeup": sorted(set(recorded_makeups))} if bags else
            {"makeup": makeup, "seeds": list(seeds), "steps": n_steps, "sut": sut})
    print(json.dumps({**head, "figures": result, "highd": highd_figures()}, indent=1))
    if json_out:
        json_out.write_text(json.dumps({"figures": result, "highd": highd_figures()}, indent=2))
    return 0
