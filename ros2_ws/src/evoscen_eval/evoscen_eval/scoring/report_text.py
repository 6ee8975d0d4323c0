"""The report's words: ``report.md`` (:func:`markdown`) and the score lines a run prints (:func:`score_lines`).

One score story wherever a score is read (docs/evaluation.md, "Symbols"): D, the comparative score evoscen
ranks SUTs by, first, with its terms P, S, L, X; then the method's intelligence I, reported for
reproducing the paper. Every count says whose it is (the SUT's or all vehicles'); every number of a table
names its unit, or says it is a count or a ratio (a ``unit`` column, or the unit in the column's header).
"""

from __future__ import annotations

import math
from typing import Any

from evoscen_sim.config.scenario_config import EvaluationConfig

from evoscen_eval.scoring.exposure_rules import definition, rules_summary, ttc_text
from evoscen_eval.scoring.metrics import D_NAME

I_NAME = "the method's intelligence I (for reproducing the paper)"
"""What the method's I is called wherever it is shown (docs/method.md (24))."""
SEVERITY_MEANING = ("severity: how far the worst state went past its rule's threshold, a ratio (1 at the "
                    "threshold, 2 at twice the danger; docs/evaluation.md §2.1)")


def plural(n: int, one: str, many: str | None = None) -> str:
    """``n`` with its noun in the right number: ``1 state``, ``2 states``."""
    return f"{n} {one if n == 1 else (many or one + 's')}"


def lane_changes_under_way(report: dict[str, Any]) -> int:
    """The SUT's lane changes still under way when the run ended (0 or 1): the last of
    ``interaction.changes`` (every change the SUT started) lasting to the run's last state."""
    changes = report["interaction"].get("changes") or []
    states = report["run"].get("states")
    last = changes[-1]["end_state"] if changes else None
    return int(states is not None and last is not None and last >= states)


# ---------------------------------------------------------------------- the printed lines


def comparative_line(report: dict[str, Any]) -> str | None:
    """D and its terms in one line (docs/evaluation.md §10); None without a ``comparative`` section."""
    d = report.get("comparative")
    if not d:
        return None
    w = d.get("weights") or {"safety": 0.6, "lane_change_time": 0.2, "interaction": 0.2}
    return (f"{D_NAME}: {d['score']:.4f} = P·({w['safety']:g}·S + {w['lane_change_time']:g}·L + "
            f"{w['interaction']:g}·X): progress P {d['progress']['score']:.4f}, safety per SUT-km S "
            f"{d['safety']['score']:.4f}, lane-change time L {d['lane_change_time']['score']:.4f}, "
            f"interaction X {d['interaction']['score']:.4f}")


def score_line(report: dict[str, Any]) -> str:
    """The method's I in one line, each term as weight × score (the effective weights, which sum the
    weighted terms to I), e.g. ``the method's intelligence I (for reproducing the paper): 0.6889 = 0.6 ×
    safety I_s 0.8104 + 0.2 × efficiency I_e 0.1874 + 0.2 × interaction I_i 0.8260``."""
    g = report["intelligence"]
    ew = g.get("effective_weights", g["weights"])
    terms = []
    for name, sym in (("safety", "I_s"), ("efficiency", "I_e"), ("interaction", "I_i")):
        score = report[name]["score"]
        terms.append(f"{name} {sym} undefined (left out)" if score is None else f"{ew[name]:g} × {name} {sym} {score:.4f}")
    intel = "–" if g["score"] is None else f"{g['score']:.4f}"
    return f"{I_NAME}: {intel} = " + " + ".join(terms)


def counts_line(report: dict[str, Any]) -> str:
    """The scenario's complexity K and the SUT's counts in one line."""
    c, s = report["complexity"]["score"], report["safety"]
    return ("complexity K (the scenario's): " + ("–" if c is None else f"{c:.4f}")
            + f"  SUT collisions: {s['collisions']}  SUT exposures: {s['exposures']}")


def challenge_line(report: dict[str, Any]) -> str | None:
    """The challenge layer in one line (None for a run without it), e.g. ``challenges (the SUT's leader
    braking hard): 1 onset; the run's weight p/q = 0.0245``."""
    ch = report.get("challenge")
    if ch is None:
        return None
    return (f"challenges (the SUT's leader braking hard): {plural(ch['count'], 'onset')}; the run's weight p/q = "
            f"{ch['weight']:.4g}" + ("" if ch["complete"] else " (run cut short: its onsets' factors only)"))


def score_lines(report: dict[str, Any]) -> list[str]:
    """What a run prints of its scores, D first: D's line, I's line, K and the SUT's counts; the challenges
    where the run had the layer."""
    first, challenge = comparative_line(report), challenge_line(report)
    return [*([first] if first else []), score_line(report), counts_line(report), *([challenge] if challenge else [])]


def challenge_markdown(ch: dict[str, Any]) -> list[str]:
    """The report's challenge section: each onset, the run's weight (docs/challenges.md)."""
    out = ["\n## Challenges\n", f"{plural(ch['count'], 'onset')} of the SUT's leader's hard braking, drawn "
           f"from the tilted distribution; the run's likelihood ratio p/q = {ch['weight']:.6g} (log "
           f"{ch['log_weight']:.6g}){'' if ch['complete'] else ', the run cut short: its onsets only'}; "
           "naturalistic rates weight each run by it (docs/challenges.md).\n"]
    if ch["onsets"]:
        out += ["| step | time (s) | vehicle | deceleration (m/s²) | duration (s) | q/p |", "|---|---|---|---|---|---|"]
        out += [f"| {o['step']} | {o['time_s']:.1f} | {o['vehicle']} | {o['decel_mps2']:.2f} | {o['duration_s']:.2f} | "
                f"{o['multiplier']:.4g} |" for o in ch["onsets"]]
        out.append("")
    return out


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


def _esc(text: Any) -> str:
    return str(text).replace("|", "\\|")  # a literal | would end the cell


def _table(rows: list[tuple[str, Any, str, str]]) -> str:
    """A table of (quantity, value, unit, meaning); unit ``count``, ``ratio``, a unit, or ``–`` for a setting."""
    lines = ["| quantity | value | unit | meaning |", "|---|---|---|---|"]
    lines += [f"| {_esc(name)} | {_f(value)} | {_esc(unit)} | {_esc(meaning)} |" for name, value, unit, meaning in rows]
    return "\n".join(lines) + "\n"


def exposure_caption(x: dict[str, Any]) -> str:
    """An exposure in one line: its rules with their values and vehicles, its lowest TTC ahead and
    its severity — the words of report.md's exposure table and of the worst-exposure snapshot."""
    ttc = x["min_ttc_s"]
    return (f"{rules_summary(x)}; lowest TTC ahead {'– (never closing)' if ttc is None else ttc_text(ttc) + ' s'}; "
            f"severity {x['severity']:.3g} (1 at the threshold, 2 at twice the danger)")


def exposure_rows(exposures: list[dict[str, Any]], limit: int = 50) -> list[str]:
    """report.md's exposure table: one row per exposure (the first ``limit``)."""
    out = ["\n| exposure (no.) | start (s) | states (count) | rules that made it one: value vs threshold (vehicle) | "
           "lowest TTC ahead (s) | severity (ratio) |", "|---|---|---|---|---|---|"]
    for n, x in enumerate(exposures[:limit], 1):
        out.append(f"| {n} | {x['start_time_s']:.1f} | {x['states']}{' (open)' if x['open_at_end'] else ''} | "
                   f"{_esc(rules_summary(x))} | {ttc_text(x['min_ttc_s'])} | {_f(x['severity'], 3)} |")
    if len(exposures) > limit:
        out.append(f"\n… and {len(exposures) - limit} more (report.json lists all).")
    out.append(f"\n{SEVERITY_MEANING[0].upper()}{SEVERITY_MEANING[1:]}.\n")
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


def comparative_markdown(report: dict[str, Any]) -> list[str]:
    """report.md's first section: D, its formula and its terms' formulas with their values (docs/evaluation.md §10)."""
    d = report.get("comparative")
    if not d:
        return []
    w, p, s, lt, x = d["weights"], d["progress"], d["safety"], d["lane_change_time"], d["interaction"]
    neutral = f"no SUT lane change: the neutral {_f(d['no_lane_change_value'])}"
    ranks = ("the score evoscen ranks SUTs by" if d.get("score_form", "comparative") == "comparative" else
             "reported beside I, which this run's `evaluation.score_form: method` ranks by")
    return [f"## {D_NAME}\n",
            f"D is {ranks} (docs/evaluation.md §10): D = P·({w['safety']:g}·S + {w['lane_change_time']:g}·L + "
            f"{w['interaction']:g}·X) = {_f(p['score'])} × ({w['safety']:g} × {_f(s['score'])} + "
            f"{w['lane_change_time']:g} × {_f(lt['score'])} + {w['interaction']:g} × {_f(x['score'])}) = "
            f"**{_f(d['score'])}**\n",
            "| term | value (ratio) | formula | meaning |", "|---|---|---|---|",
            f"| progress P | {_f(p['score'])} | min(1, d_SUT/d_ref) = min(1, {_f(p['sut_distance_m'])} m / "
            f"{_f(p['reference_distance_m'])} m) | the SUT's distance against that of the traffic in its view |",
            f"| safety S | {_f(s['score'])} | 1/(1 + r/r0), r = (E + κ·C)/km = ({s['exposures']} + "
            f"{_f(s['collision_exposures'])}·{s['collisions']}) / {_f(s['sut_km'])} km = {_f(s['rate_per_km'])} "
            f"per km, r0 = {_f(s['rate_scale_per_km'])} per km | every SUT exposure (E) and collision (C) costs, "
            "per SUT-km |",
            f"| lane-change time L | {_f(lt['score'])} | "
            + (f"e^(−T̄_l/{_f(lt['lane_change_time_scale_s'])} s), T̄_l = {_f(lt['mean_lane_change_time_s'])} s"
               if lt["defined"] else neutral) + " | the SUT's completed lane changes |",
            f"| interaction X | {_f(x['score'])} | " + ("I_i (below)" if x["defined"] else neutral)
            + " | the BVs' reactions to the SUT's lane changes |\n"]


def intelligence_markdown(report: dict[str, Any]) -> list[str]:
    """report.md's section on the method's I: each term as weight × score, and what the weights are."""
    s, e, i, g = (report[k] for k in ("safety", "efficiency", "interaction", "intelligence"))
    w, ew = g["weighted"], g.get("effective_weights", g["weights"])
    same = all(abs(ew[k] - g["weights"][k]) < 1e-12 for k in ew)
    weights = ("the weights as configured (`evaluation.weight_*`)" if same else
               "the effective weights: an undefined term is left out and the others scaled to sum to 1 "
               "(`evaluation.undefined_terms: exclude`, docs/evaluation.md §4)")
    return [f"## {I_NAME[0].upper()}{I_NAME[1:]}\n",
            f"I = i_s·I_s + i_e·I_e + i_i·I_i (docs/method.md (24)), with {weights}. Its safety I_s is not D's S: "
            "I_s scales the counts to the method's run length and saturates, S is a rate per SUT-km.\n",
            "| metric | score (ratio) | weight (ratio) | weighted term (ratio) |", "|---|---|---|---|",
            f"| safety I_s | {_f(s['score'])} | {_f(ew['safety'])} | {_f(w['safety'])} |",
            f"| efficiency I_e | {_f(e['score'])} | {_f(ew['efficiency'])} | {_f(w['efficiency'])} |",
            f"| interaction I_i | {_f(i['score'])}{'' if i.get('defined', True) else ' (undefined: no SUT lane change, left out)'}"
            f" | {_f(ew['interaction'])} | {_f(w['interaction'])} |",
            f"| **I** | | | **{_f(g['score'])}** |\n"]


def safety_markdown(s: dict[str, Any], ev: EvaluationConfig | None) -> list[str]:
    """report.md's "Safety": I_s's formula, the rules in words, its counts."""
    scaled = s.get("count_normalisation") == "method_length"
    formula = ("I_s = 0.7·(1 − min(C', C_max)/C_max) + 0.3·e^(−E'), C' = C·N_ref/N, E' = E·N_ref/N "
               "(counts scaled to the method's run length)\n" if scaled else "I_s = 0.7·(1 − min(C, C_max)/C_max) + 0.3·e^(−E)\n")
    counts = []
    if "count_normalisation" in s:  # reports from before the key: the counts entered as counted
        counts = [
            ("count normalisation", s["count_normalisation"], "–", "method_length: C and E scaled to N_ref steps; "
                                                                    "literal: as counted"),
            ("N", s["steps"], "steps", "steps scored (the run's length)"),
            ("N_ref", s["count_reference_steps"], "steps", "reference length" + ("" if scaled else ", unused")),
            ("C'", s["collisions_used"], "count", "C as it enters I_s" + (f" (C·{s['count_factor']:.6g})" if scaled else "")),
            ("E'", s["exposures_used"], "count", "E as it enters I_s" + (f" (E·{s['count_factor']:.6g})" if scaled else "")),
        ]
    rules = (definition(ev) if ev is not None else
             [f"see docs/evaluation.md §2 (TTC threshold {s['ttc_threshold_s']:g} s, hard braking "
              f"{s['hard_brake_mps2']:g} m/s²)"])
    rules_md = ("A state is dangerous when one of these rules holds (docs/evaluation.md §2); an exposure is a "
                "maximal run of dangerous states:\n\n" + "\n".join(f"- {r}" for r in rules) + "\n")
    return ["## Safety I_s\n", formula, rules_md, _table([
        ("C", s["collisions"], "count", "collisions involving the SUT (one per contact), counted in the run"),
        ("C_max", s["collision_cap"], "count", "collision cap"),
        ("E", s["exposures"], "count", "the SUT's exposures (maximal runs of dangerous states: the rules above), "
                                       "counted in the run"),
        *counts,
        ("open at end", s["exposures_open_at_end"], "count", "exposures still open when the run ended (in E)"),
        ("dangerous states", s["dangerous_states"], "count", "states in exposures"),
        ("min TTC", s["min_ttc_s"], "s", "lowest TTC to the vehicle ahead in the SUT's path (– = never closing)"),
        ("min acceleration", s["min_accel_mps2"], "m/s²", "the SUT's hardest braking (dangerous only as the "
                                                           "hard-braking rule above reads it)"),
        ("all collisions", s["collisions_all"], "count", "every colliding pair, BVs included"),
    ])]


def efficiency_markdown(report: dict[str, Any]) -> list[str]:
    """report.md's "Efficiency": I_e's formula, Q's form in words, the SUT's lane changes (those under way said)."""
    e = report["efficiency"]
    under_way = lane_changes_under_way(report)
    literal = e["density_form"] == "literal"
    form = (f"literal: the method's formula as printed, √h̄·v̄/(H·v_max), at most 1/√H = {_f(1 / math.sqrt(e['max_vehicles_in_view']))} "
            "(a full view at v_max), so I_e stays low even at full speed" if literal else
            "normalised: √(h̄/H)·v̄/v_max, 1 in a full view at v_max")
    done = f"those T̄_l averages over ({e['lane_changes_aborted']} aborted"
    done += f"; {under_way} still under way at the end, not in T̄_l)" if under_way else ")"
    return ["\n## Efficiency I_e\n", "I_e = 0.5·(Q + e^(−T̄_l/3 s)), Q the density-speed term\n", _table([
        ("v̄", e["mean_speed_mps"], "m/s", "mean SUT speed"),
        ("h̄", e["mean_vehicles_in_view"], "count", "mean vehicles in the SUT's view"),
        ("H", e["max_vehicles_in_view"], "count", "most vehicles that fit in the view"),
        ("v_max", e["v_max_mps"], "m/s", "speed normaliser"),
        ("Q", e["density_speed_term"], "ratio", f"density-speed term, {form}"),
        ("T̄_l", e["mean_lane_change_time_s"], "s", "mean SUT lane-change time"
         + ("" if e["lane_change_time_defined"] else (" (no lane change: the configured default)"
                                                     if e.get("lane_change_term_used", True)
                                                     else " (no lane change: undefined, term left out of I_e)"))),
        ("SUT lane changes completed", e["lane_changes"], "count", done),
        ("e^(−T̄_l/3 s)", e["lane_change_term"], "ratio", "lane-change term"),
    ])]


def interaction_markdown(report: dict[str, Any]) -> list[str]:
    """report.md's "Interaction utility"."""
    i = report["interaction"]
    under_way = lane_changes_under_way(report)
    started = "lane changes the SUT started; the averages run over them"
    if under_way:
        started += f" ({under_way} still under way at the end)"
    return ["\n## Interaction utility I_i\n", "I_i = (1/3)·(2 − clip(|v~|)/Δv_max − clip(|a~|)/Δa_max + e^(−√L̄))\n",
            _table([
                ("SUT lane changes", i["sut_lane_changes"], "count", started),
                ("|v~|", i["speed_fluctuation_mps"], "m/s", "in-view BVs' mean |speed − speed at the change's start|"),
                ("|a~|", i["accel_fluctuation_mps2"], "m/s²", "same for acceleration"),
                ("L̄", i["bv_lane_changes"], "count", "mean lane changes of in-view BVs during the SUT's changes"),
                ("Δv_max, Δa_max", f"{i['dv_max_mps']:g}, {i['da_max_mps2']:g}", "m/s, m/s²", "normalisers"),
            ])]


def complexity_markdown(c: dict[str, Any]) -> list[str]:
    """report.md's "Complexity" (K: the scenario's, not the SUT's score)."""
    return ["\n## Complexity K (the scenario's)\n",
            "K = 0.4·(1 − e^(−E_w/k1)) + 0.3·(2 − e^(−LC/k2) − e^(−AD/k3))\n", _table([
                ("K", c["score"], "ratio", "complexity score"),
                ("LC", c["lane_changes"], "count", f"lane changes of all vehicles per {c['window_steps']}-state window"),
                ("AD", c["accel_decel"], "count", f"vehicle-states with |acceleration| > {c['accel_activity_mps2']:g} "
                 "m/s² per window" + (f" (acceleration averaged over the trailing {c['accel_activity_window_s']:g} s)"
                                      if c.get("accel_activity_form") == "smoothed" else "")),
                ("E_w", c["exposures"], "count", "the SUT's exposures per window"),
                ("windows", c["windows"], "count", "whole windows in the run"),
                ("k1, k2, k3", ", ".join(f"{k:g}" for k in c["k"]), "count per window", "constants"),
            ])]


def markdown(report: dict[str, Any], images: list[str], ev: EvaluationConfig | None = None) -> str:
    """``report.md``: D first, then the method's I, then each score's inputs as tables, then the plots
    (``ev``: the settings the run was scored under, for the exposure rules in words)."""
    r, s = report["run"], report["safety"]
    out = [f"# Evaluation: {r.get('scenario') or 'run'} (SUT {r.get('sut_model') or '?'}, seed {r.get('seed')})\n",
           f"{r['steps']} steps ({r['duration_s']:.1f} s simulated, dt {r['dt_s']:g} s), {r['bv_count']} BVs "
           f"({r.get('bv_driver') or '?'}), SUT id {r['sut_id']}; run {'complete' if r['complete'] else 'INCOMPLETE'}.\n",
           traffic_line(r)]
    for warning in report["warnings"]:
        out.append(f"> **warning:** {warning}\n")
    out += comparative_markdown(report) + intelligence_markdown(report) + safety_markdown(s, ev)
    if s.get("conflicts"):
        out += conflicts_markdown(s["conflicts"])
    if s["exposure_list"]:
        out += exposure_rows(s["exposure_list"])
    if "surrogate_safety" in report:
        out += surrogate_markdown(report["surrogate_safety"])
    out += efficiency_markdown(report) + interaction_markdown(report) + complexity_markdown(report["complexity"])
    if "traffic" in report:
        out += traffic_markdown(report["traffic"])
    if "challenge" in report:
        out += challenge_markdown(report["challenge"])
    if images:
        out.append("\n## Plots\n")
        out += [f"![{name.rsplit('.', 1)[0]}]({name})\n" for name in images]
    return "\n".join(out) + "\n"


def conflicts_markdown(cf: dict[str, Any]) -> list[str]:
    """report.md's "Conflicts on either side of the SUT": the ``safety.conflicts`` section as a table."""
    n_pet = len(cf["lane_change_pet"])
    return ["\n### Conflicts on either side of the SUT (docs/evaluation.md)\n", _table([
        ("rear conflicts", cf["rear_conflicts"], "–", f"which follower conflicts are the SUT's (window "
                                                       f"{cf['rear_attribution_s']:g} s after a SUT lane change)"),
        ("rear braking", cf.get("rear_braking", "any"), "–",
         (f"a follower's hard braking counts within {cf['rear_braking_headway_s']:g} s of headway"
          if cf.get("rear_braking") == "within_headway" else "a follower's hard braking counts at any distance")),
        ("rear conflict states", cf["rear_conflict_states"], "count",
         "follower in the path: TTC below threshold or hard brake"),
        ("... attributed", cf["rear_conflict_states_attributed"], "count", "of them in the attribution window (dangerous)"),
        ("cut-in states", cf.get("cut_in_states", 0), "count",
         (f"SUT changing lanes with its new follower within {cf['cut_in_gap_m']:g} m (dangerous)"
          if cf.get("cut_in_gap_m") else "not counted (cut_in_gap_m 0)")),
        ("min cut-in gap", cf.get("min_cut_in_gap_m"), "m", "new follower behind the SUT during its lane changes "
                                                             "(– = none)"),
        ("beside states", cf.get("beside_states", 0), "count",
         ("SUT changing lanes with a vehicle of its target lane beside it (dangerous)"
          if cf.get("beside_lane_change") else "not counted (beside_lane_change false)")),
        ("min beside gap", cf.get("min_beside_gap_m"), "m", "longitudinal gap to the target lane's nearest vehicle "
                                                             "during SUT lane changes; < 0 = beside (– = none)"),
        ("headway states", cf.get("headway_states", 0), "count",
         (f"SUT following its leader under {cf['headway_threshold_s']:g} s of time headway, not falling back "
          "(dangerous)" if cf.get("headway_threshold_s") else "not counted (headway_threshold_s 0)")),
        ("min follower TTC", cf["min_follower_ttc_s"], "s", "follower onto the SUT (– = never closing)"),
        ("max DRAC SUT", cf["max_drac_sut_mps2"], "m/s²", "SUT behind its leader (– = infinite)"),
        ("max DRAC follower", cf["max_drac_follower_mps2"], "m/s²", "follower behind the SUT (– = infinite)"),
        (f"DRAC > {cf['drac_threshold_mps2']:g} m/s² states", f"{cf['drac_sut_states']} / {cf['drac_follower_states']}",
         "count", "SUT / follower"),
        ("min lane-change PET", cf["min_pet_s"], "s", f"over {plural(n_pet, 'SUT lane change')}"),
    ])]


def surrogate_markdown(ss: dict[str, Any]) -> list[str]:
    """report.md's "Surrogate safety": per side of the SUT the counts and sums, and each per SUT-km."""
    f, r = ss["front"], ss["rear"]
    rows = [("ttc_episodes", f"TTC < {ss['ttc_threshold_s']:g} s episodes", "count (episodes)"),
            ("drac_episodes", f"DRAC > {ss['drac_threshold_mps2']:g} m/s² episodes", "count (episodes)"),
            ("pet_events", f"PET < {ss['pet_threshold_s']:g} s lane changes", "count (lane changes)"),
            ("tet_s", f"TET (TTC < {ss['ttc_threshold_s']:g} s)", "s"),
            ("tit_s2", "TIT", "s²")]
    out = ["\n## Surrogate safety\n",
           f"The SUT's conflicts on both sides over {ss['sut_km']:.3f} SUT-km (front: the SUT behind the vehicle "
           "ahead in its path; rear: the vehicle behind in its path behind the SUT, and for PET the new follower "
           "of each SUT lane change); an episode is a maximal run of states beyond the threshold with the same "
           "other vehicle (reported only: no score reads it). Per SUT-km: the unit per km.\n",
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
        windows += f", and a last partial one of {plural(tr['windows'][-1]['states'], 'state')}"
    tail = tr["tail_states_left_out"]
    if tail:
        windows += (f"; the last {'state' if tail == 1 else plural(tail, 'state')} (under half a window) "
                    f"{'is' if tail == 1 else 'are'} in the mean, not in a window")
    out = ["\n## Traffic around the SUT\n",
           f"BVs within {rng} of the SUT along the road (|s_BV − s_SUT| ≤ {rng}, any lane), counted in every "
           f"state and averaged per {tr['window_s']:g}-s window from the run's start (reported only: no score "
           "reads it).\n", _table([
               ("mean BVs", tr["mean_bvs"], "count", f"BVs within {rng}, mean over the run's states"),
               ("lowest window mean", tr["min_window_mean_bvs"], "count", "the emptiest window (– = no window)"),
               ("states with none", f"{tr['empty_states']} ({100.0 * tr['empty_share']:.1f} %)", "count (share)",
                f"states without a BV within {rng}"),
               ("windows", n_w, "count", windows),
           ])]
    if not n_w:
        return out
    if n_w <= TRAFFIC_TABLE_WINDOWS:
        out += ["\n| window (no.) | from t (s) | states (count) | mean BVs (count) |", "|---|---|---|---|"]
        out += [f"| {n} | {x['start_time_s']:.1f} | {x['states']}{' (partial)' if x['partial'] else ''} | "
                f"{_f(x['mean_bvs'], 3)} |" for n, x in enumerate(tr["windows"], 1)]
        out.append("")
    else:
        out.append(f"\nWindow means (count), in order{' (the last partial)' if tr['last_window_partial'] else ''}: "
                   + ", ".join(_f(m, 3) for m in tr["per_window_mean_bvs"]) + "\n")
    return out
