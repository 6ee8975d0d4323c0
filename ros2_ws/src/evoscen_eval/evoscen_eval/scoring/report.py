"""The evaluation report of a run: ``report.json``, ``report.md`` and PNG plots.

Written the same way by the live evaluator node, by ``scripts/evaluate.py`` from a bag, and
by the in-process runner: :func:`write_stream_report` on the run's
:class:`~evoscen_eval.scoring.streaming.ScoreStream` (:func:`write_report` streams a
:class:`~evoscen_eval.scoring.rundata.RunData` through one). The plots read the stream's
:class:`~evoscen_eval.scoring.plot_inputs.PlotData`, bounded whatever the run's length.

Plots (matplotlib, Agg): the SUT's TTC distribution (``ttc.png``) and speed distribution
(``speed.png``); a timeline of speed, lane and TTC with exposures shaded and collisions
marked (``timeline.png``); the BVs within 100 m of the SUT over time with each 30-s window's mean
(``traffic.png``); a bird's-eye snapshot of the scene at each SUT collision
(``collision_<n>.png``, the first :data:`MAX_SNAPSHOTS`) and at the worst exposure
(``worst_exposure.png``); and a bird's-eye animation around the SUT (``run.gif``,
:mod:`evoscen_eval.scoring.animation`).

Each exposure is listed with the rules that made it one, their values and the vehicles involved
(:mod:`evoscen_eval.scoring.exposure_rules`); the worst-exposure snapshot's title and the exposure table
print the same entry of ``safety.exposure_list`` (:func:`exposure_caption`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from evoscen_sim.config.scenario_config import EvaluationConfig
from evoscen_sim.errors import HostFault, InputError

from evoscen_eval.scoring.animation import ANIMATION_FRAMES, write_animation
from evoscen_eval.scoring.exposure_rules import definition, involved, rules_summary, ttc_text
from evoscen_eval.scoring.metrics import evaluate, report_of_stream, run_info, stream_run
from evoscen_eval.scoring.plot_inputs import SPEED_BINS, TTC_BINS, PlotData, Scene
from evoscen_eval.scoring.rundata import RunData, evaluation_settings_of
from evoscen_eval.scoring.streaming import ScoreStream
from evoscen_eval.scoring.sut_collisions import MAX_SNAPSHOTS

TTC_PLOT_MAX_S = float(TTC_BINS[-1])
"""TTC values above this (and infinite TTC: nothing closing ahead) are left out of the TTC plots."""


def evaluation_settings(run: RunData, override: EvaluationConfig | None = None) -> EvaluationConfig:
    """The evaluation settings of a run: ``override``, else the recorded scenario's, else the defaults."""
    return override if override is not None else evaluation_settings_of(run.scenario)


def report_of(run: RunData, override: EvaluationConfig | None = None) -> dict[str, Any]:
    """The ``report.json`` dict of a run."""
    return evaluate(run, evaluation_settings(run, override))


def write_report(run: RunData, out_dir: Path | str, *, override: EvaluationConfig | None = None,
                 plots: bool = True, source: str | None = None, animation_frames: int = ANIMATION_FRAMES
                 ) -> dict[str, Any]:
    """Score ``run`` and write ``report.json``, ``report.md`` and (``plots``) the PNGs and the
    animation of ``animation_frames`` frames (0: none) into ``out_dir``.

    Returns the report dict. InputError if ``out_dir`` cannot be written; HostFault if the disk is
    full or the file system read-only (:data:`~evoscen_sim.errors.HostFault.ERRNOS`).
    """
    stream = stream_run(run, evaluation_settings(run, override))
    return write_stream_report(stream, run_info(run), list(run.warnings), out_dir, plots=plots, source=source,
                               lane_segments=run.lane_segments, animation_frames=animation_frames)


def write_stream_report(stream: ScoreStream, info: dict[str, Any], warnings: list[str], out_dir: Path | str, *,
                        plots: bool = True, source: str | None = None,
                        lane_segments: np.ndarray | None = None,
                        animation_frames: int = ANIMATION_FRAMES) -> dict[str, Any]:
    """:func:`write_report` for a run scored as it streamed (``info``: :func:`~evoscen_eval.scoring.metrics.run_info_of`)."""
    report = report_of_stream(stream, info, warnings)
    if source is not None:
        report["run"]["source"] = source
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        images = []
        if plots:
            plot = stream.plot_data(lane_segments)
            images = draw_plots(plot, stream.ev, report, out)
            if animation_frames > 0 and write_animation(plot.frames, lane_segments, report, out / ANIMATION_FILE,
                                                        frames=animation_frames):
                images.append(ANIMATION_FILE)
        (out / "report.json").write_text(json.dumps(report, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        (out / "report.md").write_text(markdown(report, images, stream.ev), encoding="utf-8")
    except OSError as exc:
        if exc.errno in HostFault.ERRNOS:  # a full disk, a read-only file system: the host's, not the input's
            raise HostFault.of(exc, exc.filename or out) from None
        raise InputError(f"report directory {str(out)!r}: cannot write: {exc.strerror or exc}") from None
    return report


def score_line(report: dict[str, Any]) -> str:
    """The scores in one line, each term as weight × score (the effective weights, which sum the
    weighted terms to I), e.g. ``intelligence: 0.6889 = 0.6 × safety 0.8104 + 0.2 × efficiency 0.1874
    + 0.2 × interaction 0.8260  complexity: 0.2605  SUT collisions: 0  exposures: 1``."""
    g, c = report["intelligence"], report["complexity"]["score"]
    ew = g.get("effective_weights", g["weights"])
    terms = []
    for name in ("safety", "efficiency", "interaction"):
        score = report[name]["score"]
        terms.append(f"{name} undefined (left out)" if score is None else f"{ew[name]:g} × {name} {score:.4f}")
    intel = "–" if g["score"] is None else f"{g['score']:.4f}"
    return (f"intelligence: {intel} = " + " + ".join(terms) + "  complexity: " + ("-" if c is None else f"{c:.4f}")
            + f"  SUT collisions: {report['safety']['collisions']}  exposures: {report['safety']['exposures']}")


def comparative_line(report: dict[str, Any]) -> str | None:
    """The comparative score D and its terms in one line (docs/evaluation.md §10); None without one."""
    d = report.get("comparative")
    if not d:
        return None
    return (f"comparative: {d['score']:.4f} (progress {d['progress']['score']:.4f}, safety {d['safety']['score']:.4f}, "
            f"lane-change time {d['lane_change_time']['score']:.4f}, interaction {d['interaction']['score']:.4f})")


ANIMATION_FILE = "run.gif"
"""The report's bird's-eye animation (:mod:`evoscen_eval.scoring.animation`)."""

# ---------------------------------------------------------------------- markdown


def _f(x: Any, digits: int = 4) -> str:
    if x is None:
        return "–"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        return f"{x:.{digits}g}" if math.isfinite(x) else str(x)
    return str(x)


def _table(rows: list[tuple[str, Any, str]]) -> str:
    lines = ["| quantity | value | meaning |", "|---|---|---|"]
    esc = lambda text: str(text).replace("|", "\\|")  # noqa: E731 - a literal | would end the cell
    lines += [f"| {esc(name)} | {_f(value)} | {esc(meaning)} |" for name, value, meaning in rows]
    return "\n".join(lines) + "\n"


def exposure_caption(x: dict[str, Any]) -> str:
    """An exposure in one line: its rules with their values and vehicles, its lowest TTC ahead and
    its severity — the words of report.md's exposure table and of the worst-exposure snapshot."""
    ttc = x["min_ttc_s"]
    return (f"{rules_summary(x)}; lowest TTC ahead {'– (never closing)' if ttc is None else ttc_text(ttc) + ' s'}; "
            f"severity {x['severity']:.3g}")


def exposure_rows(exposures: list[dict[str, Any]], limit: int = 50) -> list[str]:
    """report.md's exposure table: one row per exposure (the first ``limit``)."""
    esc = lambda text: str(text).replace("|", "\\|")  # noqa: E731
    out = ["\n| exposure | start (s) | states | rules that made it one: value vs threshold (vehicle) | "
           "lowest TTC ahead (s) | severity |", "|---|---|---|---|---|---|"]
    for n, x in enumerate(exposures[:limit], 1):
        out.append(f"| {n} | {x['start_time_s']:.1f} | {x['states']}{' (open)' if x['open_at_end'] else ''} | "
                   f"{esc(rules_summary(x))} | {ttc_text(x['min_ttc_s'])} | {_f(x['severity'], 3)} |")
    if len(exposures) > limit:
        out.append(f"\n… and {len(exposures) - limit} more (report.json lists all).")
    out.append("")
    return out


def traffic_line(r: dict[str, Any]) -> str:
    """The report's line saying which traffic the run had (make-up, policy set, BVs per class)."""
    makeup = r.get("makeup") or "uniform"
    what = {"highd": "highD make-up (cars and trucks, highD's desired speeds; docs/bv-profiles.md)",
            "uniform": "uniform make-up (every BV a car, desired speeds capped at the limit)"}.get(makeup, makeup)
    parts = [f"Traffic: {what}"]
    if r.get("bv_cars") is not None:
        parts.append(f"{r['bv_cars']} cars and {r['bv_trucks']} trucks")
    parts.append(f"cars driven by {r.get('bv_driver') or '?'}"
                 + (f", policy set {r['policy_set']}" if r.get("policy_set") else ""))
    return "; ".join(parts) + ".\n"


def markdown(report: dict[str, Any], images: list[str], ev: EvaluationConfig | None = None) -> str:
    """``report.md``: the scores and their inputs as tables, then the plots (``ev``: the settings
    the run was scored under, for the exposure rules in words)."""
    r, s, e, i, g, c = (report[k] for k in ("run", "safety", "efficiency", "interaction", "intelligence", "complexity"))
    w = g["weighted"]
    ew = g.get("effective_weights", g["weights"])
    out = [f"# Evaluation: {r.get('scenario') or 'run'} (SUT {r.get('sut_model') or '?'}, seed {r.get('seed')})\n",
           f"{r['steps']} steps ({r['duration_s']:.1f} s simulated, dt {r['dt_s']:g} s), {r['bv_count']} BVs "
           f"({r.get('bv_driver') or '?'}), SUT id {r['sut_id']}; run {'complete' if r['complete'] else 'INCOMPLETE'}.\n",
           traffic_line(r)]
    for warning in report["warnings"]:
        out.append(f"> **warning:** {warning}\n")
    out += ["## Intelligence\n",
            "| metric | score | weight (effective) | weighted term |", "|---|---|---|---|",
            f"| safety I_s | {_f(s['score'])} | {_f(ew['safety'])} | {_f(w['safety'])} |",
            f"| efficiency I_e | {_f(e['score'])} | {_f(ew['efficiency'])} | {_f(w['efficiency'])} |",
            f"| interaction I_i | {_f(i['score'])}{'' if i.get('defined', True) else ' (undefined: no SUT lane change, left out)'}"
            f" | {_f(ew['interaction'])} | {_f(w['interaction'])} |",
            f"| **intelligence I** | | | **{_f(g['score'])}** |\n"]
    d = report.get("comparative")
    if d:  # docs/evaluation.md §10: the score experiments compare SUTs with (evaluation.score_form)
        dw = d["weights"]
        out[-1] = out[-1][:-1]  # the table goes on
        out += [f"| comparative D = P·({dw['safety']:g}·S + {dw['lane_change_time']:g}·L + {dw['interaction']:g}·X): "
                f"P {_f(d['progress']['score'])}, "
                f"S {_f(d['safety']['score'])}, L {_f(d['lane_change_time']['score'])}, X {_f(d['interaction']['score'])}"
                f" | | | **{_f(d['score'])}** |\n"]
    scaled = s.get("count_normalisation") == "method_length"
    formula = ("I_s = 0.7·(1 − min(C', C_max)/C_max) + 0.3·e^(−E'), C' = C·N_ref/N, E' = E·N_ref/N "
               "(counts scaled to the method's run length)\n" if scaled else "I_s = 0.7·(1 − min(C, C_max)/C_max) + 0.3·e^(−E)\n")
    counts = []
    if "count_normalisation" in s:  # reports from before the key: the counts entered as counted
        counts = [
            ("count normalisation", s["count_normalisation"], "method_length: C and E scaled to N_ref steps; "
                                                               "literal: as counted"),
            ("N", s["steps"], "steps scored (the run's length)"),
            ("N_ref", s["count_reference_steps"], "reference length (steps)" + ("" if scaled else ", unused")),
            ("C'", s["collisions_used"], "C as it enters I_s" + (f" (C·{s['count_factor']:.6g})" if scaled else "")),
            ("E'", s["exposures_used"], "E as it enters I_s" + (f" (E·{s['count_factor']:.6g})" if scaled else "")),
        ]
    rules = (definition(ev) if ev is not None else
             [f"see docs/evaluation.md §2 (TTC threshold {s['ttc_threshold_s']:g} s, hard braking "
              f"{s['hard_brake_mps2']:g} m/s²)"])
    rules_md = ("A state is dangerous when one of these rules holds (docs/evaluation.md §2); an exposure is a "
                "maximal run of dangerous states:\n\n" + "\n".join(f"- {r}" for r in rules) + "\n")
    out += ["## Safety\n", formula, rules_md, _table([
        ("C", s["collisions"], "collisions involving the SUT (one per contact), counted in the run"),
        ("C_max", s["collision_cap"], "collision cap"),
        ("E", s["exposures"], "exposures (maximal runs of dangerous states: the rules above), counted in the run"),
        *counts,
        ("open at end", s["exposures_open_at_end"], "exposures still open when the run ended (counted)"),
        ("dangerous states", s["dangerous_states"], "states in exposures"),
        ("min TTC (s)", s["min_ttc_s"], "lowest TTC to the vehicle ahead in the SUT's path (– = never closing)"),
        ("min acceleration (m/s²)", s["min_accel_mps2"], "the SUT's hardest braking (dangerous only as the "
                                                        "hard-braking rule above reads it)"),
        ("all collisions", s["collisions_all"], "every colliding pair, BVs included"),
    ])]
    if s.get("conflicts"):
        out += conflicts_markdown(s["conflicts"])
    if s["exposure_list"]:
        out += exposure_rows(s["exposure_list"])
    if "surrogate_safety" in report:
        out += surrogate_markdown(report["surrogate_safety"])
    out += ["\n## Efficiency\n", "I_e = 0.5·(density-speed term + e^(−T̄_l/3))\n", _table([
        ("v̄ (m/s)", e["mean_speed_mps"], "mean SUT speed"),
        ("h̄", e["mean_vehicles_in_view"], "mean vehicles in the SUT's view"),
        ("H", e["max_vehicles_in_view"], "most vehicles that fit in the view"),
        ("v_max (m/s)", e["v_max_mps"], "speed normaliser"),
        ("density-speed term", e["density_speed_term"], f"form: {e['density_form']}"),
        ("T̄_l (s)", e["mean_lane_change_time_s"], "mean SUT lane-change time"
         + ("" if e["lane_change_time_defined"] else (" (no lane change: the configured default)"
                                                     if e.get("lane_change_term_used", True)
                                                     else " (no lane change: undefined, term left out of I_e)"))),
        ("lane changes", e["lane_changes"], f"completed by the SUT ({e['lane_changes_aborted']} aborted)"),
        ("e^(−T̄_l/3)", e["lane_change_term"], "lane-change term"),
    ])]
    out += ["\n## Interaction utility\n", "I_i = (1/3)·(2 − clip(|v~|)/Δv_max − clip(|a~|)/Δa_max + e^(−√L̄))\n",
            _table([
                ("SUT lane changes", i["sut_lane_changes"], "lane changes the averages run over"),
                ("|v~| (m/s)", i["speed_fluctuation_mps"], "in-view BVs' mean |speed − speed at the change's start|"),
                ("|a~| (m/s²)", i["accel_fluctuation_mps2"], "same for acceleration"),
                ("L̄", i["bv_lane_changes"], "mean lane changes of in-view BVs during the SUT's changes"),
                ("Δv_max, Δa_max", f"{i['dv_max_mps']:g}, {i['da_max_mps2']:g}", "normalisers"),
            ])]
    out += ["\n## Complexity\n", "C = 0.4·(1 − e^(−E/k1)) + 0.3·(2 − e^(−LC/k2) − e^(−AD/k3))\n", _table([
        ("C", c["score"], "complexity score"),
        ("LC", c["lane_changes"], f"lane changes (all vehicles) per {c['window_steps']}-state window"),
        ("AD", c["accel_decel"], f"vehicle-states with |acceleration| > {c['accel_activity_mps2']:g} m/s² per window"
                + (f" (acceleration averaged over the trailing {c['accel_activity_window_s']:g} s)"
                   if c.get("accel_activity_form") == "smoothed" else "")),
        ("E", c["exposures"], "SUT exposures per window"),
        ("windows", c["windows"], "whole windows in the run"),
        ("k1, k2, k3", ", ".join(f"{k:g}" for k in c["k"]), "constants"),
    ])]
    if "traffic" in report:
        out += traffic_markdown(report["traffic"])
    if images:
        out.append("\n## Plots\n")
        out += [f"![{Path(name).stem}]({name})\n" for name in images]
    return "\n".join(out) + "\n"


def conflicts_markdown(cf: dict[str, Any]) -> list[str]:
    """report.md's "Conflicts on either side of the SUT": the ``safety.conflicts`` section as a table."""
    return ["\n### Conflicts on either side of the SUT (docs/evaluation.md)\n", _table([
        ("rear conflicts", cf["rear_conflicts"], f"which follower conflicts are the SUT's (window "
                                                  f"{cf['rear_attribution_s']:g} s after a SUT lane change)"),
        ("rear braking", cf.get("rear_braking", "any"),
         (f"a follower's hard braking counts within {cf['rear_braking_headway_s']:g} s of headway"
          if cf.get("rear_braking") == "within_headway" else "a follower's hard braking counts at any distance")),
        ("rear conflict states", cf["rear_conflict_states"], "follower in the path: TTC below threshold or hard brake"),
        ("... attributed", cf["rear_conflict_states_attributed"], "of them in the attribution window (dangerous)"),
        ("cut-in states", cf.get("cut_in_states", 0),
         (f"SUT changing lanes with its new follower within {cf['cut_in_gap_m']:g} m (dangerous)"
          if cf.get("cut_in_gap_m") else "not counted (cut_in_gap_m 0)")),
        ("min cut-in gap (m)", cf.get("min_cut_in_gap_m"), "new follower behind the SUT during its lane changes "
                                                          "(– = none)"),
        ("beside states", cf.get("beside_states", 0),
         ("SUT changing lanes with a vehicle of its target lane beside it (dangerous)"
          if cf.get("beside_lane_change") else "not counted (beside_lane_change false)")),
        ("min beside gap (m)", cf.get("min_beside_gap_m"), "longitudinal gap to the target lane's nearest vehicle "
                                                           "during SUT lane changes; < 0 = beside (– = none)"),
        ("headway states", cf.get("headway_states", 0),
         (f"SUT following its leader under {cf['headway_threshold_s']:g} s of time headway, not falling back "
          "(dangerous)" if cf.get("headway_threshold_s") else "not counted (headway_threshold_s 0)")),
        ("min follower TTC (s)", cf["min_follower_ttc_s"], "follower onto the SUT (– = never closing)"),
        ("max DRAC SUT (m/s²)", cf["max_drac_sut_mps2"], "SUT behind its leader (– = infinite)"),
        ("max DRAC follower (m/s²)", cf["max_drac_follower_mps2"], "follower behind the SUT (– = infinite)"),
        (f"DRAC > {cf['drac_threshold_mps2']:g} states", f"{cf['drac_sut_states']} / {cf['drac_follower_states']}",
         "SUT / follower"),
        ("min lane-change PET (s)", cf["min_pet_s"], f"over {len(cf['lane_change_pet'])} SUT lane changes"),
    ])]


def surrogate_markdown(ss: dict[str, Any]) -> list[str]:
    """report.md's "Surrogate safety": per side of the SUT the counts and sums, and each per SUT-km."""
    f, r = ss["front"], ss["rear"]
    rows = [("ttc_episodes", f"TTC < {ss['ttc_threshold_s']:g} s episodes", "episodes"),
            ("drac_episodes", f"DRAC > {ss['drac_threshold_mps2']:g} m/s² episodes", "episodes"),
            ("pet_events", f"PET < {ss['pet_threshold_s']:g} s lane changes", "lane changes"),
            ("tet_s", f"TET (TTC < {ss['ttc_threshold_s']:g} s)", "s"),
            ("tit_s2", "TIT", "s²")]
    out = ["\n## Surrogate safety\n",
           f"The SUT's conflicts on both sides over {ss['sut_km']:.3f} SUT-km (front: the SUT behind the vehicle "
           "ahead in its path; rear: the vehicle behind in its path behind the SUT, and for PET the new follower "
           "of each SUT lane change); an episode is a maximal run of states beyond the threshold with the same "
           "other vehicle (reported only: no score reads it).\n",
           "| measure | front | rear | front per SUT-km | rear per SUT-km | unit |", "|---|---|---|---|---|---|"]
    for key, name, unit in rows:
        out.append(f"| {name} | {_f(f[key])} | {_f(r[key])} | {_f(f['per_km'][key])} | {_f(r['per_km'][key])} | "
                   f"{unit} |")
    out.append("")
    return out


TRAFFIC_TABLE_WINDOWS = 50
"""Up to this many traffic windows report.md lists as a table; more as one line of means."""


def traffic_markdown(tr: dict[str, Any]) -> list[str]:
    """report.md's "Traffic around the SUT": the run's figures, then the mean of each window."""
    rng, n_w = f"{tr['range_m']:g} m", len(tr["windows"])
    whole = n_w - int(tr["last_window_partial"])
    windows = f"{whole} whole, of {tr['window_s']:g} s ({tr['window_states']} states)"
    if tr["last_window_partial"]:
        windows += f", and a last partial one of {tr['windows'][-1]['states']} states"
    if tr["tail_states_left_out"]:
        windows += (f"; the last {tr['tail_states_left_out']} states (under half a window) are in the mean, "
                    "not in a window")
    out = ["\n## Traffic around the SUT\n",
           f"BVs within {rng} of the SUT along the road (|s_BV − s_SUT| ≤ {rng}, any lane), counted in every "
           f"state and averaged per {tr['window_s']:g}-s window from the run's start (reported only: no score "
           "reads it).\n", _table([
               ("mean BVs", tr["mean_bvs"], f"BVs within {rng}, mean over the run's states"),
               ("lowest window mean", tr["min_window_mean_bvs"], "the emptiest window (– = no window)"),
               ("states with none", f"{tr['empty_states']} ({100.0 * tr['empty_share']:.1f} %)",
                f"states without a BV within {rng}"),
               ("windows", n_w, windows),
           ])]
    if not n_w:
        return out
    if n_w <= TRAFFIC_TABLE_WINDOWS:
        out += ["\n| window | from t (s) | states | mean BVs |", "|---|---|---|---|"]
        out += [f"| {n} | {x['start_time_s']:.1f} | {x['states']}{' (partial)' if x['partial'] else ''} | "
                f"{_f(x['mean_bvs'], 3)} |" for n, x in enumerate(tr["windows"], 1)]
        out.append("")
    else:
        out.append(f"\nWindow means, in order{' (the last partial)' if tr['last_window_partial'] else ''}: "
                   + ", ".join(_f(m, 3) for m in tr["per_window_mean_bvs"]) + "\n")
    return out


# ---------------------------------------------------------------------- plots


def draw_plots(plot: PlotData, ev: EvaluationConfig, report: dict[str, Any], out: Path) -> list[str]:
    """Draw the PNGs into ``out``; returns their file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names: list[str] = []
    closing = int(plot.ttc_hist.sum())
    fig, ax = plt.subplots(figsize=(6, 3.5))
    if closing:
        ax.stairs(plot.ttc_hist, TTC_BINS, fill=True, color="tab:blue")
    ax.axvline(ev.ttc_threshold_s, color="tab:red", ls="--", label=f"threshold {ev.ttc_threshold_s:g} s")
    ax.set(xlabel="SUT TTC to the vehicle ahead in its path (s)", ylabel="states",
           title=f"TTC distribution ({closing} of {plot.states} states closing within {TTC_PLOT_MAX_S:g} s)")
    ax.legend()
    names.append(_save(fig, out, "ttc.png"))

    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.stairs(plot.speed_hist, SPEED_BINS, fill=True, color="tab:green")
    ax.set(xlabel="SUT speed (m/s)", ylabel="states",
           title=f"Speed distribution (mean {report['efficiency']['mean_speed_mps']:.2f} m/s)")
    names.append(_save(fig, out, "speed.png"))

    t = plot.timeline_time_s
    fig, axes = plt.subplots(3, 1, figsize=(10, 6.5), sharex=True)
    axes[0].plot(t, plot.timeline_speed, lw=0.8)
    axes[0].set_ylabel("speed (m/s)")
    axes[1].step(t, plot.timeline_lane, where="post", lw=0.8)
    axes[1].set_ylabel("lane")
    from matplotlib.ticker import MaxNLocator

    axes[1].yaxis.set_major_locator(MaxNLocator(integer=True))
    axes[2].plot(t, np.minimum(plot.timeline_ttc, TTC_PLOT_MAX_S), lw=0.8)
    axes[2].axhline(ev.ttc_threshold_s, color="tab:red", ls="--", lw=0.8)
    axes[2].set(ylabel=f"TTC (s, ≤{TTC_PLOT_MAX_S:g})", xlabel="time (s)")
    dt = report["run"]["dt_s"]
    t0 = float(t[0]) if t.size else 0.0
    spans = exposure_spans(report, t0)
    for a, b in spans:
        for ax in axes:
            ax.axvspan(a, b, color="tab:orange", alpha=0.35, lw=0)
    if spans:  # a marker above each exposure: visible whatever the run's length
        axes[0].plot([(a + b) / 2 for a, b in spans], [1.0] * len(spans), "v", color="tab:orange", ms=7,
                     transform=axes[0].get_xaxis_transform(), clip_on=False, label="exposure")
    for col in report["safety"]["collision_list"]:
        for ax in axes:
            ax.axvline(col["time_s"], color="tab:red", lw=1.2)
    starts = lane_change_marks(report, t0, t, plot.timeline_lane)
    for direction, marker, colour in ((1, "^", "tab:green"), (-1, "v", "tab:purple")):
        pts = [(tm, lane) for tm, lane, d in starts if d == direction]
        if pts:
            axes[1].plot(*zip(*pts), marker, color=colour, ms=4, ls="none",
                         label="SUT lane change " + ("left" if direction > 0 else "right"))
    if starts:
        axes[1].legend(loc="upper right", fontsize=7)
    every = "" if plot.timeline_stride == 1 else f"; one point per {plot.timeline_stride} states, lowest TTC"
    axes[0].set_title(f"SUT timeline: {report['safety']['exposures']} exposures (shaded, ▼; at least "
                      f"{100 * MIN_SPAN_SHARE:g} % of the axis wide), {len(starts)} SUT lane changes (▲ left, ▼ right), "
                      f"{report['safety']['collisions']} collisions (red){every}", fontsize=9)
    names.append(_save(fig, out, "timeline.png"))

    if "traffic" in report:
        names.append(_traffic_plot(plt, plot, report["traffic"], dt, out))

    for n, col in enumerate(report["safety"]["collision_list"][:MAX_SNAPSHOTS], 1):
        scene = plot.collision_scenes.get(min(int(col["state"]), plot.states - 1))
        if scene is not None:
            names.append(_snapshot(plt, scene, plot.lane_segments, set(col["ids"]),
                                   f"collision {n} at t = {col['time_s']:.1f} s", out, f"collision_{n}.png"))
    if plot.worst_scene is not None:
        w = plot.worst_scene
        n, x = worst_exposure_of(report, w.state)
        names.append(_snapshot(plt, w, plot.lane_segments, set(involved(x)) if x else set(),
                               worst_exposure_title(report, w.state, w.time_s), out, "worst_exposure.png"))
    return names


MIN_SPAN_SHARE = 0.004
"""An exposure's span on the timeline is at least this share of the run's duration wide (0.4 %: 1.2 s of a
300-s run), so a one-state exposure is not a hairline."""


def exposure_spans(report: dict[str, Any], t0: float = 0.0) -> list[tuple[float, float]]:
    """Each exposure's (start, end) on the timeline (s): its states, widened about their middle to at
    least :data:`MIN_SPAN_SHARE` of the run's duration and clamped to the run."""
    dt, duration = report["run"]["dt_s"], report["run"]["duration_s"]
    last = t0 + duration
    width = MIN_SPAN_SHARE * duration
    out = []
    for x in report["safety"]["exposure_list"]:
        a, b = x["start_time_s"], min(x["start_time_s"] + x["states"] * dt, last)
        if b - a < width:
            mid = (a + b) / 2
            a, b = max(t0, mid - width / 2), min(last, mid + width / 2)
        out.append((a, b))
    return out


def lane_change_marks(report: dict[str, Any], t0: float, times: np.ndarray, lanes: np.ndarray
                      ) -> list[tuple[float, float, int]]:
    """The SUT's lane changes as (time of the first state, lane there, +1 left / -1 right), from
    ``safety.conflicts.lane_change_pet`` (one entry per change; none in a report without it); the
    lane and so the direction (towards the target lane) from the timeline's point at that time."""
    dt = report["run"]["dt_s"]
    out = []
    for c in (report["safety"].get("conflicts") or {}).get("lane_change_pet", []):
        tm = t0 + int(c["start_state"]) * dt
        i = max(0, int(np.searchsorted(times, tm + 1e-9, side="right")) - 1)
        lane = float(lanes[i]) if len(lanes) else float(c["target_lane"])
        out.append((tm, lane, 1 if int(c["target_lane"]) > lane else -1))
    return out


def worst_exposure_of(report: dict[str, Any], state: int) -> tuple[int, dict[str, Any] | None]:
    """The exposure whose worst state is ``state`` and its number in report.md's table (1-based)."""
    for n, x in enumerate(report["safety"]["exposure_list"], 1):
        if int(x["worst_state"]) == int(state):
            return n, x
    return 0, None


def worst_exposure_title(report: dict[str, Any], state: int, time_s: float) -> str:
    """The title of ``worst_exposure.png``: the exposure's entry in report.md's words (:func:`exposure_caption`)."""
    n, x = worst_exposure_of(report, state)
    head = f"worst exposure (no. {n} of report.md) at its most severe state, t = {time_s:.1f} s"
    return head + (": " + exposure_caption(x) if x else "")


def _traffic_plot(plt, plot: PlotData, tr: dict[str, Any], dt: float, out: Path) -> str:
    """``traffic.png``: BVs within the range of the SUT over time with each window's mean."""
    from matplotlib.ticker import MaxNLocator

    fig, ax = plt.subplots(figsize=(10, 3.5))
    t = plot.timeline_time_s
    per = "per state" if plot.timeline_stride == 1 else f"mean of each {plot.timeline_stride} states"
    ax.step(t, plot.timeline_bvs, where="post", lw=0.7, color="0.55", label=f"BVs within {tr['range_m']:g} m ({per})")
    for n, x in enumerate(tr["windows"]):
        end = x["start_time_s"] + x["states"] * dt
        label = ("last partial window's mean" if x["partial"] else
                 f"{tr['window_s']:g}-s window mean" if n == 0 else None)
        ax.hlines(x["mean_bvs"], x["start_time_s"], end, colors="tab:blue", lw=2.5, ls=":" if x["partial"] else "-",
                  label=label)
    ax.axhline(tr["mean_bvs"], color="tab:red", ls="--", lw=0.8, label=f"run mean {tr['mean_bvs']:.2f}")
    ax.set_ylim(bottom=-0.25)  # a count of 0 stays visible above the axis
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    low = tr["min_window_mean_bvs"]
    ax.set(xlabel="time (s)", ylabel="BVs",
           title=f"Traffic around the SUT: mean {tr['mean_bvs']:.2f} BVs within {tr['range_m']:g} m, lowest window "
                 f"{'–' if low is None else f'{low:.2f}'}, none in {100.0 * tr['empty_share']:.1f} % of states")
    ax.legend(loc="upper right", fontsize=8)
    return _save(fig, out, "traffic.png")


def _save(fig, out: Path, name: str) -> str:
    fig.tight_layout()
    fig.savefig(out / name, dpi=100)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return name


def _snapshot(plt, scene: Scene, lane_segments: np.ndarray | None, highlight: set[int], title: str,
              out: Path, name: str) -> str:
    """Bird's-eye view around the SUT in ``scene``: lane lines, every vehicle as its box."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Polygon

    c, sut = scene.columns, scene.sut_index
    cx, cy = c["x"][sut], c["y"][sut]
    half = 70.0
    fig, ax = plt.subplots(figsize=(10, 4))
    if lane_segments is not None and len(lane_segments):
        seg = lane_segments
        near = (np.abs(seg[:, :, 0] - cx).min(axis=1) < 2 * half) & (np.abs(seg[:, :, 1] - cy).min(axis=1) < 2 * half)
        ax.add_collection(LineCollection(seg[near], colors="0.6", linewidths=0.8))
    for j in range(scene.ids.shape[0]):
        x, y, yaw, length, width = (c[f][j] for f in ("x", "y", "yaw", "length", "width"))
        if abs(x - cx) > half + 10 or abs(y - cy) > half:
            continue
        ca, sa = math.cos(yaw), math.sin(yaw)
        corners = [(x + ca * u - sa * v, y + sa * u + ca * v)
                   for u, v in ((length / 2, width / 2), (-length / 2, width / 2),
                                (-length / 2, -width / 2), (length / 2, -width / 2))]
        vid = int(scene.ids[j])
        color = "orange" if j == sut else ("tab:red" if vid in highlight else "tab:blue")
        edge, lw = ("tab:red", 2.0) if vid in highlight else ("k", 0.5)
        ax.add_patch(Polygon(corners, closed=True, fc=color, ec=edge, lw=lw, alpha=0.85))
        ax.text(x, y + width, f"{vid}\n{c['speed'][j] * 3.6:.0f}", fontsize=6, ha="center", va="bottom")
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(cy - 15, cy + 15)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    import textwrap

    wrapped = "\n".join(line for part in title.split("\n") for line in textwrap.wrap(part, 120))
    ax.set_title(f"{wrapped}\n(SUT orange, involved vehicles outlined red; ids, km/h)", fontsize=8)
    return _save(fig, out, name)
