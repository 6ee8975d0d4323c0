"""The intelligence experiment (docs/method.md §6.1): each SUT among the BVs on the same seeds, compared.

``scripts/experiment_intelligence.py`` parses the command line and calls :func:`main`: one round per SUT
and seed (the same BV layout and draws for every SUT), run on the campaign engine; per SUT the weighted
terms and the method's intelligence I and the comparative score D with 95 % intervals, every pair of SUTs paired by seed on the score
``evaluation.score_form`` selects (:func:`paired_comparisons`; D by default, docs/evaluation.md §10) and on
the method's efficiency term, the surrogate-safety rates, and the SUTs' TTC and speed distributions
(:func:`plot_distributions`).
"""

from __future__ import annotations

from pathlib import Path

from evoscen_contract.contract import EXIT_INTERRUPTED, EXIT_OK

from evoscen_experiments.timing import finish

from evoscen_experiments.experiments import fmt_ci, markdown_table, mean_ci, positive_int, write_csv, batch_option
from evoscen_experiments.sensitivity import SSM_RATES, ssm_label, ssm_rate


def _build(args):
    """The SUTs, the rounds (every SUT on every seed), the workers, the seed count and the first seed."""
    from evoscen_experiments.experiments import Round, config_loader, distinct_names

    seeds = positive_int("--seeds", args.seeds)
    first = positive_int("--first-seed", args.first_seed, 0)
    jobs = positive_int("--jobs", args.jobs)
    suts = distinct_names("--suts", args.suts, "SUT model names")
    rounds = []
    load = config_loader(args.config)  # the file parsed once
    for sut in suts:  # every override gets the config's validation (one-line errors)
        for seed in range(first, first + seeds):
            cfg = load({"sut.model": sut, "seed": str(seed), "steps": args.steps,
                                                     "bvs.mix": args.mix, "bvs.count": args.bvs,
                                                     "recording.enabled": "false"})
            rounds.append(Round(sut, cfg))
    return suts, rounds, jobs, seeds, first


def main(args) -> int:
    """The experiment of the parsed options (``scripts/experiment_intelligence.py``; text values, checked here):
    the rounds run (or read back), the tables written into ``args.out`` and printed. Returns the exit status;
    InputError (one line) on bad input, before anything is written."""
    from evoscen_experiments.experiments import run_rounds_with_bar, set_up

    suts, rounds, jobs, seeds, first = set_up(args.out, lambda: _build(args))
    results = run_rounds_with_bar(rounds, args.out, jobs=jobs, desc="intelligence", batch=batch_option(args))
    if results is None:
        return EXIT_INTERRUPTED
    table, ssm_table = per_sut_tables(args.out, suts, rounds, results)
    pair_rows, pair_csv = paired_comparisons(suts, rounds, results)
    eff_rows, eff_csv = paired_comparisons(suts, rounds, results, "efficiency")
    if pair_csv:
        write_csv(args.out / "paired.csv", ["sut_a", "sut_b", "delta_d_mean", "delta_d_ci95", "seeds",
                                            "significant"], pair_csv)
        write_csv(args.out / "paired_efficiency.csv", ["sut_a", "sut_b", "d_efficiency_mean", "d_efficiency_ci95",
                                                       "seeds", "significant"], eff_csv)
    any_cfg = rounds[0].cfg
    first_report = results[rounds[0].key]["report"]
    compared = ("D" if (first_report.get("settings") or {}).get("score_form") == "comparative" and "comparative"
                in first_report else "I")  # evaluation.score_form: the score SUTs are compared with
    pair_table = (markdown_table(["A", "B", f"{compared}(A) − {compared}(B), paired by seed", "seeds",
                                  "A vs B (95 %)"], pair_rows)
                  if pair_rows else "")
    eff_table = (markdown_table(["A", "B", "I_e(A) − I_e(B), paired by seed", "seeds", "A vs B (95 %)"], eff_rows)
                 if eff_rows else "")
    text = (f"# Intelligence experiment\n\n{len(suts)} SUTs x {seeds} seeds ({first}..{first + seeds - 1}), "
            f"{any_cfg.steps} steps, {any_cfg.bvs.count} BVs ({any_cfg.bvs.driver}, mix {args.mix}); weights "
            f"{any_cfg.evaluation.weight_safety:g}/{any_cfg.evaluation.weight_efficiency:g}/"
            f"{any_cfg.evaluation.weight_interaction:g}; mean ± 95 % interval over seeds"
            + (f"; challenge.mode {any_cfg.challenge.mode}: every mean weighted by its runs' likelihood ratios p/q "
               "(the naturalistic means; interval by linearisation, docs/challenges.md), the paired comparisons "
               "raw (the same challenges for both)" if any_cfg.challenge.mode == "nade" else "") + f".\n\n{table}\n"
            + (f"Paired comparisons (the same seeds: same traffic and random streams; mean ± 95 % interval of "
               f"the per-seed difference):\n\n{pair_table}\nThe efficiency term I_e alone, paired the same way:\n\n"
               f"{eff_table}\n" if pair_table else "") +
            "Surrogate safety of each SUT per SUT-km (docs/evaluation.md; front: the SUT behind its leader, rear: its "
            f"follower behind it), mean ± 95 % interval over seeds:\n\n{ssm_table}\n"
            "![TTC](ttc.png)\n\n![speed](speed.png)\n")
    (args.out / "intelligence.md").write_text(text, encoding="utf-8")
    plot_distributions(args.out, suts, rounds, results)
    print(table, end="")
    if pair_table:
        print("\n" + pair_table, end="")
        print("\n" + eff_table, end="")
    print("\n" + ssm_table, end="")
    print(f"written: {args.out / 'intelligence.md'}, intelligence.csv, surrogate_safety.csv, rounds.csv, ttc.png, "
          "speed.png"
          + (", paired.csv, paired_efficiency.csv" if pair_csv else ""))
    finish(args.out)  # the command's start-up and throughput (timing.json)
    return EXIT_OK


def per_sut_tables(out: Path, suts: list[str], rounds, results) -> tuple[str, str]:
    """Per SUT the method's weighted terms and its I, collisions, exposures and D, the comparative score, and its
    surrogate-safety rates, mean ± 95 % interval over seeds: ``intelligence.csv``, ``rounds.csv`` (every round)
    and ``surrogate_safety.csv`` written; returns the two Markdown tables."""
    header = ["SUT", "I_s (weighted)", "I_e (weighted)", "I_i (weighted)", "I (the method's)",
              "collisions", "exposures", "seeds", "D (the comparative score)"]
    rows, csv_rows, round_rows, ssm_rows, ssm_csv = [], [], [], [], []
    for sut in suts:
        rs = [results[r.key] for r in rounds if r.label == sut]
        reps = [r["report"] for r in rs]
        ci = _estimator(reps)
        cols = [ci([x["intelligence"]["weighted"][k] for x in reps]) for k in ("safety", "efficiency", "interaction")]
        total = ci([x["intelligence"]["score"] for x in reps])
        col = ci([x["safety"]["collisions"] for x in reps])
        exp = ci([x["safety"]["exposures"] for x in reps])
        comp = ci([x["comparative"]["score"] for x in reps])  # docs/evaluation.md §10
        rows.append([sut, *(fmt_ci(*c) for c in cols), fmt_ci(*total), fmt_ci(*col, 2), fmt_ci(*exp, 2), str(len(reps)),
                     fmt_ci(*comp)])
        csv_rows.append([sut, *(v for c in (*cols, total, col, exp) for v in c), len(reps), *comp])
        rates = [ci([v if v == v else None for v in (ssm_rate(x, side, m) for x in reps)]) for side, m in SSM_RATES]
        ssm_rows.append([sut, *(fmt_ci(*c, 2) for c in rates), str(len(reps))])
        ssm_csv.append([sut, *(v for c in rates for v in c), len(reps)])
        for r in rs:
            x = r["report"]
            round_rows.append([sut, r["seed"], r["steps"], x["safety"]["score"], x["efficiency"]["score"],
                               x["interaction"]["score"], x["intelligence"]["score"], x["safety"]["collisions"],
                               x["safety"]["exposures"], x["efficiency"]["mean_speed_mps"], r["wall_time_s"],
                               *(ssm_rate(x, side, m) for side, m in SSM_RATES), x["comparative"]["score"]])
    write_csv(out / "intelligence.csv",
              ["sut", *(f"{k}_{s}" for k in ("safety_weighted", "efficiency_weighted", "interaction_weighted",
                                             "i", "collisions", "exposures") for s in ("mean", "ci95")),
               "seeds", "d_mean", "d_ci95"], csv_rows)
    write_csv(out / "rounds.csv", ["sut", "seed", "steps", "i_s", "i_e", "i_i", "i",
                                   "collisions", "exposures", "mean_speed_mps", "wall_time_s",
                                   *(f"ssm_{side}_{m}_per_km" for side, m in SSM_RATES), "d"], round_rows)
    write_csv(out / "surrogate_safety.csv",
              ["sut", *(f"{side}_{m}_per_km_{s}" for side, m in SSM_RATES for s in ("mean", "ci95")), "seeds"], ssm_csv)
    first_report = results[rounds[0].key]["report"]
    ssm_table = markdown_table(["SUT", *(ssm_label(side, m, first_report) for side, m in SSM_RATES), "seeds"], ssm_rows)
    return markdown_table(header, rows), ssm_table


def _estimator(reports: list[dict]):
    """How a SUT's means are taken over its runs: ``mean_ci`` (Student-t interval); for runs of the challenge
    scenario, weighted by their likelihood ratios p/q (``mean_ci_weighted``: the naturalistic means,
    docs/challenges.md). A value None (undefined) or nan is left out."""
    from evoscen_experiments.stats import mean_ci_weighted

    weights = [(x.get("challenge") or {}).get("weight", 1.0) for x in reports]
    if not any("challenge" in x for x in reports):
        return lambda values: mean_ci([v for v in values if v is not None and v == v])
    return lambda values: mean_ci_weighted([v if v is not None and v == v else None for v in values], weights)


def paired_comparisons(suts: list[str], rounds, results, section: str = "intelligence"
                       ) -> tuple[list[list[str]], list[list]]:
    """Every pair of SUTs: the per-seed difference of ``section``'s score (intelligence: the score
    ``evaluation.score_form`` selects, D by default; or a term of the method: efficiency, safety,
    interaction), mean ± 95 % interval (shared seeds)."""
    from evoscen_eval.scoring.metrics import compared_scores

    from evoscen_experiments.sensitivity import paired
    from evoscen_experiments.stats import difference_words

    def value(report: dict):  # the total as evaluation.score_form selects it (docs/evaluation.md §10); a term: the method's
        return compared_scores(report)[section] if section == "intelligence" else report[section]["score"]

    scores = {sut: {r.cfg.seed: value(results[r.key]["report"]) for r in rounds if r.label == sut} for sut in suts}
    rows, csv_rows = [], []
    for i, a in enumerate(suts):
        for b in suts[i + 1:]:
            d = paired(scores[a], scores[b])
            sig = d.n >= 2 and abs(d.mean) > d.half
            rows.append([a, b, fmt_ci(d.mean, d.half), str(d.n), difference_words(d.mean, d.half, d.n)])
            csv_rows.append([a, b, d.mean, d.half, d.n, int(sig)])
    return rows, csv_rows


def plot_distributions(out: Path, suts: list[str], rounds, results) -> None:
    """TTC and speed distributions of the SUTs, overlaid (density, pooled over seeds)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from evoscen_eval.scoring.plot_inputs import SPEED_BINS, TTC_BINS

    for name, bins, key, xlabel, title in (
            ("ttc.png", TTC_BINS, "ttc_hist", "SUT TTC to the vehicle ahead in its path (s)", "TTC distribution per SUT"),
            ("speed.png", SPEED_BINS, "speed_hist", "SUT speed (m/s)", "Speed distribution per SUT")):
        fig, ax = plt.subplots(figsize=(7, 4))
        for sut in suts:
            counts = np.sum([results[r.key][key] for r in rounds if r.label == sut], axis=0).astype(float)
            if counts.sum() > 0:
                density = counts / (counts.sum() * np.diff(bins))
                ax.stairs(density, bins, label=f"{sut} ({int(counts.sum())} states)", lw=1.5)
        ax.set(xlabel=xlabel, ylabel="density", title=title)
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
