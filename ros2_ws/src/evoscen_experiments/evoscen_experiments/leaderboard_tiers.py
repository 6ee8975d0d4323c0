"""The leaderboard in tiers (docs/experiments.md §4): a verdict for every pair of SUTs, letters and rank ranges.

Every pair (a ranked above b) gets :func:`evoscen_experiments.sequential.verdict` on a − b of D paired by
episode (seeds in order) at one look over the shared episodes, where its boundary is z_{0.975} = 1.96:
``a_higher`` or ``b_higher`` when the interval excludes 0 (the pair is *resolved*), ``equivalent`` inside ±δ,
else ``unresolved``, with the episodes an unresolved pair would need (:func:`episodes_needed`). The same per
seed block, side by side; a pair resolved one way in one block and the other way in another is a
*contradiction*.

SUTs that no resolved pair separates share a tier. As verdicts need not chain (a ≈ b, b ≈ c, a > c), the
tiers are shown as a **compact letter display** — two SUTs share a letter unless their pair is resolved —
built by the insert-and-absorb algorithm with its sweep (H.-P. Piepho, "An algorithm for a letter-based
representation of all-pairwise comparisons", J. Comput. Graph. Stat. 13(2), 456–466, 2004;
:func:`letters`), and as **rank ranges**: the best rank a SUT can take given the resolved pairs is 1 + the SUTs
resolved above it, the worst the number of SUTs − those resolved below it (:func:`rank_ranges`).
"""

from __future__ import annotations

import math
import string
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from evoscen_experiments.sequential import Verdict, verdict

DELTA = 0.005
"""The equivalence margin of D (the sensitivity experiment's ``--delta`` default)."""
Z_975, Z_80 = 1.959963984540054, 0.8416212335729143
"""z_{0.975} (two-sided 5 %) and z_{0.8} (80 % power) of :func:`episodes_needed`."""
WORDS = {"a_higher": "a > b", "b_higher": "a < b", "equivalent": "a ≈ b", "unresolved": "unresolved",
         "continue": "unresolved"}
RESOLVED = ("a_higher", "b_higher")


def diffs_of(va: Mapping[int, float], vb: Mapping[int, float], seeds=None) -> list[float]:
    """a − b over the seeds (sorted; ``seeds``: only those) where both are defined (finite)."""
    shared = sorted(set(va) & set(vb) if seeds is None else set(va) & set(vb) & set(seeds))
    d = [va[s] - vb[s] for s in shared]
    return [x for x in d if math.isfinite(x)]


def judge(diffs: Sequence[float], delta: float = DELTA) -> Verdict:
    """The verdict on paired differences at one look over all of them (unresolved below 2)."""
    n = len(diffs)
    if n < 2:
        mean = diffs[0] if n else math.nan
        return Verdict("unresolved", n, mean, -math.inf, math.inf, 0)
    return verdict(diffs, round_size=n, budget=n, delta=delta)


def episodes_needed(diffs: Sequence[float]) -> int | None:
    """The paired episodes at which a true difference equal to the observed mean would be resolved with 80 %
    power at two-sided 5 %: ⌈((z_{0.975} + z_{0.8}) · sd / |mean|)²⌉ (the fixed-sample normal
    approximation); None below 2 differences or at mean 0."""
    n = len(diffs)
    if n < 2:
        return None
    mean = sum(diffs) / n
    sd = math.sqrt(sum((x - mean) ** 2 for x in diffs) / (n - 1))
    if mean == 0 or not math.isfinite(sd):
        return None
    return math.ceil(((Z_975 + Z_80) * sd / abs(mean)) ** 2)


@dataclass(frozen=True)
class PairResult:
    """One pair (a ranked above b): the verdict over all episodes, the episodes needed where unresolved,
    and the verdict per seed block."""

    a: str
    b: str
    verdict: Verdict
    needed: int | None
    blocks: tuple[str, ...] = ()

    @property
    def contradiction(self) -> bool:
        """Resolved one way in one block and the other way in another."""
        return "a_higher" in self.blocks and "b_higher" in self.blocks


def pair_results(values: Mapping[str, Mapping[int, float]], order: Sequence[str], blocks: Sequence = (),
                 delta: float = DELTA) -> list[PairResult]:
    """Every pair of ``order`` (SUT -> seed -> D in ``values``), a ranked above b, with its verdicts."""
    out = []
    for i, a in enumerate(order):
        for b in order[i + 1:]:
            d = diffs_of(values[a], values[b])
            v = judge(d, delta)
            per_block = tuple(judge(diffs_of(values[a], values[b], blk.seeds), delta).verdict for blk in blocks)
            out.append(PairResult(a, b, v, episodes_needed(d) if v.verdict == "unresolved" else None,
                                  per_block if len(blocks) > 1 else ()))
    return out


def above_of(pairs: Sequence[PairResult]) -> set[tuple[str, str]]:
    """The resolved pairs as (higher, lower)."""
    return {(p.a, p.b) if p.verdict.verdict == "a_higher" else (p.b, p.a)
            for p in pairs if p.verdict.verdict in RESOLVED}


def rank_ranges(order: Sequence[str], above: set[tuple[str, str]]) -> dict[str, tuple[int, int]]:
    """SUT -> (best, worst) rank given the resolved pairs ``above`` ((higher, lower)): best = 1 + the SUTs
    resolved above it, worst = the number of SUTs − those resolved below it."""
    n = len(order)
    return {s: (1 + sum(1 for h, lo in above if lo == s), n - sum(1 for h, lo in above if h == s)) for s in order}


def _letter(k: int) -> str:
    alphabet = string.ascii_lowercase
    return alphabet[k] if k < len(alphabet) else alphabet[k % len(alphabet)] + str(k // len(alphabet))


def letters(order: Sequence[str], above: set[tuple[str, str]]) -> dict[str, str]:
    """SUT -> its letters (Piepho 2004): two SUTs share a letter exactly when their pair is not resolved.

    Insert: start with one column holding every SUT; for each resolved pair, every column holding both is
    split into a copy without the one and a copy without the other. Absorb: a column contained in another is
    dropped. Sweep: a SUT leaves a column when every other SUT in it shares another column with it (and it
    keeps one). Letters go to the columns in the order of their best-ranked SUT, so the top SUT gets ``a``."""
    rank = {s: i for i, s in enumerate(order)}
    cols: list[frozenset[str]] = [frozenset(order)] if order else []
    for i, x in enumerate(order):
        for y in order[i + 1:]:
            if (x, y) not in above and (y, x) not in above:
                continue
            new: list[frozenset[str]] = []
            for c in cols:
                new += [c - {x}, c - {y}] if x in c and y in c else [c]
            new = list(dict.fromkeys(new))  # distinct, in order
            cols = [c for c in new if not any(c < o for o in new)]
    cols = [set(c) for c in cols]
    for c in cols:
        for s in sorted(c, key=rank.get):
            others = [o for o in cols if o is not c and s in o]
            if others and all(any(u in o for o in others) for u in c if u != s):
                c.discard(s)
    cols = sorted((c for c in cols if c), key=lambda c: sorted(rank[s] for s in c))
    return {s: "".join(_letter(k) for k, c in enumerate(cols) if s in c) for s in order}


def range_text(best: int, worst: int) -> str:
    """``3`` or ``1–4``."""
    return str(best) if best == worst else f"{best}–{worst}"


def tiers(values: Mapping[str, Mapping[int, float]], order: Sequence[str], blocks: Sequence = (),
          delta: float = DELTA) -> tuple[list[PairResult], dict[str, tuple[int, int]], dict[str, str]]:
    """The pairs with their verdicts, the rank ranges and the letters of the SUTs in ``order``."""
    pairs = pair_results(values, order, blocks, delta)
    return (pairs, *tiers_of(order, pairs))


def tiers_of(order: Sequence[str], pairs: Sequence[PairResult]) -> tuple[dict[str, tuple[int, int]], dict[str, str]]:
    """The rank ranges and the letters of the SUTs in ``order`` given their pairs' verdicts, from one look
    (:func:`pair_results`) or from the sequential looks (:mod:`evoscen_experiments.leaderboard_sequential`)."""
    above = above_of(pairs)
    return rank_ranges(order, above), letters(order, above)


def pair_tables(pairs: Sequence[PairResult], blocks: Sequence, d: str = "D") -> tuple[list, list, list, str]:
    """The pairs' Markdown header and rows, their CSV rows (:data:`PAIRS_CSV` then one verdict per block, then
    the contradiction flag) and the summary in words."""
    labels = [b.label for b in blocks] if len(blocks) > 1 else []
    header = ["a", "b", f"Δ{d} = a − b [95 %]", "n", "verdict", "episodes needed",
              *(f"block {lab}" for lab in labels), *(["agreement"] if labels else [])]
    md, rows = [], []
    for p in pairs:
        v = p.verdict
        flag = "contradiction" if p.contradiction else ("same" if len(set(p.blocks)) == 1 else "differ")
        md.append([p.a, p.b, f"{v.mean:+.4f} [{v.low:+.4f}, {v.high:+.4f}]", str(v.episodes), WORDS[v.verdict],
                   "–" if p.needed is None else f"{p.needed:,}", *(WORDS[w] for w in p.blocks),
                   *([f"**{flag}**" if p.contradiction else flag] if labels else [])])
        rows.append([p.a, p.b, v.mean, v.low, v.high, v.episodes, v.verdict, "" if p.needed is None else p.needed,
                     *p.blocks, *([int(p.contradiction)] if labels else [])])
    resolved = [p for p in pairs if p.verdict.verdict in RESOLVED]
    text = (f"{len(resolved)} of {len(pairs)} pairs resolved, "
            f"{sum(p.verdict.verdict == 'equivalent' for p in pairs)} equivalent, "
            f"{sum(p.verdict.verdict == 'unresolved' for p in pairs)} unresolved")
    if labels:
        text += (f"; between blocks: {sum(len(set(p.blocks)) == 1 for p in pairs)} pairs with the same verdict in "
                 f"every block, {sum(p.contradiction for p in pairs)} contradictions (a > b in one block, a < b "
                 f"in another)")
    return header, md, rows, text


PAIRS_CSV = ["a", "b", "delta_d_mean", "delta_d_low", "delta_d_high", "n", "verdict", "episodes_needed"]


def pairs_csv_header(blocks: Sequence) -> list[str]:
    """The columns of ``pairs.csv``: :data:`PAIRS_CSV`, with two or more blocks a verdict per block and the
    contradiction flag."""
    if len(blocks) < 2:
        return list(PAIRS_CSV)
    return [*PAIRS_CSV, *(f"verdict_block_{b.first}_{b.last}" for b in blocks), "contradiction"]
