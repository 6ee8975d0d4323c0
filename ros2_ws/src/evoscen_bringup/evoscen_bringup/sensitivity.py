"""SUT mutation analysis: does a testing scenario tell an intact SUT from its mutants?

The yardstick of a testing scenario (docs/sensitivity.md): every mutant (a deliberately
degraded SUT, :mod:`evoscen_sut.mutants`) runs on the **same seeds** as its intact model —
common random numbers: the same initial traffic and the same random streams — and the
paired differences ``intact − mutant`` of every score are summarised per seed.

* **detected** — the 95 % Student-t interval of the paired intelligence difference lies
  above zero (the intact model scores higher, beyond noise);
* **seeds needed** — the smallest ``n`` from which on the interval over the first ``n``
  seeds (in seed order) lies above zero *for every larger prefix too* (a detection that
  comes and goes with the next seed is not counted before it settles); ``None`` when the
  mutant is not detected with all seeds;
* **mutation score** of a scenario — detected mutants / all mutants;
* **pairing** — the correlation over seeds of the intact and the mutant intelligence: how
  much the two runs of a seed share (1: the seed moves both alike, so the paired difference
  cancels the seed's luck; 0: pairing buys nothing over two independent samples). Reported
  per mutant and as the median per scenario (docs/sensitivity.md).

Pure functions over per-seed values (no simulation here); the experiment is
``scripts/experiment_sensitivity.py``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

SCORES = ("intelligence", "safety", "efficiency", "interaction")
"""The report's scores compared intact − mutant (each the unweighted ``score`` of its section,
``intelligence`` the total)."""


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
    """The score ``name`` (one of :data:`SCORES`) of a ``report.json`` dict; ``nan`` when the
    report leaves it undefined (``null``, docs/evaluation.md "Undefined score terms")."""
    if name not in SCORES:
        raise ValueError(f"score {name!r}: expected one of {', '.join(SCORES)}")
    value = report[name]["score"]
    return math.nan if value is None else float(value)
