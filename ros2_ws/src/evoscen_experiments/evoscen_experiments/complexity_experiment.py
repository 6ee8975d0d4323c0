"""The complexity experiment (docs/method.md §6.2): one SUT in the evolving scenario and in rule-based baselines.

``scripts/experiment_complexity.py`` parses the command line and calls :func:`main`: per scenario
(``evolving``: the configuration's BVs; a BV driver name: every BV driven by it) ``--rounds`` rounds of the
same SUT, run on the campaign engine; per scenario LC, AD and E per evaluation window averaged over windows
and rounds, and the complexity score C of those averages (:func:`evoscen_eval.scoring.metrics.complexity_score`).
"""

from __future__ import annotations

from pathlib import Path

from evoscen_contract.contract import EXIT_INTERRUPTED, EXIT_OK

from evoscen_experiments.timing import finish
from evoscen_sim.errors import InputError

from evoscen_experiments.experiments import fmt_ci, markdown_table, mean_ci, positive_int, write_csv, batch_option


def _build(args):
    """The scenarios, the rounds (every scenario on every seed), the workers and the rounds per scenario."""
    from evoscen_experiments.experiments import Round, config_loader, distinct_names

    n_rounds = positive_int("--rounds", args.rounds)
    first = positive_int("--first-seed", args.first_seed, 0)
    jobs = positive_int("--jobs", args.jobs)
    scenarios = distinct_names("--scenarios", args.scenarios)
    rounds = []
    load = config_loader(args.config)  # the file parsed once
    for name in scenarios:
        for seed in range(first, first + n_rounds):
            overrides = {"sut.model": args.sut, "seed": str(seed), "steps": args.steps, "recording.enabled": "false"}
            if name != "evolving":
                overrides["bvs.driver"] = name
            if args.mix is not None:
                overrides["bvs.mix"] = args.mix
            rounds.append(Round(name, load(overrides)))
    return scenarios, rounds, jobs, n_rounds


def main(args) -> int:
    """The experiment of the parsed options (``scripts/experiment_complexity.py``; text values, checked here):
    the rounds run (or read back), the table written into ``args.out`` and printed. Returns the exit status;
    InputError (one line) on bad input (``--steps`` shorter than one complexity window: once the rounds ran)."""
    from evoscen_eval.scoring.metrics import complexity_score

    from evoscen_experiments.experiments import run_rounds_with_bar, set_up

    scenarios, rounds, jobs, n_rounds = set_up(args.out, lambda: _build(args))
    results = run_rounds_with_bar(rounds, args.out, jobs=jobs, desc="complexity", batch=batch_option(args))
    if results is None:
        return EXIT_INTERRUPTED
    ev = rounds[0].cfg.evaluation
    header = ["scenario", "BV driver", f"LC / {ev.window_steps}", f"AD / {ev.window_steps}", f"E / {ev.window_steps}",
              "K", "K (rounds)", "rounds"]
    rows, csv_rows, round_rows, bars = [], [], [], []
    for name in scenarios:
        rs = [results[r.key] for r in rounds if r.label == name]
        driver = next(r.cfg.bvs.driver for r in rounds if r.label == name)
        cx = [r["report"]["complexity"] for r in rs]
        if any(c["score"] is None for c in cx):
            raise InputError(f"--steps {args.steps}: shorter than one complexity window ({ev.window_steps} states)")
        # averaged over all windows of all rounds (every round has the same number of windows)
        lc, ad, e = (mean_ci([c[k] for c in cx]) for k in ("lane_changes", "accel_decel", "exposures"))
        score = complexity_score(e[0], lc[0], ad[0], ev.k_exposure, ev.k_lane_change, ev.k_accel)
        per_round = mean_ci([c["score"] for c in cx])
        rows.append([name, driver, fmt_ci(*lc, 2), fmt_ci(*ad, 1), fmt_ci(*e, 3), f"{score:.4f}", fmt_ci(*per_round),
                     str(len(rs))])
        csv_rows.append([name, driver, *lc, *ad, *e, score, *per_round, len(rs)])
        bars.append((name, lc, ad, e, score))
        for r, c in zip(rs, cx):
            run = r["report"]["run"]
            round_rows.append([name, r["seed"], r["steps"], c["lane_changes"], c["accel_decel"], c["exposures"],
                               c["score"], c["windows"], r["wall_time_s"], run.get("makeup"), run.get("bv_trucks")])
    write_csv(args.out / "complexity.csv", ["scenario", "bv_driver", "lc_mean", "lc_ci95", "ad_mean", "ad_ci95",
                                            "e_mean", "e_ci95", "complexity", "complexity_rounds_mean",
                                            "complexity_rounds_ci95", "rounds"], csv_rows)
    write_csv(args.out / "rounds.csv", ["scenario", "seed", "steps", "lc", "ad", "e", "complexity", "windows",
                                        "wall_time_s", "makeup", "bv_trucks"], round_rows)
    table = markdown_table(header, rows)
    cfg0 = rounds[0].cfg
    wall = sum(r["wall_time_s"] for r in results.values())
    simulated = sum(r["report"]["run"]["duration_s"] for r in results.values())
    (args.out / "complexity.md").write_text(
        f"# Complexity experiment\n\nSUT {args.sut}; {len(scenarios)} scenarios x {n_rounds} rounds x {cfg0.steps} "
        f"steps, {cfg0.bvs.count} BVs; windows of {ev.window_steps} states; mean ± 95 % interval over rounds; "
        f"K from the averaged LC, AD, E (k = {ev.k_exposure:g}, {ev.k_lane_change:g}, {ev.k_accel:g}); "
        f"{simulated:,.0f} s simulated (scored states of all rounds), {wall:,.0f} s of the rounds' own times "
        f"summed over the workers (the command's wall time: timing.json).\n\n{table}\n"
        "![complexity](complexity.png)\n", encoding="utf-8")
    plot(args.out / "complexity.png", bars, ev.window_steps)
    print(table, end="")
    print(f"written: {args.out / 'complexity.md'}, complexity.csv, rounds.csv, complexity.png")
    finish(args.out)  # the command's start-up and throughput (timing.json)
    return EXIT_OK


def plot(path: Path, bars, window: int) -> None:
    """LC, AD, E per window and K per scenario, with 95 % intervals."""
    import math

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(13, 3.5))
    names = [b[0] for b in bars]
    for ax, idx, title in zip(axes, (1, 2, 3), (f"LC per {window} states", f"AD per {window} states",
                                                  f"E per {window} states")):
        means = [b[idx][0] for b in bars]
        errs = [0.0 if math.isnan(b[idx][1]) else b[idx][1] for b in bars]
        ax.bar(names, means, yerr=errs, capsize=4, color="tab:blue")
        ax.set_title(title)
    axes[3].bar(names, [b[4] for b in bars], color="tab:red")
    axes[3].set_title("complexity K")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
