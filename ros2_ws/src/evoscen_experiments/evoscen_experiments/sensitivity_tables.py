"""One design's tables and files of the sensitivity experiment (docs/sensitivity.md).

:func:`summarise` turns the rounds of one test design into ``sensitivity.md``, ``sensitivity.csv``,
``mutation_scores.csv``, ``blocks.csv``, ``not_applicable.csv``, ``speeds.csv``, ``rounds.csv`` and
``sensitivity.png``: per scenario and base SUT the paired differences intact − mutant of every score
(:mod:`evoscen_experiments.sensitivity`), per seed block the detection
(:mod:`evoscen_experiments.replication`), the surrogate-safety rates and the speeds. The experiment
that runs the rounds is :mod:`evoscen_experiments.sensitivity_experiment`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from evoscen_experiments.sensitivity import COLUMNS, PROFILES, SCORES, SSM_RATES, paired, score_of, ssm_rate, symbols
from evoscen_experiments.stats import difference_words, fmt_ci, markdown_table, mean_ci

INTACT = "intact"
"""The variant name of the intact SUT model (every other variant is a mutant of the library)."""


def role(mutant: str) -> str:
    """``profile`` for a reference profile (:data:`~evoscen_experiments.sensitivity.PROFILES`: reported, not counted
    in detection), else ``defect``."""
    return "profile" if mutant in PROFILES else "defect"

SENSITIVITY_CSV = ["design", "scenario", "bv_driver", "base", "mutant", "class", "role",
                   *(f"delta_{COLUMNS[n]}_{s}" for n in SCORES for s in ("mean", "ci95")),
                   "d_collisions_mean", "d_collisions_ci95", "d_exposures_mean", "d_exposures_ci95", "d_min_pet_mean",
                   "d_min_pet_ci95", "detected",
                   "seeds_needed", "seeds", "pairing_r",
                   *(f"d_ssm_{side}_{ms}_per_km_{s}" for side, ms in SSM_RATES for s in ("mean", "ci95")), "ssm_n"]
SCORES_CSV = ["scenario", "bv_driver", "base", "detected", "mutants", "mutation_score", "d_intact_mean",
              "d_intact_ci95", "median_pairing_r", "not_applicable", "detected_per_block",
              "min_detected_over_blocks", "min_block", "detected_every_block", "contradictions"]
BLOCKS_CSV = ["design", "scenario", "bv_driver", "base", "mutant", "class", "block_first_seed", "block_last_seed",
              "delta_d_mean", "delta_d_ci95", "n", "detected", "needed", "better"]
SPEEDS_CSV = ["design", "scenario", "bv_driver", "base", "mutant", "d_sut_speed_mean", "d_sut_speed_ci95",
              "d_reference_speed_mean", "d_reference_speed_ci95", "n"]
NOT_APPLICABLE_CSV = ["scenario", "bv_driver", "base", "mutant", "class", "applies_to"]
ROUNDS_CSV = ["design", "scenario", "base", "variant", "seed", "steps", *(COLUMNS[n] for n in SCORES), "collisions", "exposures",
              "wall_time_s", *(f"ssm_{side}_{ms}_per_km" for side, ms in SSM_RATES)]


class SeedReports:
    """The reports of one design's rounds, seed -> ``report.json`` dict per (scenario, base, variant), and the
    per-seed figures the tables pair (``nan`` where a report leaves one undefined)."""

    def __init__(self, reports: dict[tuple[str, str, str], dict[int, dict]]) -> None:
        self.reports = reports

    def score(self, key: tuple[str, str, str], name: str) -> dict[int, float]:
        return {s: score_of(r, name) for s, r in self.reports[key].items()}

    def counts(self, key: tuple[str, str, str], section: str, field_name: str) -> dict[int, float]:
        return {s: float(r[section][field_name]) for s, r in self.reports[key].items()}

    def min_pet(self, key: tuple[str, str, str]) -> dict[int, float]:
        out = {}
        for s, r in self.reports[key].items():
            v = (r["safety"].get("conflicts") or {}).get("min_pet_s")
            out[s] = math.nan if v is None else float(v)
        return out

    def rates(self, key: tuple[str, str, str], side: str, measure: str) -> dict[int, float]:
        return {s: ssm_rate(r, side, measure) for s, r in self.reports[key].items()}

    def speeds(self, key: tuple[str, str, str], which: str) -> dict[int, float]:
        """Per seed the SUT's mean speed (``sut``) or the comparative score's reference speed (``reference``:
        the mean speed of the vehicles in the SUT's view, docs/evaluation.md §10.2), m/s; nan where absent."""
        out = {}
        for s, r in self.reports[key].items():
            if which == "sut":
                v = (r.get("efficiency") or {}).get("mean_speed_mps")
            else:
                v = (((r.get("comparative") or {}).get("progress")) or {}).get("reference_mean_speed_mps")
            out[s] = math.nan if v is None else float(v)
        return out


@dataclass
class Tables:
    """The rows one design's tables gather, scenario by scenario and base by base."""

    csv_rows: list = field(default_factory=list)
    score_rows: list = field(default_factory=list)
    md_parts: list = field(default_factory=list)
    plot_data: list = field(default_factory=list)
    block_csv: list = field(default_factory=list)
    csv_na: list = field(default_factory=list)
    speed_csv: list = field(default_factory=list)


@dataclass(frozen=True)
class Cell:
    """One scenario and base SUT of a design: what its rows are labelled with."""

    design: str
    scenario: str
    driver: str
    base: str
    unit: str
    sym: dict = field(default_factory=dict)
    """Each score's symbol (:func:`~evoscen_experiments.sensitivity.symbols`: D, S, P, X by default)."""


def summarise(design, rounds: list, results: dict, meta: dict, out: Path, bases: list[str],
              scenarios: list[str], mutants: list[str]) -> tuple[dict, str]:
    """One design's tables and files in ``out`` (sensitivity.md/.csv, mutation_scores.csv, rounds.csv,
    sensitivity.png). Returns (scenario, base) -> :class:`DesignSummary` and the score table (Markdown)."""
    from evoscen_experiments.replication import SeedBlock

    out.mkdir(parents=True, exist_ok=True)
    rounds = [r for r in rounds if meta[r.key][0] == design.name]
    reports: dict[tuple[str, str, str], dict[int, dict]] = {}
    for rnd in rounds:
        reports.setdefault(meta[rnd.key][1:], {})[rnd.cfg.seed] = results[rnd.key]["report"]
    seeds = SeedReports(reports)
    first_report = next(iter(next(iter(reports.values())).values()))
    blocks = [SeedBlock(a, b) for a, b in design.block_bounds]
    tables = Tables()
    summaries = {}
    for scenario in scenarios:
        driver = next(r.cfg.bvs.driver for r in rounds if meta[r.key][1] == scenario)
        for base in bases:
            cell = Cell(design.name, scenario, driver, base, design.unit, symbols(first_report))
            summaries[(scenario, base)] = scenario_base(tables, seeds, cell, mutants, blocks, first_report)
    write_files(out, tables, round_rows(design, rounds, results, meta))
    score_table = scores_table(tables.score_rows, scenarios, design.unit, symbols(first_report)["intelligence"])
    text = (f"# Sensitivity experiment (SUT mutation analysis)\n\nScores: {form_text(first_report)}.\n\n"
            f"{overview(design, rounds, results, meta, bases, mutants, scenarios, blocks)}\n\n"
            f"{score_table}\n" + "\n".join(tables.md_parts) + "\n![sensitivity](sensitivity.png)\n")
    (out / "sensitivity.md").write_text(text, encoding="utf-8")
    plot(out / "sensitivity.png", tables.plot_data, symbols(first_report)["intelligence"])
    return summaries, score_table


def scenario_base(tables: Tables, seeds: SeedReports, cell: Cell, mutants: list[str], blocks: list,
                  first_report: dict):
    """The rows of one scenario and base SUT: every applicable mutant's paired differences, per block and of
    the surrogate-safety rates and speeds, the not applicable ones named; its section of ``sensitivity.md``.
    Returns its :class:`~evoscen_experiments.sensitivity.DesignSummary`."""
    from evoscen_experiments.replication import applicable_split
    from evoscen_experiments.sensitivity import summarise_design
    from evoscen_sut.mutants import LIBRARY

    intact_key = (cell.scenario, cell.base, INTACT)
    applicable, not_applicable = applicable_split(cell.base, mutants)
    summary = summarise_design(seeds.score(intact_key, "intelligence"),
                               {m: seeds.score((cell.scenario, cell.base, m), "intelligence") for m in applicable})
    intact_rates = [mean_ci([v for v in seeds.rates(intact_key, side, ms).values() if not math.isnan(v)])
                    for side, ms in SSM_RATES]
    ssm_rows = [["intact (mean)", *(fmt_ci(mean, half, 2) for mean, half in intact_rates),
                 str(len(seeds.reports[intact_key]))]]
    block_rows, b_scores = block_part(tables, seeds, cell, applicable, blocks)
    rows, speed_rows, points = [], [], []
    for m in applicable:
        row, ssm_row, speed_row, point = mutant_rows(tables, seeds, cell, m, summary.pairing_r[m])
        rows.append(row)
        ssm_rows.append(ssm_row)
        speed_rows.append(speed_row)
        points.append(point)
    for m in not_applicable:
        rows.append([m, LIBRARY[m].klass, f"not applicable to {cell.base}",
                     *["–"] * (len(mutant_header(cell.unit, cell.sym)) - 3)])
        tables.csv_na.append([cell.scenario, cell.driver, cell.base, m, LIBRARY[m].klass, LIBRARY[m].applies])
    intact_i = mean_ci(list(seeds.score(intact_key, "intelligence").values()))
    low = b_scores.min_block
    tables.score_rows.append([cell.scenario, cell.driver, cell.base, summary.detected, summary.mutants, summary.score,
                              *intact_i, summary.median_r, len(not_applicable), ";".join(map(str, b_scores.detected)),
                              b_scores.min_detected, "" if low is None else low.label, b_scores.every_block,
                              b_scores.contradictions])
    speeds = (mean_ci([v for v in seeds.speeds(intact_key, "sut").values() if not math.isnan(v)]),
              mean_ci([v for v in seeds.speeds(intact_key, "reference").values() if not math.isnan(v)]))
    tables.md_parts.append(section(cell, summary, intact_i, not_applicable, b_scores, blocks, rows, block_rows,
                                   ssm_header(first_report), ssm_rows, speeds, speed_rows))
    tables.plot_data.append((f"{cell.scenario} / {cell.base}", points))
    return summary


def block_part(tables: Tables, seeds: SeedReports, cell: Cell, applicable: list[str], blocks: list):
    """Per applicable mutant and seed block the paired interval of the compared score (D), detection and runs needed
    (:func:`evoscen_experiments.replication.block_detection`): its Markdown rows (into ``blocks.csv`` too)
    and the mutation score per block."""
    from evoscen_experiments.replication import block_detection, block_scores
    from evoscen_sut.mutants import LIBRARY

    intact_key = (cell.scenario, cell.base, INTACT)
    per_block = {m: block_detection(seeds.score(intact_key, "intelligence"),
                                    seeds.score((cell.scenario, cell.base, m), "intelligence"), blocks)
                 for m in applicable}
    rows = [[m if m not in PROFILES else f"{m} (profile)", *(c for b in per_block[m].per_block for c in (
        f"{fmt_ci(b.diff.mean, b.diff.half)} (n {b.diff.n})", "yes" if b.detected else "no (better)" if b.better
        else "no", "–" if b.needed is None else str(b.needed))),
        f"{per_block[m].detected_blocks}/{len(blocks)}" + (", **contradiction**" if per_block[m].contradiction else "")]
        for m in applicable]
    for m in applicable:
        for b in per_block[m].per_block:
            tables.block_csv.append([cell.design, cell.scenario, cell.driver, cell.base, m, LIBRARY[m].klass,
                                     b.block.first, b.block.last, b.diff.mean, b.diff.half, b.diff.n, int(b.detected),
                                     "" if b.needed is None else b.needed, int(b.better)])
    return rows, block_scores({m: v for m, v in per_block.items() if m not in PROFILES}, blocks)


def mutant_rows(tables: Tables, seeds: SeedReports, cell: Cell, m: str, r_pair: float):
    """One mutant against the intact model on the same seeds: its row of the main table (its CSV row and its
    speeds' CSV row go into ``tables``), of the surrogate-safety table and of the speeds, and its plot point."""
    from evoscen_experiments.sensitivity import seeds_needed
    from evoscen_sut.mutants import LIBRARY

    intact_key, key = (cell.scenario, cell.base, INTACT), (cell.scenario, cell.base, m)
    diffs = {name: paired(seeds.score(intact_key, name), seeds.score(key, name)) for name in SCORES}
    d_col = paired(seeds.counts(key, "safety", "collisions"), seeds.counts(intact_key, "safety", "collisions"))
    d_exp = paired(seeds.counts(key, "safety", "exposures"), seeds.counts(intact_key, "safety", "exposures"))
    d_pet = paired(seeds.min_pet(intact_key), seeds.min_pet(key))
    d_ssm = [paired(seeds.rates(key, side, ms), seeds.rates(intact_key, side, ms)) for side, ms in SSM_RATES]
    ssm_row = [m, *(fmt_ci(d.mean, d.half, 2) for d in d_ssm), str(d_ssm[0].n)]
    d_v = paired(seeds.speeds(key, "sut"), seeds.speeds(intact_key, "sut"))
    d_ref = paired(seeds.speeds(key, "reference"), seeds.speeds(intact_key, "reference"))
    speed_row = [m, fmt_ci(d_v.mean, d_v.half, 2), fmt_ci(d_ref.mean, d_ref.half, 2),
                 # the ratio only where the SUT's speed changed beyond noise
                 f"{d_ref.mean / d_v.mean:.2f}" if d_v.n >= 2 and abs(d_v.mean) > d_v.half else "–", str(d_v.n)]
    tables.speed_csv.append([cell.design, cell.scenario, cell.driver, cell.base, m, d_v.mean, d_v.half, d_ref.mean,
                             d_ref.half, d_v.n])
    need = seeds_needed(seeds.score(intact_key, "intelligence"), seeds.score(key, "intelligence"))
    di = diffs["intelligence"]
    hit = di.above_zero
    cells = [fmt_ci(diffs[n].mean, diffs[n].half) for n in SCORES]
    # in words the mutant against the intact model: mutant − intact, the negative of the column's
    klass = LIBRARY[m].klass if m not in PROFILES else f"{LIBRARY[m].klass}, profile"
    row = [m, klass, cells[0], difference_words(-di.mean, di.half, di.n), *cells[1:],
           fmt_ci(d_col.mean, d_col.half, 2), fmt_ci(d_exp.mean, d_exp.half, 2), fmt_ci(d_pet.mean, d_pet.half, 2),
           "yes" if hit else "no", "–" if need is None else str(need), "–" if math.isnan(r_pair) else f"{r_pair:.2f}"]
    tables.csv_rows.append([cell.design, cell.scenario, cell.driver, cell.base, m, LIBRARY[m].klass, role(m),
                            *(v for n in SCORES for v in (diffs[n].mean, diffs[n].half)),
                            d_col.mean, d_col.half, d_exp.mean, d_exp.half, d_pet.mean, d_pet.half, int(hit),
                            "" if need is None else need, di.n, r_pair,
                            *(v for d in d_ssm for v in (d.mean, d.half)), d_ssm[0].n])
    return row, ssm_row, speed_row, (m, di)


def mutant_header(unit: str, sym: dict | None = None) -> list[str]:
    """The columns of a scenario's main table (``unit``: episode or seed; ``sym``: the scores' symbols, D, S, P, X
    by default)."""
    d, s, p, x = (sym or symbols({"settings": {"score_form": "comparative"}})).values()
    return ["mutant", "class", f"Δ{d} (intact − mutant)", f"mutant's {d} vs intact (95 %)", f"Δ{s}", f"Δ{p}", f"Δ{x}",
            "Δ collisions (mutant − intact)", "Δ exposures (mutant − intact)", "Δ min PET (s, intact − mutant)",
            "detected", f"{unit}s needed", "pairing r"]


def ssm_header(first_report: dict) -> list[str]:
    """The columns of the surrogate-safety table (thresholds from the first report)."""
    from evoscen_experiments.sensitivity import ssm_label

    return ["mutant", *(ssm_label(side, m, first_report) for side, m in SSM_RATES), "n"]


def section(cell: Cell, summary, intact_i, not_applicable: list[str], b_scores, blocks: list, rows: list,
            block_rows: list, ssm_head: list[str], ssm_rows: list, speeds, speed_rows: list) -> str:
    """The Markdown section of one scenario and base SUT: its detection in words, then the main table, the
    table per seed block, the surrogate-safety table and the speeds."""
    unit, base, score, low = cell.unit, cell.base, summary.score, b_scores.min_block
    (v_i, ref_i) = speeds
    d = cell.sym.get("intelligence", "D")
    block_header = ["mutant", *(h for b in blocks for h in (f"Δ{d} block {b.label}", f"detected {b.label}",
                                                           f"{unit}s needed {b.label}")), "detected in blocks"]
    per_block_text = ", ".join(f"{k}/{summary.mutants} in block {b.label}" for k, b in zip(b_scores.detected, blocks))
    return (f"## {cell.scenario} (BVs: {cell.driver}), SUT {base}\n\nIntact {d} "
            f"{fmt_ci(*intact_i)}; mutation score over all {unit}s {summary.detected}/{summary.mutants}"
            f"{'' if math.isnan(score) else f' = {score:.2f}'} (applicable defects; "
            f"{len(not_applicable)} not applicable to {base}"
            f"{': ' + ', '.join(not_applicable) if not_applicable else ''}); per block: "
            f"{per_block_text}; minimum over blocks {b_scores.min_detected}/{summary.mutants}"
            f"{'' if low is None else f' (block {low.label})'}; detected in every block "
            f"{b_scores.every_block}/{summary.mutants}; contradictions (worse in one block, better in another) "
            f"{b_scores.contradictions}{profile_note(summary)}.\n\n"
            + markdown_table(mutant_header(unit, cell.sym), rows)
            + f"\nPer seed block: Δ{d} = intact − mutant over the block's {unit}s (95 % interval, n), "
            f"detected (no (better): the mutant scores higher), {unit}s needed (the smallest n from which every prefix of the block's {unit}s "
            f"detects).\n\n" + markdown_table(block_header, block_rows)
            + f"\nSurrogate safety of the SUT per SUT-km (docs/evaluation.md): the intact model's mean "
            f"± 95 % interval over {unit}s, then each mutant's paired difference mutant − intact "
            f"(> 0: more conflicts), n {unit}s.\n\n" + markdown_table(ssm_head, ssm_rows)
            + f"\nSpeeds (m/s): the intact SUT's mean {fmt_ci(*v_i, 2)}, the progress reference (the "
            f"mean speed of the vehicles in its view, docs/evaluation.md §10.2) {fmt_ci(*ref_i, 2)}; "
            f"per mutant the paired differences mutant − intact and their ratio (how much of the "
            f"SUT's change the reference follows; where the SUT's change is significant).\n\n"
            + markdown_table(["mutant", "Δ SUT speed", "Δ reference speed", "ratio", "n"], speed_rows))


def round_rows(design, rounds: list, results: dict, meta: dict) -> list:
    """One row per round of the design (``rounds.csv``)."""
    rows = []
    for rnd in rounds:
        _, scenario, base, variant = meta[rnd.key]
        r = results[rnd.key]
        rep = r["report"]
        rows.append([design.name, scenario, base, variant, r["seed"], r["steps"], *(score_of(rep, n) for n in SCORES),
                     rep["safety"]["collisions"], rep["safety"]["exposures"], r["wall_time_s"],
                     *(ssm_rate(rep, side, ms) for side, ms in SSM_RATES)])
    return rows


def write_files(out: Path, tables: Tables, rounds_rows: list) -> None:
    """The design's CSV files."""
    from evoscen_experiments.experiments import write_csv

    write_csv(out / "sensitivity.csv", SENSITIVITY_CSV, tables.csv_rows)
    write_csv(out / "mutation_scores.csv", SCORES_CSV, tables.score_rows)
    write_csv(out / "blocks.csv", BLOCKS_CSV, tables.block_csv)
    write_csv(out / "speeds.csv", SPEEDS_CSV, tables.speed_csv)
    write_csv(out / "not_applicable.csv", NOT_APPLICABLE_CSV, tables.csv_na)
    write_csv(out / "rounds.csv", ROUNDS_CSV, rounds_rows)


def profile_note(summary) -> str:
    """The profiles run beside the defects, named as not counted ("" without any)."""
    names = [m for m in summary.per_mutant if m in PROFILES]
    return f"; not counted: {', '.join(names)} (a profile, not a defect)" if names else ""


def scores_table(score_rows: list, scenarios: list[str], unit: str, d: str = "D") -> str:
    """The mutation scores per scenario and base (Markdown; ``d``: the score's symbol) and the pooled mutation
    score per scenario (profiles not counted)."""
    table = markdown_table(["scenario", "BV driver", "SUT", "detected", "mutation score", f"intact {d}",
                            "median pairing r", "not applicable", "detected per block",
                            "min over blocks (block)", "detected in every block", "contradictions"],
                           [[s, d, b, f"{k}/{n}", "–" if math.isnan(x) else f"{x:.2f}", fmt_ci(m, h),
                             "–" if math.isnan(r) else f"{r:.2f}", str(na), per.replace(";", ", "),
                             f"{lo}/{n} ({lo_b})", f"{ev}/{n}", str(con)]
                            for s, d, b, k, n, x, m, h, r, na, per, lo, lo_b, ev, con in score_rows])
    pooled = []
    for scenario in scenarios:
        own = [row for row in score_rows if row[0] == scenario]
        k, n = sum(row[3] for row in own), sum(row[4] for row in own)
        every = sum(row[13] for row in own)
        pooled.append(f"{scenario}: detected {k}/{n} applicable (base, mutant) pairs over all {unit}s, "
                      f"{every}/{n} in every block; {sum(row[9] for row in own)} pairs not applicable")
    return (table + "\nMutation score over the applicable (base, mutant) pairs, profiles (" + ", ".join(PROFILES)
            + ") not counted: " + "; ".join(pooled) + ".\n")


def form_text(first_report: dict) -> str:
    """The scores compared, in words (``evaluation.score_form`` of the runs)."""
    form = (first_report.get("settings") or {}).get("score_form", "method")
    return ("D, the comparative score (evaluation.score_form: comparative, docs/evaluation.md §10), its safety S, "
            "progress P and interaction X" if form == "comparative" else
            "the method's intelligence I (evaluation.score_form: method)")


def overview(design, rounds: list, results: dict, meta: dict, bases: list[str], mutants: list[str],
             scenarios: list[str], blocks: list) -> str:
    """The paragraph under the title: the size of the experiment, how it pairs, what the columns mean, its
    simulated and wall time, and its compute (:func:`compute_text`)."""
    unit = design.unit
    cfg0 = rounds[0].cfg
    wall = sum(results[r.key]["wall_time_s"] for r in rounds)
    simulated = sum(results[r.key]["report"]["run"]["duration_s"] for r in rounds)
    variants = len({meta[r.key][1:] for r in rounds})
    return (f"{len(bases)} base SUT(s) x {len(mutants)} mutants "
            f"x {len(scenarios)} scenarios x {design.runs} {unit}s (seed blocks "
            f"{', '.join(b.label for b in blocks)}; no sequential stopping: every block runs all its {unit}s), "
            f"{design.steps} steps, {cfg0.bvs.count} BVs; paired by {unit} (common random numbers: a seed fixes the "
            f"initial state after the warm-up and every random stream); differences intact − mutant of the "
            f"unweighted scores (Δ collisions/exposures: mutant − intact; Δ min PET: intact − mutant of the run's "
            f"smallest lane-change PET, > 0 when the mutant cuts in closer), mean ± 95 % interval over {unit}s; "
            f"the mutant's score in words: 'significantly lower' (= detected: the intact − mutant interval lies above 0), "
            f"'significantly higher' or 'no significant difference'; pairing r: correlation over {unit}s of intact and "
            f"mutant score; {simulated:,.0f} s simulated (scored states of all runs), {wall:,.0f} s of the runs' own "
            f"times summed over the workers (the command's wall time: timing.json).\n\n{compute_text(design, cfg0, variants)}")


def warmup_steps(cfg) -> int:  # a ScenarioConfig
    """Steps of the warm-up before every run (``traffic.warmup_s / dt_s``; none without the traffic window)."""
    return int(round(cfg.traffic.warmup_s / cfg.dt_s)) if cfg.traffic.mode == "window" else 0


def compute_text(design, cfg, variants: int) -> str:
    """One paragraph: the design's SUT steps (what equal compute equalises) and its warm-up (extra compute)."""
    from evoscen_experiments.sensitivity import design_compute

    w = warmup_steps(cfg)
    c = design_compute(design, w)
    warm = (f"the warm-up (traffic.warmup_s = {cfg.traffic.warmup_s:g} s, {w} steps) runs before every run and is "
            f"extra compute, the same per run in either design: {design.runs} x {w} = {c.warmup_steps:,} steps"
            if w else "no warm-up (traffic.warmup_s = 0 or no traffic window)")
    seeds = (f"seeds {design.seeds[0]}..{design.seeds[-1]}" if len(design.block_bounds) == 1 else
             "seed blocks " + ", ".join(f"{a}..{b}" for a, b in design.block_bounds))
    return (f"Design {design.name}: {design.runs} {design.unit}s ({seeds}) x "
            f"{design.steps:,} steps = {c.sut_steps:,} SUT steps per variant and scenario; {warm}; "
            f"{c.total:,} simulated steps per variant and scenario, {c.total * variants:,} in all "
            f"({variants} variant-scenario pairs, {design.runs * variants:,} runs); challenge.mode "
            f"{cfg.challenge.mode} (docs/challenges.md).")


def plot(path: Path, panels, d: str = "D") -> None:
    """Paired difference (intact − mutant) of the compared score (symbol ``d``: D by default) of every mutant with
    its 95 % interval, one panel per scenario."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 0.45 * max(len(p[1]) for p in panels) + 1.6),
                             sharey=True, squeeze=False)
    for ax, (title, points) in zip(axes[0], panels):
        for y, (_name, d) in enumerate(points):
            half = 0.0 if math.isnan(d.half) else d.half
            color = "tab:green" if d.above_zero else "tab:red"
            ax.errorbar([d.mean], [y], xerr=[[half], [half]], fmt="o", color=color, capsize=3)
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_yticks(range(len(points)), [p[0] for p in points])
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(f"Δ{d} intact − mutant (95 % CI)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
