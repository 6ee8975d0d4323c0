"""Small statistics and table helpers shared by the experiments and the campaigns."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


def mean_ci(values: Sequence[float]) -> tuple[float, float]:
    """Mean and the half-width of its 95 % Student-t interval (``nan`` with fewer than 2 values)."""
    x = np.asarray([v for v in values if v is not None], dtype=float)
    if x.size == 0:
        return math.nan, math.nan
    if x.size < 2:
        return float(x.mean()), math.nan
    from scipy import stats

    half = float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return float(x.mean()), half


Z95 = 1.959963984540054
"""z_{0.975}: the half-width of a 95 % interval in standard errors."""


@dataclass(frozen=True)
class Rate:
    """A weighted ratio estimate: its value, the half-width of its 95 % interval, the episodes and the effective
    number of episodes."""

    value: float
    half: float
    n: int
    n_eff: float


def weighted_rate(y, x, w) -> Rate:
    """R = Σ w·y / Σ w·x and its 95 % half-width from the linearised variance n/(n−1) · Σ (w (y − R x))² / (Σ w x)²
    (the ratio estimator's, Cochran, *Sampling Techniques*, §6.4); w all 1: the plain ratio of sums."""
    y, x, w = (np.asarray(a, dtype=float) for a in (y, x, w))
    n = y.size
    if n < 2 or not (w * x).sum() > 0.0:
        raise ValueError("weighted_rate: needs two or more episodes with distance")
    sx = float((w * x).sum())
    r = float((w * y).sum()) / sx
    z = w * (y - r * x)
    var = n / (n - 1) * float((z * z).sum()) / sx**2
    n_eff = float(w.sum()) ** 2 / float((w * w).sum())
    return Rate(r, Z95 * math.sqrt(var), n, n_eff)


def mean_ci_weighted(values: Sequence[float | None], weights: Sequence[float]) -> tuple[float, float]:
    """The weighted mean Σ w·x / Σ w of the values that are not None (a run of the challenge scenario weighted
    by its likelihood ratio p/q: the naturalistic mean, docs/challenges.md) and the half-width of its 95 %
    interval by linearisation: :func:`weighted_rate` with every x = 1 (``nan`` with fewer than 2 values)."""
    pairs = [(float(v), float(w)) for v, w in zip(values, weights) if v is not None]
    if len(pairs) < 2 or not sum(w for _, w in pairs) > 0.0:
        return (pairs[0][0], math.nan) if len(pairs) == 1 else (math.nan, math.nan)
    y, w = zip(*pairs)
    r = weighted_rate(y, np.ones(len(y)), w)
    return r.value, r.half


def fmt_ci(mean: float, half: float, digits: int = 4) -> str:
    """``mean ± half`` (just the mean when the interval is undefined; – without a mean)."""
    if math.isnan(mean):
        return "–"
    return f"{mean:.{digits}f}" if math.isnan(half) else f"{mean:.{digits}f} ± {half:.{digits}f}"


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def difference_words(mean: float, half: float, n: int) -> str:
    """A paired difference ``a − b`` with its 95 % interval ``mean ± half`` over ``n`` pairs, in words:
    ``significantly higher`` (the whole interval above 0: a above b), ``significantly lower`` (below 0),
    ``no significant difference`` (the interval holds 0) or ``– (n < 2)`` (no interval)."""
    if n < 2 or not (math.isfinite(mean) and math.isfinite(half)):
        return "– (n < 2)" if n < 2 else "–"
    if mean - half > 0.0:
        return "significantly higher"
    if mean + half < 0.0:
        return "significantly lower"
    return "no significant difference"
