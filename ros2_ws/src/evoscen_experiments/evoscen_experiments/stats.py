"""Small statistics and table helpers shared by the experiments and the campaigns."""

from __future__ import annotations

import math
from collections.abc import Sequence

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


def mean_ci_weighted(values: Sequence[float | None], weights: Sequence[float]) -> tuple[float, float]:
    """The weighted mean Σ w·x / Σ w of the values that are not None (a run of the challenge scenario weighted
    by its likelihood ratio p/q: the naturalistic mean, docs/challenges.md) and the half-width of its 95 %
    interval by linearisation, 1.96 · √(n/(n−1) · Σ (w (x − m))² / (Σ w)²) (``nan`` with fewer than 2 values)."""
    pairs = [(float(v), float(w)) for v, w in zip(values, weights) if v is not None]
    if not pairs:
        return math.nan, math.nan
    x, w = (np.array(c) for c in zip(*pairs))
    m = float((w * x).sum() / w.sum())
    if x.size < 2:
        return m, math.nan
    z = w * (x - m)
    return m, 1.959963984540054 * math.sqrt(x.size / (x.size - 1) * float((z * z).sum()) / float(w.sum()) ** 2)


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
