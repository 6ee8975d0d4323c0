"""The leaderboard in tiers (evoscen_experiments.leaderboard_tiers): letters and rank ranges on hand-made verdict
sets, the episodes-needed formula, the pair verdicts and contradictions between blocks, by hand; and the
contradictions of the sensitivity experiment's blocks (evoscen_experiments.replication)."""

from __future__ import annotations

import itertools
import math
import random

import pytest

from evoscen_experiments import leaderboard_tiers as lt
from evoscen_experiments.replication import block_detection, block_scores, consecutive_blocks

ABC = ["A", "B", "C"]


@pytest.mark.parametrize("above, letters, ranges", [
    # A > C only: A and B share a, B and C share b; A can rank 1–2 (C below it), C 2–3, B anywhere
    ({("A", "C")}, {"A": "a", "B": "ab", "C": "b"}, {"A": (1, 2), "B": (1, 3), "C": (2, 3)}),
    # a full chain: every pair resolved, one letter and one rank each
    ({("A", "B"), ("A", "C"), ("B", "C")}, {"A": "a", "B": "b", "C": "c"}, {"A": (1, 1), "B": (2, 2), "C": (3, 3)}),
    # all equivalent (no pair resolved): one letter, every rank possible
    (set(), {"A": "a", "B": "a", "C": "a"}, {"A": (1, 3), "B": (1, 3), "C": (1, 3)}),
    # B > C only: A shares a letter with both, B and C none
    ({("B", "C")}, {"A": "ab", "B": "a", "C": "b"}, {"A": (1, 3), "B": (1, 2), "C": (2, 3)}),
])
def test_letters_and_rank_ranges_by_hand(above, letters, ranges):
    assert lt.letters(ABC, above) == letters
    assert lt.rank_ranges(ABC, above) == ranges


def test_four_suts_by_hand():
    # A > C, A > D, B > D. Insert: {ABCD} -> (A, C): {BCD}, {ABD} -> (A, D): {BCD}, {BD}, {AB}; absorb {BD}
    # -> (B, D): {CD}, {BC}, {AB}; letters by best member: {AB} a, {BC} b, {CD} c
    order, above = ["A", "B", "C", "D"], {("A", "C"), ("A", "D"), ("B", "D")}
    assert lt.letters(order, above) == {"A": "a", "B": "ab", "C": "bc", "D": "c"}
    # best = 1 + resolved above, worst = 4 − resolved below
    assert lt.rank_ranges(order, above) == {"A": (1, 2), "B": (1, 3), "C": (2, 4), "D": (3, 4)}
    assert [lt.range_text(*r) for r in lt.rank_ranges(order, above).values()] == ["1–2", "1–3", "2–4", "3–4"]


def test_letters_are_shared_exactly_by_the_unresolved_pairs():
    rng = random.Random(7)
    order = list("ABCDEFG")
    for _ in range(200):
        above = {(x, y) for x, y in itertools.combinations(order, 2) if rng.random() < 0.4}
        got = lt.letters(order, above)
        for x, y in itertools.combinations(order, 2):
            assert bool(set(got[x]) & set(got[y])) == ((x, y) not in above), (above, got)
        assert all(got[s] for s in order)


def test_episodes_needed_by_hand():
    # d = 0.1, 0.3: mean 0.2, sd 0.1·√2; ((1.95996 + 0.84162) · 0.141421 / 0.2)² = 1.98099² = 3.924 -> 4
    assert lt.episodes_needed([0.1, 0.3]) == 4
    # d = 1, −1, 1, −1, 2: mean 0.4, sd √1.8 = 1.341641; (2.801585 · 3.354102)² = 9.396799² = 88.30 -> 89
    assert lt.episodes_needed([1, -1, 1, -1, 2]) == 89
    assert lt.episodes_needed([0.1, -0.1]) is None and lt.episodes_needed([0.3]) is None


def test_pair_verdicts_by_hand():
    # 0.1, 0.2, 0.3: mean 0.2 ± 1.96·0.1/√3 = ± 0.11316: a > b
    v = lt.judge([0.1, 0.2, 0.3])
    assert (v.verdict, v.episodes) == ("a_higher", 3) and v.low == pytest.approx(0.2 - 0.113159, abs=1e-6)
    # ±0.001: mean 0 ± 1.96·0.0011547/2 = ± 0.00113, inside ±0.005: equivalent
    assert lt.judge([0.001, -0.001, 0.001, -0.001]).verdict == "equivalent"
    # 0.1, −0.1: 0 ± 0.196: unresolved; one difference: unresolved
    assert lt.judge([0.1, -0.1]).verdict == "unresolved" and lt.judge([0.5]).verdict == "unresolved"
    assert lt.judge([-0.3, -0.2, -0.1]).verdict == "b_higher"


def test_a_contradiction_between_blocks_is_flagged_and_counted():
    blocks = consecutive_blocks(0, 2, 2)  # seeds 0–1 and 2–3
    values = {"a": {0: 1.0, 1: 1.1, 2: 0.0, 3: 0.1}, "b": {0: 0.0, 1: 0.0, 2: 1.0, 3: 1.0},
              "c": {0: 0.0, 1: 0.1, 2: 0.0, 3: 0.1}}
    pairs, ranges, letters = lt.tiers(values, ["a", "b", "c"], blocks)
    by = {(p.a, p.b): p for p in pairs}
    # a − b: block 1 1.0, 1.1 (a > b), block 2 −1.0, −0.9 (a < b); over all 0.05 ± 1.96·1.0408/2: unresolved
    ab = by[("a", "b")]
    assert ab.blocks == ("a_higher", "b_higher") and ab.contradiction and ab.verdict.verdict == "unresolved"
    assert ab.needed == math.ceil(((lt.Z_975 + lt.Z_80) * math.sqrt(((0.95 ** 2 + 1.05 ** 2 + 1.05 ** 2
                                                                      + 0.95 ** 2) / 3)) / 0.05) ** 2)
    # a − c: 1.0, 1.0, 0.0, 0.0: mean 0.5 ± 1.96·0.57735/2 = ± 0.566: unresolved; block 1: 1.0, 1.0 (sd 0): a > c,
    # block 2: 0, 0 (sd 0, inside ±0.005): a ≈ c — different verdicts, no contradiction
    assert by[("a", "c")].blocks == ("a_higher", "equivalent") and not by[("a", "c")].contradiction
    head, md, rows, text = lt.pair_tables(pairs, blocks)
    assert head[-3:] == ["block 0–1", "block 2–3", "agreement"]
    assert md[0][-3:] == ["a > b", "a < b", "**contradiction**"] and rows[0][-1] == 1
    assert lt.pairs_csv_header(blocks)[-3:] == ["verdict_block_0_1", "verdict_block_2_3", "contradiction"]
    assert md[1][-1] == "differ" and rows[1][-1] == 0
    # b − c: 0, −0.1, 1, 0.9: 0.45 ± 1.96·0.58023/2 = ± 0.569: unresolved. No pair resolved over all: one tier
    assert text == ("0 of 3 pairs resolved, 0 equivalent, 3 unresolved; between blocks: 0 pairs with the same "
                    "verdict in every block, 1 contradictions (a > b in one block, a < b in another)")
    assert letters == {"a": "a", "b": "a", "c": "a"} and ranges == {"a": (1, 3), "b": (1, 3), "c": (1, 3)}


def test_a_mutant_worse_in_one_block_and_better_in_another_is_a_contradiction():
    blocks = consecutive_blocks(0, 2, 2)
    intact = {0: 1.0, 1: 1.1, 2: 0.0, 3: 0.1}
    flip = block_detection(intact, {0: 0.0, 1: 0.0, 2: 1.0, 3: 1.0}, blocks)
    assert [(b.detected, b.better) for b in flip.per_block] == [(True, False), (False, True)] and flip.contradiction
    same = block_detection(intact, {0: 0.0, 1: 0.0, 2: 0.0, 3: 0.1}, blocks)
    assert not same.contradiction
    assert block_scores({"flip": flip, "same": same}, blocks).contradictions == 1
