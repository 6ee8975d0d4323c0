"""A campaign's results: the results table, the summary with its statistics and plots, the gallery of
critical events (docs/campaigns.md), rebuilt from the finished runs' files."""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from evoscen_experiments.campaign import COUNT_COLUMNS, KIND_COLUMNS, SCORE_COLUMNS, TRAFFIC_COLUMNS, collect_rows, result_path, write_atomic
from evoscen_experiments.campaign_spec import CampaignRun, Spec


def write_results(spec: Spec, runs: Sequence[CampaignRun], out_dir: Path) -> list[dict[str, Any]]:
    """``results.parquet`` (one row per finished run of the spec) and ``summary.md``, each written
    whole or not at all (a temporary file renamed). An output that cannot be written is a
    :class:`~evoscen_sim.errors.HostFault` naming the file (the runs' results are kept)."""
    from evoscen_sim.errors import HostFault

    try:
        return _write_results(spec, runs, out_dir)
    except OSError as exc:
        with contextlib.suppress(OSError):
            (out_dir / "results.parquet.tmp").unlink()
        raise HostFault.of(exc, exc.filename or out_dir) from None


def _write_results(spec: Spec, runs: Sequence[CampaignRun], out_dir: Path) -> list[dict[str, Any]]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows = collect_rows(runs, out_dir)
    axes = list(spec.grid)
    columns = ["key", *axes, "seed", "steps", *SCORE_COLUMNS, "score_form", *COUNT_COLUMNS, *KIND_COLUMNS, *TRAFFIC_COLUMNS, "clips",
               "wall_time_s",
               "node", "pid"]
    table = pa.table({c: [row.get(c) for row in rows] for c in columns}) if rows else pa.table(
        {c: pa.array([], type=pa.string()) for c in columns})
    tmp = out_dir / "results.parquet.tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, out_dir / "results.parquet")
    images = summary_plots(spec, runs, rows, out_dir) if rows else []
    write_atomic(out_dir / "summary.md", summary_markdown(spec, runs, rows)
                  + "".join(f"\n![{Path(name).stem}]({name})\n" for name in images))
    if spec.record != "none":
        write_atomic(out_dir / "gallery.md", gallery_markdown(spec, runs, out_dir))
    return rows


def summary_plots(spec: Spec, runs: Sequence[CampaignRun], rows: Sequence[Mapping[str, Any]],
                  out_dir: Path) -> list[str]:
    """``summary.png`` (per cell: the compared score's mean, :func:`compared_column`, with its 95 % interval) and
    ``distributions.png`` (per cell: the SUT's TTC and speed distributions over all its runs, as fractions of
    states)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from evoscen_eval.scoring.plot_inputs import SPEED_BINS, TTC_BINS

    from evoscen_experiments.stats import mean_ci

    grouped = cells(spec, rows)
    labels = [", ".join(cell) or spec.name for cell in grouped]
    column, name = compared_column(rows)
    stats = [mean_ci([m[column] for m in members if not _missing(m.get(column))]) for members in grouped.values()]
    fig, ax = plt.subplots(figsize=(max(6.0, 0.6 * len(labels) + 2), 4))
    x = np.arange(len(labels))
    ax.bar(x, [m for m, _ in stats], yerr=[0.0 if math.isnan(h) else h for _, h in stats], capsize=3,
           color="tab:blue")
    ax.set_xticks(x, labels, rotation=45, ha="right", fontsize=8)
    ax.set(ylabel=f"{name} (mean, 95 % interval)", title=f"campaign {spec.name}: {len(rows)} runs")
    fig.tight_layout()
    fig.savefig(out_dir / "summary.png", dpi=100)
    plt.close(fig)
    key_of = {r.key: ", ".join(v for _, v in r.cell) or spec.name for r in runs}
    hists: dict[str, list[np.ndarray]] = {}
    for row in rows:
        path = out_dir / "runs" / row["key"] / "plot.json"
        if path.exists():
            plot = json.loads(path.read_text(encoding="utf-8"))
            h = hists.setdefault(key_of[row["key"]], [np.zeros(len(TTC_BINS) - 1), np.zeros(len(SPEED_BINS) - 1)])
            h[0] += plot["ttc_hist"]
            h[1] += plot["speed_hist"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for label, (ttc, speed) in hists.items():
        for ax, h, bins in ((axes[0], ttc, TTC_BINS), (axes[1], speed, SPEED_BINS)):
            if h.sum():
                ax.stairs(h / h.sum(), bins, label=label)
    axes[0].set(xlabel="SUT TTC to the vehicle ahead (s, closing states up to 20 s)", ylabel="fraction")
    axes[1].set(xlabel="SUT speed (m/s)", ylabel="fraction")
    if len(hists) <= 12:
        axes[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "distributions.png", dpi=100)
    plt.close(fig)
    return ["summary.png", "distributions.png"]


def gallery_markdown(spec: Spec, runs: Sequence[CampaignRun], out_dir: Path) -> str:
    """``gallery.md``: every critical event of the finished runs, most severe first
    (:func:`evoscen_eval.scenes.clips.rank_key`), with its picture, clip and reproduce command."""
    from evoscen_eval.scenes.clips import rank_key
    from evoscen_eval.scoring.exposure_rules import rules_summary, ttc_text

    events = []
    for r in runs:
        path = out_dir / "runs" / r.key / "clips.json"
        if result_path(out_dir, r.key).exists() and path.exists():
            events += [(e, r) for e in json.loads(path.read_text(encoding="utf-8"))]
    events.sort(key=lambda item: rank_key(item[0]))
    lines = [f"# Critical events of campaign {spec.name}\n",
             f"{len(events)} events: SUT collisions, then exposures by falling severity (at the exposure's worst "
             "state the largest ratio over the rules that hold there, 1 at a rule's threshold, 2 at twice the "
             "danger: TTC, gap or headway at half the threshold, braking or DRAC at twice it; docs/evaluation.md "
             f"§2.1); each a clip of ±{spec.clip_s:g} s (`python scripts/replay.py CLIP`, Foxglove), its animation "
             "and the command that runs the same configuration to the clip's end.\n",
             "| rank | event | cell | seed | t (s) | severity | rules: value vs threshold (vehicle) | "
             "lowest TTC ahead (s) | vehicles involved | scene | animation | clip | reproduce |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n, (e, r) in enumerate(events, 1):
        base = f"runs/{r.key}"
        pic = f"![scene]({base}/{e['png']})" if e.get("png") else "–"
        sev = "–" if e["severity"] is None else f"{e['severity']:.2f}"
        ttc = ttc_text(e.get("min_ttc_s"))
        cell = ", ".join(f"{k}={v}" for k, v in r.cell) or "–"
        gif = f"[clip.gif]({base}/{e['gif']})" if e.get("gif") else "–"
        rules = rules_summary(e).replace("|", "\\|") if e["kind"] == "exposure" else "–"
        ids = ", ".join(str(i) for i in e.get("ids", [])) or "–"
        lines.append(f"| {n} | {e['kind']} | {cell} | {r.seed} | {e['time_s']:.1f} | {sev} | {rules} | {ttc} | {ids} | "
                     f"{pic} | {gif} | `{base}/{e['clip']}` | `{e.get('command') or '–'}` |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------- statistics

SUMMARY_SCORES = ("comparative", "comparative_safety", "comparative_progress", "comparative_lane_change_time",
                  "comparative_interaction", "intelligence", "complexity")
"""The scores summary.md gives per cell, D first (symbols: :data:`~evoscen_experiments.campaign.SCORE_COLUMNS`)."""


def bootstrap_ci(values: Sequence[float], rng: np.random.Generator, draws: int = 2000) -> tuple[float, float, float]:
    """Mean and its 95 % percentile-bootstrap interval ``(mean, low, high)`` (for skewed counts
    such as collisions); ``nan`` bounds with fewer than 2 values."""
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    if x.size < 2:
        return float(x.mean()), math.nan, math.nan
    means = x[rng.integers(0, x.size, size=(draws, x.size))].mean(axis=1)
    low, high = np.percentile(means, [2.5, 97.5])
    return float(x.mean()), float(low), float(high)


def compared_column(rows: Sequence[Mapping[str, Any]]) -> tuple[str, str]:
    """The column a campaign's summary compares cells by, and its name: D, the comparative score, unless every
    run was scored with ``evaluation.score_form: method`` (then the method's I)."""
    if rows and all(row.get("score_form") == "method" for row in rows):
        return "intelligence", "I, the method's intelligence"
    return "comparative", "D, the comparative score"


def _label(column: str) -> str:
    """A score column's heading in summary.md: its symbol, the method's I and the scenario's K said so."""
    return {"intelligence": "I, the method's", "complexity": "K, the scenario's"}.get(column, SCORE_COLUMNS[column])


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def cells(spec: Spec, rows: Sequence[Mapping[str, Any]]) -> dict[tuple[str, ...], list[Mapping[str, Any]]]:
    """Rows grouped by cell (the axes' values in the spec's order)."""
    out: dict[tuple[str, ...], list[Mapping[str, Any]]] = {}
    for row in rows:
        out.setdefault(tuple(str(row[a]) for a in spec.grid), []).append(row)
    return out


def summary_markdown(spec: Spec, runs: Sequence[CampaignRun], rows: Sequence[Mapping[str, Any]]) -> str:
    """Per-cell means with 95 % intervals (Student t for scores, bootstrap for counts) and, with
    ``compare``, paired differences to the reference on shared seeds."""
    from evoscen_experiments.sensitivity import paired
    from evoscen_experiments.stats import difference_words, fmt_ci, markdown_table, mean_ci

    axes = list(spec.grid)
    column, compared = compared_column(rows)
    lines = [f"# Campaign {spec.name}\n",
             f"{len(rows)} of {len(runs)} runs finished; {len(spec.seeds)} seeds per cell; spec `{spec.path.name}`. "
             "Scores, each a ratio in [0, 1]: D, the comparative score (D = P·(0.6·S + 0.2·L + 0.2·X), "
             "docs/evaluation.md §10), with its terms; the method's intelligence I (for reproducing the paper); K, "
             "the scenario's complexity (– for a run shorter than one window): mean ± 95 % Student-t interval over "
             f"seeds. Counts, the SUT's: mean [95 % bootstrap interval]. Cells are compared by {compared}.\n"]
    rng = np.random.default_rng(0)  # the bootstrap's draws: fixed, so the summary is reproducible
    body = []
    grouped = cells(spec, rows)
    for cell, members in grouped.items():
        entry = [*cell, str(len(members))]
        for score in SUMMARY_SCORES:
            vals = [m[score] for m in members if not _missing(m.get(score))]
            entry.append(fmt_ci(*mean_ci(vals)) if vals else "–")
        for name in COUNT_COLUMNS:
            mean, low, high = bootstrap_ci([m[name] for m in members], rng)
            entry.append(f"{mean:.2f} [{low:.2f}, {high:.2f}]" if not math.isnan(low) else f"{mean:.2f}")
        kinds = {c[len("collisions_"):]: sum(m.get(c) or 0 for m in members) for c in KIND_COLUMNS}
        entry.append(", ".join(f"{k} {n}" for k, n in kinds.items() if n) or "–")
        body.append(entry)
    lines.append(markdown_table([*axes, "n (count)", *(f"{_label(s)} (ratio)" for s in SUMMARY_SCORES),
                                 "SUT collisions (count)", "SUT exposures (count)",
                                 "SUT collisions by kind (all seeds, count)"], body))
    if spec.compare is not None and rows:
        axis, ref = spec.compare
        i = axes.index(axis)
        comp = []
        for cell, members in grouped.items():
            if cell[i] == ref:
                continue
            ref_cell = cell[:i] + (ref,) + cell[i + 1:]
            base = {m["seed"]: math.nan if _missing(m.get(column)) else m[column] for m in grouped.get(ref_cell, [])}
            other = {m["seed"]: math.nan if _missing(m.get(column)) else m[column] for m in members}
            p = paired(other, base)  # this cell − the reference (the leaderboard's SUT − reference)
            comp.append([*cell, str(p.n), fmt_ci(p.mean, p.half), difference_words(p.mean, p.half, p.n)])
        sym = SCORE_COLUMNS[column]
        lines.append(f"\n## Paired by seed: each other {axis} − {ref} ({compared})\n")
        lines.append(f"Δ{sym} = the cell's {sym} − {ref}'s on the same seed, mean ± 95 % Student-t interval; "
                     "'significantly higher' ('lower'): the whole interval above (below) 0.\n")
        lines.append(markdown_table([*axes, "seeds (count)", f"Δ{sym} (− {ref}, ratio)", f"vs {ref} (95 %)"], comp))
    return "\n".join(lines) + "\n"
