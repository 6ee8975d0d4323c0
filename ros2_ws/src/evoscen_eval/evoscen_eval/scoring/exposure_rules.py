"""Why an exposure is one: the rule of docs/evaluation.md §2 that made each of its states
dangerous, the vehicle involved and the value that crossed the rule's threshold, and the
severity of a state as those rules measure it.

:func:`evoscen_sim.danger.safety.danger_terms` decides *whether* a state is dangerous, term by
term; this module says *which measure* of a term held (the hard-braking rule holds through the
DRAC to the leader or through the SUT's own braking; a rear conflict through the follower's TTC
or its braking) and keeps, per exposure and measure, the most extreme value with its state and
vehicle (:class:`ExposureRules`). The report lists them (``safety.exposure_list[i].rules``);
the worst-exposure snapshot, the clips and the gallery read the same entries.

Severity of a state (:func:`severity`, docs/evaluation.md §2.1): the largest ratio over the
measures that hold in it, each 1 at its threshold and 2 at twice the danger — threshold / value
for the TTCs, gaps and headways (2 at half the threshold), value / threshold for decelerations
and DRAC (2 at twice the threshold), and the overlap rule of the beside measure
(:func:`~evoscen_sim.danger.safety.beside_severity`: 1 as the bodies begin to overlap, 2 side by
side). A measure that does not hold adds nothing: hard braking without a conflict under
``hard_braking: conflict`` is no exposure, so it makes none more severe either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from evoscen_sim.danger.safety import DangerTerms, beside_severity

TTC_FLOOR_S = 1e-3
"""TTCs, gaps and headways below this enter the ratios at it (contact: TTC 0 gives 2 s / 1 ms = 2000)."""

RULES = ("front_ttc", "hard_braking", "rear", "cut_in", "beside", "tailgating")
"""The rules of docs/evaluation.md §2, in its order (items 1–6)."""

RULE_TEXT = {
    "front_ttc": "TTC ahead",
    "hard_braking": "hard braking",
    "rear": "rear conflict",
    "cut_in": "cut-in",
    "beside": "lane change beside",
    "tailgating": "tailgating",
}
"""A rule's name in words."""


@dataclass
class RuleInputs:
    """A block's per-state quantities the rules read (``[n]`` arrays; indices -1 for none)."""

    ttc: np.ndarray
    accel: np.ndarray
    drac_sut: np.ndarray
    leader: np.ndarray
    follower: np.ndarray
    follower_ttc: np.ndarray
    follower_accel: np.ndarray
    follower_thw: np.ndarray
    cut_in_vehicle: np.ndarray
    cut_in_gap: np.ndarray
    beside_vehicle: np.ndarray
    beside_gap: np.ndarray
    beside_length_sum: np.ndarray
    headway: np.ndarray


@dataclass(frozen=True)
class Measure:
    rule: str
    name: str
    unit: str
    comparison: str  # "<" or ">": dangerous when the value is below (above) the threshold
    extreme: str  # "min" or "max": the most dangerous value


MEASURES = (
    Measure("front_ttc", "TTC to the leader", "s", "<", "min"),
    Measure("hard_braking", "DRAC to the leader", "m/s²", ">", "max"),
    Measure("hard_braking", "SUT acceleration", "m/s²", "<", "min"),
    Measure("rear", "follower TTC", "s", "<", "min"),
    Measure("rear", "follower acceleration", "m/s²", "<", "min"),
    Measure("cut_in", "gap to the new follower", "m", "<", "min"),
    Measure("beside", "gap to the vehicle beside", "m", "<", "min"),
    Measure("tailgating", "time headway to the leader", "s", "<", "min"),
)
"""Each way a rule holds, with its value and direction."""


def measures(ev, terms: DangerTerms, q: RuleInputs) -> list[tuple[Measure, np.ndarray, np.ndarray, float,
                                                                   np.ndarray, np.ndarray]]:
    """Per measure: (measure, where it holds, its value, its threshold, its ratio, the vehicle's index)."""
    hb, thr = ev.hard_brake_mps2, ev.ttc_threshold_s
    conflict = ev.hard_braking == "conflict"
    needed = terms.braking & (q.drac_sut > hb) if conflict else np.zeros_like(terms.braking)
    own = terms.braking & (q.accel < -hb)
    if conflict:  # imposed: the follower within the headway must brake as hard (safety.hard_braking_dangerous)
        own = own & (q.follower_thw < ev.rear_braking_headway_s)
    rear_brake = terms.rear & (q.follower_accel < -hb)
    if ev.rear_braking == "within_headway":
        rear_brake = rear_brake & (q.follower_thw < ev.rear_braking_headway_s)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = [
            (MEASURES[0], terms.low_ttc, q.ttc, thr, thr / np.maximum(q.ttc, TTC_FLOOR_S), q.leader),
            # DRAC is infinite at contact while closing: capped where the TTC ratio is (TTC floored at 1 ms)
            (MEASURES[1], needed, q.drac_sut, hb, np.minimum(q.drac_sut / hb, thr / TTC_FLOOR_S), q.leader),
            (MEASURES[2], own, q.accel, -hb, -q.accel / hb, q.follower if conflict else np.full_like(q.leader, -1)),
            (MEASURES[3], terms.rear & (q.follower_ttc < thr), q.follower_ttc, thr,
             thr / np.maximum(q.follower_ttc, TTC_FLOOR_S), q.follower),
            (MEASURES[4], rear_brake, q.follower_accel, -hb, -q.follower_accel / hb, q.follower),
            (MEASURES[5], terms.cut_in, q.cut_in_gap, ev.cut_in_gap_m,
             ev.cut_in_gap_m / np.maximum(q.cut_in_gap, TTC_FLOOR_S), q.cut_in_vehicle),
            (MEASURES[6], terms.beside, q.beside_gap, 0.0, beside_severity(q.beside_gap, q.beside_length_sum),
             q.beside_vehicle),
            (MEASURES[7], terms.tailgating, q.headway, ev.headway_threshold_s,
             ev.headway_threshold_s / np.maximum(q.headway, TTC_FLOOR_S), q.leader),
        ]
    return out


def severity(ev, terms: DangerTerms, q: RuleInputs) -> np.ndarray:
    """Per state the largest ratio of the measures that hold in it (module docstring); 0 where none does."""
    sev = np.zeros(np.shape(terms.danger), dtype=np.float64)
    for _m, holds, _v, _t, ratio, _j in measures(ev, terms, q):
        if holds.any():
            sev = np.where(holds, np.maximum(sev, np.nan_to_num(ratio, nan=0.0, posinf=0.0)), sev)
    return sev


class ExposureRules:
    """One exposure's rules: per rule its dangerous states, per measure its most extreme value."""

    def __init__(self) -> None:
        self.rule_states = {rule: 0 for rule in RULES}
        self._best: dict[int, dict[str, Any]] = {}

    def add(self, seg: slice, k0: int, times: np.ndarray, ev, terms: DangerTerms, q: RuleInputs,
            ids: np.ndarray) -> None:
        """The states ``seg`` of a block whose first state is ``k0`` (all in this exposure)."""
        for rule, term in (("front_ttc", terms.low_ttc), ("hard_braking", terms.braking), ("rear", terms.rear),
                           ("cut_in", terms.cut_in), ("beside", terms.beside), ("tailgating", terms.tailgating)):
            self.rule_states[rule] += int(np.asarray(term)[seg].sum())
        for n, (m, holds, value, threshold, _ratio, vehicle) in enumerate(measures(ev, terms, q)):
            h = np.flatnonzero(holds[seg])
            if not h.size:
                continue
            vals = value[seg][h]
            i = int(h[int(np.argmin(vals) if m.extreme == "min" else np.argmax(vals))])
            v = float(value[seg][i])
            best = self._best.get(n)
            if best is not None:
                best["states"] += int(h.size)
                if not (v < best["_v"] if m.extreme == "min" else v > best["_v"]):
                    continue
            else:
                best = self._best[n] = {"states": int(h.size)}
            j = int(vehicle[seg][i])
            r = seg.start + i
            best.update(_v=v, rule=m.rule, measure=m.name, value=v if math.isfinite(v) else None, unit=m.unit,
                        comparison=m.comparison, threshold=float(threshold),
                        vehicle_id=int(ids[j]) if j >= 0 else None, state=k0 + r, time_s=float(times[r]))

    def records(self) -> list[dict[str, Any]]:
        """The exposure's ``rules`` list: one entry per measure that held, in :data:`MEASURES` order."""
        out = []
        for n in sorted(self._best):
            b = self._best[n]
            out.append({key: b[key] for key in ("rule", "measure", "states", "value", "unit", "comparison",
                                                "threshold", "vehicle_id", "state", "time_s")})
        return out


def rule_text(record: dict[str, Any]) -> str:
    """One measure of an exposure in words, e.g. ``cut-in: gap to the new follower 7.05 m < 10 m (vehicle 12)``."""
    value = "contact" if record["value"] is None else f"{record['value']:.3g} {record['unit']}"
    who = "" if record.get("vehicle_id") is None else f" (vehicle {record['vehicle_id']})"
    return (f"{RULE_TEXT[record['rule']]}: {record['measure']} {value} {record['comparison']} "
            f"{record['threshold']:g} {record['unit']}{who}")


def involved(exposure: dict[str, Any]) -> list[int]:
    """The vehicles an exposure's rules name (the SUT's counterparts), in the order of its rules."""
    return list(dict.fromkeys(r["vehicle_id"] for r in exposure.get("rules", []) if r.get("vehicle_id") is not None))


def ttc_text(ttc_s: float | None) -> str:
    """An exposure's lowest TTC ahead as every report prints it: 4 significant digits, ``–`` for none."""
    return "–" if ttc_s is None else f"{ttc_s:.4g}"


def rules_summary(exposure: dict[str, Any]) -> str:
    """An exposure's rules in one line (``; ``-separated), or ``–`` for a report without them."""
    rules = exposure.get("rules")
    return "; ".join(rule_text(r) for r in rules) if rules else "–"


def definition(ev) -> list[str]:
    """The rules in force under the evaluation settings ``ev``, each in words (docs/evaluation.md §2)."""
    hb, thr = ev.hard_brake_mps2, ev.ttc_threshold_s
    out = [f"TTC ahead: the SUT's TTC to the leader in its path < {thr:g} s"]
    if ev.hard_braking == "conflict":
        out.append(f"hard braking: the SUT's DRAC to its leader > {hb:g} m/s², or the SUT braking below −{hb:g} m/s² "
                   f"with its follower within {ev.rear_braking_headway_s:g} s of headway")
    else:
        out.append(f"hard braking: the SUT's acceleration < −{hb:g} m/s²")
    if ev.rear_conflicts != "none":
        when = ("from a SUT lane change until " + f"{ev.rear_attribution_s:g} s after it"
                if ev.rear_conflicts == "after_lane_change" else "at any time")
        brake = (f" within {ev.rear_braking_headway_s:g} s of headway" if ev.rear_braking == "within_headway" else "")
        out.append(f"rear conflict ({when}): the follower's TTC < {thr:g} s, or it brakes below −{hb:g} m/s²{brake}")
    if ev.cut_in_gap_m > 0:
        out.append(f"cut-in: the SUT changing lanes with its new follower closer than {ev.cut_in_gap_m:g} m")
    if ev.beside_lane_change:
        out.append("lane change beside: the SUT changing lanes with a vehicle of its target lane overlapping it")
    if ev.headway_threshold_s > 0:
        out.append(f"tailgating: time headway to the leader < {ev.headway_threshold_s:g} s, not falling back, "
                   f"for more than {ev.headway_grace_s:g} s")
    return out
