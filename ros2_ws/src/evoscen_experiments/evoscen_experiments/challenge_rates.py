"""One SUT's naturalistic rates per SUT-km from challenge runs, weighted back, beside a reference
(docs/challenges.md, "The estimator"): ``scripts/challenge_rates.py``.

Two sets of episodes of the same SUT on disjoint seed blocks: the *challenge* set under ``--mode`` (``nade``
by default), the *reference* set under ``--reference-mode`` (``naturalistic``: the layer's process at p). Per
set and rate (SUT exposures, SUT collisions, front TTC episodes: docs/evaluation.md), the ratio estimator
R = Σ w·y / Σ w·x over its episodes (y the count, x the SUT-km, w the run's weight p/q; 1 for runs without
the layer) with its 95 % interval by linearisation, the effective number of episodes (Σw)² / Σw², and the
difference challenge − reference with its interval (independent sets). Writes ``rates.md`` and
``rates.csv``; rounds saved and resumable as in every experiment.
"""

from __future__ import annotations

import math
from pathlib import Path

from evoscen_contract.contract import EXIT_INTERRUPTED, EXIT_OK
from evoscen_sim.config.config_schema import CHALLENGE_MODES
from evoscen_sim.errors import InputError

from evoscen_experiments.experiments import markdown_table, positive_int, write_csv, batch_option
from evoscen_experiments.stats import Z95, Rate, weighted_rate  # noqa: F401  (Rate: the estimates' type)
from evoscen_experiments.timing import finish

RATES = (("exposures", "SUT exposures per SUT-km"), ("collisions", "SUT collisions per SUT-km"),
         ("front_ttc_episodes", "front TTC episodes per SUT-km"))


def episode_values(report: dict) -> dict[str, float]:
    """The counts, the SUT-km and the weight of one run's report."""
    ch = report.get("challenge")
    ss = report["surrogate_safety"]
    return {"exposures": float(report["safety"]["exposures"]), "collisions": float(report["safety"]["collisions"]),
            "front_ttc_episodes": float(ss["front"]["ttc_episodes"]), "km": float(report["comparative"]["safety"]["sut_km"]),
            "weight": 1.0 if ch is None else float(ch["weight"])}


def _mode(option: str, text: str) -> str:
    if text not in CHALLENGE_MODES:
        raise InputError(f"{option}: expected one of {', '.join(CHALLENGE_MODES)}, got {text!r}")
    return text


def _build(args):
    from evoscen_experiments.experiments import Round, config_loader

    sets = []
    load = config_loader(args.config)
    for name, mode, n, first in (("challenge", _mode("--mode", args.mode), args.episodes, args.first_seed),
                                 ("reference", _mode("--reference-mode", args.reference_mode),
                                  args.reference_episodes, args.reference_first_seed)):
        n_ep, first_seed = positive_int(f"--{'' if name == 'challenge' else 'reference-'}episodes", n), \
            positive_int(f"--{'' if name == 'challenge' else 'reference-'}first-seed", first, 0)
        sets.append((name, mode, range(first_seed, first_seed + n_ep)))
    a, b = sets[0][2], sets[1][2]
    if a.start < b.stop and b.start < a.stop:
        raise InputError(f"--first-seed / --reference-first-seed: the blocks {a.start}..{a.stop - 1} and "
                         f"{b.start}..{b.stop - 1} overlap; expected disjoint seed blocks")
    rounds = [Round(f"{name}:{mode}", load({"sut.model": args.sut, "seed": str(s), "steps": args.episode_steps,
                                            "recording.enabled": "false", "challenge.mode": mode}))
              for name, mode, seeds in sets for s in seeds]
    return sets, rounds, positive_int("--jobs", args.jobs)


def main(args) -> int:
    """The two sets run (or read back), the rates and their difference written and printed; InputError (one
    line) on bad input before anything runs."""
    from evoscen_experiments.experiments import run_rounds_with_bar, set_up

    sets, rounds, jobs = set_up(args.out, lambda: _build(args))
    results = run_rounds_with_bar(rounds, args.out, jobs=jobs, desc="rates", batch=batch_option(args))
    if results is None:
        return EXIT_INTERRUPTED
    per_set = {}
    for name, mode, _seeds in sets:
        vals = [episode_values(results[r.key]["report"]) for r in rounds if r.label == f"{name}:{mode}"]
        per_set[name] = {k: weighted_rate([v[k] for v in vals], [v["km"] for v in vals], [v["weight"] for v in vals])
                         for k, _ in RATES}
    rows, csv_rows = [], []
    for key, label in RATES:
        c, r = per_set["challenge"][key], per_set["reference"][key]
        diff, half = c.value - r.value, math.hypot(c.half, r.half)
        inside = abs(diff) <= half
        rows.append([label, f"{c.value:.4f} ± {c.half:.4f}", f"{r.value:.4f} ± {r.half:.4f}",
                     f"{diff:+.4f} ± {half:.4f}", "yes" if inside else "**no**"])
        csv_rows.append([key, c.value, c.half, c.n, c.n_eff, r.value, r.half, r.n, r.n_eff, diff, half, int(inside)])
    (cn, cm, cs), (rn, rm, rs) = sets
    header = ["rate", f"{cn} ({cm}, reweighted), seeds {cs.start}..{cs.stop - 1}",
              f"{rn} ({rm}), seeds {rs.start}..{rs.stop - 1}", "difference (95 %)", "0 inside"]
    table = markdown_table(header, rows)
    eff = per_set["challenge"]["exposures"]
    text = (f"# Naturalistic rates from challenge runs\n\nSUT {args.sut}, {args.episode_steps} steps per episode; "
            f"{cn}: {eff.n} episodes (effective {eff.n_eff:.1f}), {rn}: {per_set['reference']['exposures'].n}; ratio "
            f"estimates Σ w·count / Σ w·km with 95 % intervals (docs/challenges.md).\n\n{table}")
    Path(args.out, "rates.md").write_text(text, encoding="utf-8")
    write_csv(Path(args.out) / "rates.csv", ["rate", "challenge", "challenge_ci95", "challenge_episodes",
                                             "challenge_effective", "reference", "reference_ci95",
                                             "reference_episodes", "reference_effective", "difference",
                                             "difference_ci95", "zero_inside"], csv_rows)
    print(text, end="")
    print(f"written: {Path(args.out) / 'rates.md'}, rates.csv")
    finish(args.out)
    return EXIT_OK
