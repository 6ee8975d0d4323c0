"""Statistics that replicate: seed blocks, detection per block, applicability, pairwise verdicts, Kendall τ.

Pure functions over per-seed values (no simulation here), used by :mod:`evoscen_experiments.sensitivity_tables`
and :mod:`evoscen_experiments.leaderboard` (docs/sensitivity.md "Seed blocks", docs/experiments.md §4).

* **seed blocks** — an experiment's seeds in disjoint, contiguous blocks (:func:`parse_seed_blocks`,
  :func:`consecutive_blocks`); every figure is computed per block as well, so a reader sees whether
  it replicates on seeds it was not computed on;
* **detection per block** — :func:`block_detection`: per mutant and block the paired interval, the
  verdict and the episodes needed (:func:`evoscen_experiments.sensitivity.seeds_needed`), and whether the
  mutant is detected in *every* block; the mutation score per block and its minimum over the blocks;
* **applicability** — :func:`applicable_split`: which mutants of a selection apply to a base
  (:func:`evoscen_sut.mutants.mutants_for`); the others are not run and are reported as not
  applicable, and the mutation score counts applicable (base, mutant) pairs only;
* **pairwise verdicts** — :func:`pairwise`: every pair of SUTs paired by episode, mean ± 95 %
  Student-t interval, n and the words "significantly higher/lower";
* **verdicts side by side** — :func:`side_by_side`: the sequential designs' verdicts of one comparison in
  every block, and whether two blocks contradict each other;
* **Kendall τ** — :func:`kendall_tau`: the agreement of two blocks' orders (τ-b: ties in either
  block counted as neither concordant nor discordant, and taken out of the denominator).

No sequential stopping: every block runs all its seeds, so the 95 % intervals keep their nominal
error rate (docs/sensitivity.md "Seed blocks").
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from evoscen_experiments.sensitivity import Paired, paired, seeds_needed
from evoscen_experiments.stats import difference_words


@dataclass(frozen=True)
class SeedBlock:
    """A block of consecutive seeds ``first`` .. ``last`` (both included)."""

    first: int
    last: int

    @property
    def seeds(self) -> range:
        return range(self.first, self.last + 1)

    @property
    def size(self) -> int:
        return self.last - self.first + 1

    @property
    def label(self) -> str:
        """``first–last`` as the tables print it."""
        return f"{self.first}–{self.last}"


def _check_disjoint(blocks: Sequence[SeedBlock], option: str) -> None:
    from evoscen_sim.errors import InputError

    ordered = sorted(blocks, key=lambda b: b.first)
    for a, b in zip(ordered, ordered[1:]):
        if b.first <= a.last:
            raise InputError(f"{option}: blocks {a.first}:{a.last} and {b.first}:{b.last} overlap: expected "
                             f"disjoint seed blocks")


def parse_seed_blocks(text: str, option: str = "--seed-blocks") -> list[SeedBlock]:
    """``"A:B,C:D"`` -> blocks of seeds A..B and C..D (both ends included), in the order given.

    InputError of one line: a block not ``first:last`` of integers >= 0 with first <= last,
    overlapping blocks, no block."""
    from evoscen_sim.errors import InputError

    blocks = []
    parts = [p.strip() for p in text.split(",")]
    if not any(parts):
        raise InputError(f"{option} {text!r}: expected comma-separated blocks first:last (seeds, both included)")
    for part in parts:
        a, sep, b = part.partition(":")
        try:
            first, last = int(a), int(b)
        except ValueError:
            first, last = -1, -1
        if not sep or first < 0 or last < first:
            raise InputError(f"{option}: block {part!r}: expected first:last, integers >= 0 with first <= last")
        blocks.append(SeedBlock(first, last))
    _check_disjoint(blocks, option)
    return blocks


def consecutive_blocks(first_seed: int, blocks: int, size: int) -> list[SeedBlock]:
    """``blocks`` blocks of ``size`` seeds each, one after the other from ``first_seed``."""
    return [SeedBlock(first_seed + k * size, first_seed + (k + 1) * size - 1) for k in range(blocks)]


def restrict(values: Mapping[int, float], block: SeedBlock) -> dict[int, float]:
    """The seeds of ``values`` (seed -> value) that lie in ``block``."""
    return {s: v for s, v in values.items() if block.first <= s <= block.last}


@dataclass(frozen=True)
class BlockResult:
    """One mutant in one block: the paired ``intact − mutant`` difference and the episodes needed."""

    block: SeedBlock
    diff: Paired
    needed: int | None

    @property
    def detected(self) -> bool:
        return self.diff.above_zero

    @property
    def better(self) -> bool:
        """The whole 95 % interval of intact − mutant lies below zero: the mutant scores higher."""
        d = self.diff
        return d.n >= 2 and math.isfinite(d.half) and d.mean + d.half < 0.0


@dataclass(frozen=True)
class MutantBlocks:
    """One mutant over every block."""

    per_block: tuple[BlockResult, ...]

    @property
    def detected_in_every_block(self) -> bool:
        return bool(self.per_block) and all(b.detected for b in self.per_block)

    @property
    def detected_blocks(self) -> int:
        return sum(b.detected for b in self.per_block)

    @property
    def contradiction(self) -> bool:
        """Worse (detected) in one block, better in another."""
        return any(b.detected for b in self.per_block) and any(b.better for b in self.per_block)


def block_detection(intact: Mapping[int, float], mutant: Mapping[int, float],
                    blocks: Sequence[SeedBlock]) -> MutantBlocks:
    """Per block: the paired ``intact − mutant`` interval over the block's seeds and the episodes needed
    (the smallest n from which every prefix of the block's seeds, in order, detects)."""
    out = []
    for b in blocks:
        i, m = restrict(intact, b), restrict(mutant, b)
        out.append(BlockResult(b, paired(i, m), seeds_needed(i, m)))
    return MutantBlocks(tuple(out))


@dataclass(frozen=True)
class BlockScores:
    """A scenario's mutation score per block over the applicable mutants."""

    blocks: tuple[SeedBlock, ...]
    detected: tuple[int, ...]
    """Mutants detected in each block."""
    applicable: int
    every_block: int
    """Mutants detected in every block."""
    contradictions: int = 0
    """Mutants worse in one block and better in another."""

    @property
    def scores(self) -> tuple[float, ...]:
        return tuple(k / self.applicable if self.applicable else math.nan for k in self.detected)

    @property
    def min_detected(self) -> int:
        """The fewest detections of any block (0 without blocks)."""
        return min(self.detected, default=0)

    @property
    def min_block(self) -> SeedBlock | None:
        """The first block with the fewest detections (the block the minimum comes from)."""
        if not self.blocks:
            return None
        return self.blocks[self.detected.index(self.min_detected)]


def block_scores(results: Mapping[str, MutantBlocks], blocks: Sequence[SeedBlock]) -> BlockScores:
    """The mutation score per block of the (applicable) mutants in ``results`` (name -> :class:`MutantBlocks`)."""
    detected = tuple(sum(r.per_block[k].detected for r in results.values()) for k in range(len(blocks)))
    return BlockScores(tuple(blocks), detected, len(results),
                       sum(r.detected_in_every_block for r in results.values()),
                       sum(r.contradiction for r in results.values()))


def applicable_split(base: str, mutants: Sequence[str]) -> tuple[list[str], list[str]]:
    """``mutants`` (in their order) split into those that apply to ``base`` and those that do not
    (:func:`evoscen_sut.mutants.mutants_for`, docs/mutants.md "Which bases")."""
    from evoscen_sut.mutants import mutants_for

    ok = set(mutants_for(base))
    return [m for m in mutants if m in ok], [m for m in mutants if m not in ok]


@dataclass(frozen=True)
class PairVerdict:
    """``a − b`` paired by episode."""

    a: str
    b: str
    diff: Paired

    @property
    def words(self) -> str:
        return difference_words(self.diff.mean, self.diff.half, self.diff.n)

    @property
    def significant(self) -> bool:
        return self.words in ("significantly higher", "significantly lower")


def pairwise(order: Sequence[str], values: Mapping[str, Mapping[int, float]]) -> list[PairVerdict]:
    """Every pair (a, b) with a ranked above b in ``order``: ``a − b`` paired over their shared episodes
    (``values``: SUT -> episode seed -> score)."""
    return [PairVerdict(a, b, paired(values[a], values[b]))
            for i, a in enumerate(order) for b in order[i + 1:]]



def side_by_side(keys: Sequence, per_block: Sequence[Mapping[object, str]], one_way: str, other_way: str
                 ) -> list[tuple[object, list[str], bool]]:
    """Per key (a comparison, a pair of SUTs) its verdict word in every block (``""`` where a block has none) and
    whether the blocks contradict: one block says ``one_way`` and another ``other_way`` (worse and better; x above
    y and below). The replication tables of :mod:`evoscen_experiments.sensitivity_sequential` and
    :mod:`evoscen_experiments.leaderboard_sequential`."""
    out = []
    for key in keys:
        per = [block.get(key, "") for block in per_block]
        out.append((key, per, one_way in per and other_way in per))
    return out

def kendall_tau(x: Mapping[str, float], y: Mapping[str, float]) -> tuple[float, int, int, int]:
    """Kendall's τ-b of two score maps over the names both have: returns (τ, concordant, discordant, n).

    Over every pair of names (i, j): concordant when x and y order them alike, discordant when
    oppositely; a pair tied in x or in y is neither. τ-b = (C − D) / √((P − Tx)(P − Ty)), P = n(n−1)/2
    pairs, Tx (Ty) the pairs tied in x (y). ``nan`` below 2 names or when either side is all ties."""
    names = sorted(n for n in set(x) & set(y) if math.isfinite(x[n]) and math.isfinite(y[n]))
    c = d = tx = ty = 0
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            sx = (x[a] > x[b]) - (x[a] < x[b])
            sy = (y[a] > y[b]) - (y[a] < y[b])
            tx += sx == 0
            ty += sy == 0
            if sx * sy > 0:
                c += 1
            elif sx * sy < 0:
                d += 1
    pairs = len(names) * (len(names) - 1) // 2
    denom = math.sqrt((pairs - tx) * (pairs - ty))
    tau = (c - d) / denom if denom > 0 else math.nan
    return tau, c, d, len(names)
