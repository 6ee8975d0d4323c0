"""SUT mutation analysis: does a testing scenario tell an intact SUT from its mutants?

The yardstick of a testing scenario (docs/sensitivity.md): every mutant (a deliberately
degraded SUT, :mod:`evoscen_sut.mutants`) runs on the **same seeds** as its intact model —
common random numbers: the same initial traffic and the same random streams — and the
paired differences ``intact − mutant`` of every score are summarised per seed.

* **detected** — the 95 % Student-t interval of the paired difference of the compared score (D by default) lies
  above zero (the intact model scores higher, beyond noise);
* **seeds needed** — the smallest ``n`` from which on the interval over the first ``n``
  seeds (in seed order) lies above zero *for every larger prefix too* (a detection that
  comes and goes with the next seed is not counted before it settles); ``None`` when the
  mutant is not detected with all seeds;
* **mutation score** of a scenario — detected mutants / all mutants, the *profiles* (:data:`PROFILES`:
  a reference way of driving, not a defect) left out of both;
* **pairing** — the correlation over seeds of the intact and the mutant score: how
  much the two runs of a seed share (1: the seed moves both alike, so the paired difference
  cancels the seed's luck; 0: pairing buys nothing over two independent samples). Reported
  per mutant and as the median per scenario (docs/sensitivity.md).

Test designs (docs/sensitivity.md "Two designs"): ``long`` — a few seeds of long runs (the
method's 3,000 steps) — and ``episodes`` — many short runs, each its own seed (its initial
state after the warm-up and its random streams), intact and mutants paired per episode.
:class:`Design` holds one, :func:`design_compute` its simulated steps (equal compute = the
same SUT steps per variant), :func:`summarise_design` a scenario's detection under it and
:func:`sharper_design` the comparison's verdict.

Pure functions over per-seed values (no simulation here); the experiment is
:mod:`evoscen_experiments.sensitivity_experiment`.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

PROFILES = ("frozen",)
"""Mutants of the library that are reference profiles, not defects (docs/sensitivity.md "Profiles"): run and
reported like the others, never counted among detected mutants, in a mutation score or a verdict count."""

SCORES = ("intelligence", "safety", "efficiency", "interaction")
"""The report's scores compared intact − mutant, as ``evaluation.score_form`` selects them
(:func:`evoscen_eval.scoring.metrics.compared_scores`): the comparative score D, its safety S, progress P
and interaction X [default], or the method's I, I_s, I_e, I_i (each the unweighted ``score`` of
its section, ``intelligence`` the total)."""

COLUMNS = {"intelligence": "d", "safety": "s", "efficiency": "p", "interaction": "x"}
"""Each of :data:`SCORES` in the experiment's CSV columns, named by the comparative score's letters (D, S, P,
X; under ``evaluation.score_form: method`` the same columns hold I, I_s, I_e, I_i)."""


def symbols(report: Mapping | None) -> dict[str, str]:
    """Each of :data:`SCORES` as the tables write it: D, S, P, X (``evaluation.score_form: comparative``, the
    default) or the method's I, I_s, I_e, I_i (``method``), after the report's settings."""
    form = ((report or {}).get("settings") or {}).get("score_form", "method")
    letters = ("D", "S", "P", "X") if form == "comparative" else ("I", "I_s", "I_e", "I_i")
    return dict(zip(SCORES, letters))


@dataclass(frozen=True)
class Paired:
    """A paired difference over seeds: mean, 95 % half-width, seeds."""

    mean: float
    half: float
    n: int

    @property
    def low(self) -> float:
        """Lower end of the 95 % interval (``nan`` with fewer than 2 seeds)."""
        return self.mean - self.half

    @property
    def above_zero(self) -> bool:
        """The whole 95 % interval lies above zero."""
        return self.n >= 2 and math.isfinite(self.half) and self.low > 0.0


def t_half_width(x: np.ndarray) -> float:
    """Half-width of the 95 % Student-t interval of the mean of ``x`` (``nan`` below 2 values)."""
    x = np.asarray(x, dtype=float)
    if x.size < 2:
        return math.nan
    from scipy import stats

    return float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))


def _shared(intact: Mapping[int, float], mutant: Mapping[int, float]) -> np.ndarray:
    """``intact − mutant`` over the seeds (sorted) where both values are defined (finite)."""
    seeds = sorted(set(intact) & set(mutant))
    d = np.array([intact[s] - mutant[s] for s in seeds], dtype=float)
    return d[np.isfinite(d)]


def paired(intact: Mapping[int, float], mutant: Mapping[int, float]) -> Paired:
    """``intact − mutant`` over the seeds both have and where both are defined (seed → value maps;
    an undefined score — e.g. I_i of a run without SUT lane changes — is ``nan``)."""
    d = _shared(intact, mutant)
    if d.size == 0:
        return Paired(math.nan, math.nan, 0)
    return Paired(float(d.mean()), t_half_width(d), int(d.size))


def seeds_needed(intact: Mapping[int, float], mutant: Mapping[int, float]) -> int | None:
    """The smallest ``n`` such that every prefix of ``m >= n`` shared seeds (seed order) is detected.

    ``None`` when the full set is not detected.
    """
    d = _shared(intact, mutant)
    needed = None
    for m in range(d.size, 1, -1):  # walk back from the full set while detection holds
        half = t_half_width(d[:m])
        if math.isfinite(half) and d[:m].mean() - half > 0.0:
            needed = m
        else:
            break
    return needed


def pairing(intact: Mapping[int, float], mutant: Mapping[int, float]) -> float:
    """Pearson correlation over the seeds both have and where both are defined (finite) of the intact
    and the mutant values; ``nan`` below 3 such seeds or when either side does not vary."""
    seeds = sorted(set(intact) & set(mutant))
    a = np.array([intact[s] for s in seeds], dtype=float)
    b = np.array([mutant[s] for s in seeds], dtype=float)
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    if a.size < 3 or a.std() == 0.0 or b.std() == 0.0:
        return math.nan
    return float(np.corrcoef(a, b)[0, 1])


def mutation_score(detected: Sequence[bool]) -> float:
    """Detected mutants / all mutants (``nan`` without mutants)."""
    return float(np.mean(detected)) if len(detected) else math.nan


def score_of(report: Mapping, name: str) -> float:
    """The score ``name`` (one of :data:`SCORES`, in the form the report's ``evaluation.score_form``
    selects) of a ``report.json`` dict; ``nan`` when the report leaves it undefined (``null``, docs/evaluation.md "Undefined score terms")."""
    if name not in SCORES:
        raise ValueError(f"score {name!r}: expected one of {', '.join(SCORES)}")
    from evoscen_eval.scoring.metrics import compared_scores

    value = compared_scores(report)[name]
    return math.nan if value is None else float(value)


SSM_RATES = (("front", "ttc_episodes"), ("rear", "ttc_episodes"), ("front", "drac_episodes"),
             ("rear", "drac_episodes"), ("rear", "pet_events"), ("front", "tet_s"), ("rear", "tet_s"),
             ("front", "tit_s2"), ("rear", "tit_s2"))
"""The surrogate-safety rates per SUT-km the experiments compare (side, measure of the report's
``surrogate_safety``; docs/evaluation.md "Surrogate safety"; the front has no PET)."""


def ssm_rate(report: Mapping, side: str, measure: str) -> float:
    """A surrogate-safety rate per SUT-km of a ``report.json`` dict; ``nan`` where the report has
    none (a report from before the section, or a run of 0 km)."""
    value = (((report.get("surrogate_safety") or {}).get(side) or {}).get("per_km") or {}).get(measure)
    return math.nan if value is None else float(value)


def ssm_label(side: str, measure: str, report: Mapping | None = None) -> str:
    """A column name for a rate: ``TTC<3 front /km`` (thresholds from ``report``, else SUMO SSM's defaults)."""
    ss = (report or {}).get("surrogate_safety") or {}
    ttc, drac, pet = (f"{ss.get(k, d):g}" for k, d in (("ttc_threshold_s", 3.0), ("drac_threshold_mps2", 3.0),
                                                        ("pet_threshold_s", 2.0)))
    name = {"ttc_episodes": f"TTC<{ttc} s", "drac_episodes": f"DRAC>{drac}", "pet_events": f"PET<{pet} s",
            "tet_s": "TET (s)", "tit_s2": "TIT (s²)"}[measure]
    return f"{name} {side} /km"


DESIGNS = ("episodes", "long")
"""The test designs: ``episodes`` (N short runs of T steps) and ``long`` (seeds × long runs)."""


@dataclass(frozen=True)
class Design:
    """A test design: ``runs`` runs (seeds ``first_seed`` ..) of ``steps`` steps per SUT variant and scenario."""

    name: str
    runs: int
    steps: int
    first_seed: int
    blocks: tuple[tuple[int, int], ...] = ()
    """Seed blocks (first, last), both ends included, disjoint (docs/sensitivity.md "Seed blocks"); empty:
    one block, ``first_seed`` .. ``first_seed + runs − 1``. With blocks, ``runs`` is their total and
    ``first_seed`` the first block's first seed (:func:`blocked_design`)."""

    @property
    def seeds(self) -> Sequence[int]:
        """The seeds of the runs (one per run: an episode's or a long run's), block after block."""
        if not self.blocks:
            return range(self.first_seed, self.first_seed + self.runs)
        return [s for first, last in self.blocks for s in range(first, last + 1)]

    @property
    def block_bounds(self) -> tuple[tuple[int, int], ...]:
        """The seed blocks (first, last); one block without explicit blocks."""
        return self.blocks or ((self.first_seed, self.first_seed + self.runs - 1),)

    @property
    def unit(self) -> str:
        """What one run is called: ``episode`` or ``seed``."""
        return "episode" if self.name == "episodes" else "seed"


def blocked_design(name: str, steps: int, blocks: Sequence[tuple[int, int]]) -> Design:
    """A design over seed blocks (first, last): ``runs`` = the seeds of all blocks."""
    blocks = tuple((int(a), int(b)) for a, b in blocks)
    return Design(name, sum(b - a + 1 for a, b in blocks), steps, blocks[0][0], blocks)


@dataclass(frozen=True)
class Compute:
    """Simulated steps of a design per SUT variant and scenario."""

    sut_steps: int
    """Steps the SUT drives and is scored on (runs × steps): what equal compute equalises."""
    warmup_steps: int
    """Warm-up steps before the runs (runs × warm-up steps per run): extra compute."""

    @property
    def total(self) -> int:
        """All simulated steps, warm-ups included."""
        return self.sut_steps + self.warmup_steps


def design_compute(design: Design, warmup_steps_per_run: int) -> Compute:
    """The simulated steps of ``design`` per variant and scenario, with ``warmup_steps_per_run``
    (``traffic.warmup_s / dt_s``; 0 without a window) before every run."""
    return Compute(design.runs * design.steps, design.runs * warmup_steps_per_run)


def _median(values: Sequence[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return statistics.median(finite) if finite else math.nan


@dataclass(frozen=True)
class DesignSummary:
    """One scenario's detection under one design (the compared score, D by default, paired per seed)."""

    per_mutant: dict[str, Paired]
    """``intact − mutant`` of the compared score (D by default) per mutant, profiles too: mean, 95 %
    half-width, n."""
    pairing_r: dict[str, float]
    """Pairing r per mutant (:func:`pairing`)."""

    @property
    def defects(self) -> dict[str, Paired]:
        """:attr:`per_mutant` without the profiles (:data:`PROFILES`): what the counts below count."""
        return {m: p for m, p in self.per_mutant.items() if m not in PROFILES}

    @property
    def detected(self) -> int:
        """Defects (profiles left out) whose interval lies above zero."""
        return sum(p.above_zero for p in self.defects.values())

    @property
    def mutants(self) -> int:
        """Defects (profiles left out)."""
        return len(self.defects)

    @property
    def score(self) -> float:
        """The mutation score, detected / all defects."""
        return mutation_score([p.above_zero for p in self.defects.values()])

    @property
    def median_half(self) -> float:
        """Median over the defects of the 95 % half-width (undefined ones left out; ``nan`` if none)."""
        return _median([p.half for p in self.defects.values()])

    @property
    def median_r(self) -> float:
        """Median over the defects of the pairing r (undefined ones left out; ``nan`` if none)."""
        return _median([r for m, r in self.pairing_r.items() if m not in PROFILES])


def summarise_design(intact: Mapping[int, float], mutants: Mapping[str, Mapping[int, float]]) -> DesignSummary:
    """A scenario's detection from per-seed compared scores: ``intact`` (seed → D) and each
    mutant's (name → seed → D), paired per seed (:func:`paired`, :func:`pairing`)."""
    return DesignSummary({m: paired(intact, v) for m, v in mutants.items()},
                         {m: pairing(intact, v) for m, v in mutants.items()})


def sharper_design(summaries: Mapping[str, Sequence[DesignSummary]]) -> str | None:
    """The sharper of the designs (name → its summaries, one per scenario and base SUT): the one that
    detects more mutants over all of them; on a tie the one whose median half-width over every (scenario,
    mutant) is narrower. None when they tie on both (or a half-width is undefined)."""
    detected = {name: sum(s.detected for s in sums) for name, sums in summaries.items()}
    best = max(detected.values())
    leaders = [name for name, k in detected.items() if k == best]
    if len(leaders) == 1:
        return leaders[0]
    halves = {name: _median([p.half for s in summaries[name] for p in s.defects.values()]) for name in leaders}
    if any(math.isnan(h) for h in halves.values()):
        return None
    narrowest = min(halves.values())
    leaders = [name for name, h in halves.items() if h == narrowest]
    return leaders[0] if len(leaders) == 1 else None
