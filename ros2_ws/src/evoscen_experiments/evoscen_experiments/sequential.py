"""Sequential paired verdicts: a comparison looked at after every round of paired episodes, stopped at
its verdict, with the error rates kept over all the looks (docs/sensitivity.md, "Sequential verdicts").

A comparison of A and B (intact and mutant, two SUTs) is a stream of paired differences
d_i = score(A, episode i) − score(B, episode i). It is looked at after every ``round_size`` episodes, up
to ``budget``; at look k the *repeated confidence interval* (RCI) is mean_k ± c_k · sd_k / √n_k, and the
verdict is the first of

* ``a_higher`` (for intact − mutant: the mutant is *worse*): the RCI lies above 0;
* ``b_higher`` (the mutant is *better*): it lies below 0;
* ``equivalent``: it lies inside (−δ, +δ);
* ``unresolved``: none of them by the budget's last look.

[choice] Group-sequential boundaries c_k from an alpha-spending function (Lan & DeMets, Biometrika 70,
659–663, 1983) — O'Brien–Fleming's shape by default (wide early, close to the fixed-sample 1.96 at the
budget), Pocock's selectable — and repeated confidence intervals built on them (Jennison & Turnbull,
*Group Sequential Methods with Applications to Clinical Trials*, 2000, ch. 9): the RCIs cover the true
mean at every look at once with probability 1 − α, so each verdict above is wrong with probability at
most α however many looks were taken (checked by simulation, tests/test_sequential.py). Chosen over
anytime-valid confidence sequences because the looks are known in advance (rounds up to a budget),
which buys narrower intervals at the budget. c_k is found by numerical integration of the Brownian
motion W(t) = S_n / (σ √N) at the looks' information fractions t_k = n_k / N (Armitage, McPherson & Rowe,
JRSS A 132, 235–244, 1969), on a grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

SPENDING = ("obrien_fleming", "pocock")
VERDICTS = ("a_higher", "b_higher", "equivalent", "unresolved")


def spent(t: float, alpha: float, spending: str = "obrien_fleming") -> float:
    """The two-sided alpha spent by information fraction ``t`` (0 < t ≤ 1): Lan–DeMets' O'Brien–Fleming
    type 2 − 2Φ(z_{1−α/2} / √t), or Pocock's type α · ln(1 + (e − 1) t)."""
    from scipy.stats import norm

    if spending == "obrien_fleming":
        return float(2.0 - 2.0 * norm.cdf(norm.ppf(1.0 - alpha / 2.0) / math.sqrt(t)))
    if spending == "pocock":
        return float(alpha * math.log(1.0 + (math.e - 1.0) * t))
    raise ValueError(f"spending {spending!r}: expected one of {', '.join(SPENDING)}")


@lru_cache(maxsize=64)
def boundaries(fractions: tuple[float, ...], alpha: float = 0.05, spending: str = "obrien_fleming",
               points: int = 1201) -> tuple[float, ...]:
    """The two-sided z-scale boundaries c_k of looks at information fractions ``fractions`` (increasing,
    the last 1): under H0 (mean 0), P(|Z_j| < c_j for j < k and |Z_k| ≥ c_k) = spent(t_k) − spent(t_{k−1}).

    The continuing density of W(t_{k−1}) is kept on a grid; the crossing probability at look k is its
    integral against the normal tails beyond ±b (exact in b), solved for the alpha to spend."""
    from scipy.optimize import brentq
    from scipy.stats import norm

    t = np.asarray(fractions, dtype=float)
    if t.size == 0 or np.any(np.diff(t) <= 0) or t[0] <= 0 or abs(t[-1] - 1.0) > 1e-12:
        raise ValueError(f"fractions {fractions}: expected increasing values in (0, 1] ending at 1")
    w = np.linspace(-9.0, 9.0, points)  # W(t) for t <= 1: |W| > 9 has probability < 1e-18
    dw = w[1] - w[0]
    out, spent_before, density = [], 0.0, None
    for k, tk in enumerate(t):
        target = spent(float(tk), alpha, spending) - spent_before
        if density is None:  # the first look: W(t_1) ~ N(0, t_1)
            def cross(b: float, sd: float = math.sqrt(tk)) -> float:
                return float(2.0 * norm.sf(b / sd))
        else:
            s = math.sqrt(tk - t[k - 1])
            mass = density * dw

            def cross(b: float, s: float = s, mass: np.ndarray = mass) -> float:
                return float(np.sum(mass * (norm.cdf((-b - w) / s) + norm.sf((b - w) / s))))
        b = brentq(lambda x, goal=target: cross(x) - goal, 1e-9, 9.0, xtol=1e-10) if cross(9.0) < target < cross(1e-9) else 9.0
        out.append(b / math.sqrt(tk))
        spent_before += cross(b)
        inside = np.abs(w) < b
        if density is None:
            density = np.where(inside, norm.pdf(w, scale=math.sqrt(tk)), 0.0)
        else:
            kernel = norm.pdf((w[:, None] - w[None, :]) / s) / s
            density = np.where(inside, kernel @ (density * dw), 0.0)
    return tuple(out)


@dataclass(frozen=True)
class Verdict:
    """A sequential comparison's outcome: the verdict, the episodes it used, and the repeated confidence
    interval of the mean difference at its last look."""

    verdict: str
    """One of :data:`VERDICTS`, or ``"continue"`` when fewer than the budget's episodes were given and no
    verdict was reached yet."""
    episodes: int
    mean: float
    low: float
    high: float
    looks: int


def looks_of(round_size: int, budget: int) -> tuple[int, ...]:
    """The episodes at each look: every ``round_size`` up to ``budget`` (the last look at the budget)."""
    if round_size < 2 or budget < round_size:
        raise ValueError(f"round_size {round_size}, budget {budget}: expected 2 <= round_size <= budget")
    n = list(range(round_size, budget + 1, round_size))
    if n[-1] != budget:
        n.append(budget)
    return tuple(n)


def verdict(diffs, *, round_size: int, budget: int, delta: float, alpha: float = 0.05,
            spending: str = "obrien_fleming") -> Verdict:
    """The verdict on paired differences ``diffs`` (in episode order), looked at every ``round_size``
    episodes up to ``budget``, with equivalence margin ``delta``: the first look with a verdict decides."""
    d = np.asarray(diffs, dtype=float)
    n_looks = looks_of(round_size, budget)
    c = boundaries(tuple(n / budget for n in n_looks), alpha, spending)
    last = None
    for k, n in enumerate(n_looks):
        if n > d.size:
            break
        x = d[:n]
        mean, sd = float(x.mean()), float(x.std(ddof=1))
        half = c[k] * sd / math.sqrt(n)
        last = Verdict("continue", n, mean, mean - half, mean + half, k + 1)
        if mean - half > 0:
            return Verdict("a_higher", n, mean, mean - half, mean + half, k + 1)
        if mean + half < 0:
            return Verdict("b_higher", n, mean, mean - half, mean + half, k + 1)
        if -delta < mean - half and mean + half < delta:
            return Verdict("equivalent", n, mean, mean - half, mean + half, k + 1)
    if last is None:
        return Verdict("continue", 0, math.nan, -math.inf, math.inf, 0)
    if last.episodes == budget:
        return Verdict("unresolved", last.episodes, last.mean, last.low, last.high, last.looks)
    return last
