"""Seed blocks, detection per block, applicability, pairwise verdicts and Kendall τ (evoscen_experiments.replication),
against values worked out by hand."""

from __future__ import annotations

import math

import pytest

from evoscen_experiments.replication import (
    SeedBlock,
    applicable_split,
    block_detection,
    block_scores,
    consecutive_blocks,
    kendall_tau,
    pairwise,
    parse_seed_blocks,
)
from evoscen_sim.errors import InputError

T975_DF3 = 3.182446305  # Student-t 0.975 quantile, 3 degrees of freedom


def test_seed_blocks_parsed_and_consecutive() -> None:
    assert parse_seed_blocks("510000:510019, 520000:520019") == [SeedBlock(510000, 510019), SeedBlock(520000, 520019)]
    assert parse_seed_blocks("7:7")[0].seeds == range(7, 8)
    assert consecutive_blocks(100, 3, 5) == [SeedBlock(100, 104), SeedBlock(105, 109), SeedBlock(110, 114)]
    assert SeedBlock(100, 104).label == "100–104" and SeedBlock(100, 104).size == 5


@pytest.mark.parametrize("text, message", [
    ("5:3", "--seed-blocks: block '5:3': expected first:last, integers >= 0 with first <= last"),
    ("a:b", "--seed-blocks: block 'a:b': expected first:last"),
    ("10", "--seed-blocks: block '10': expected first:last"),
    ("0:10,5:20", "--seed-blocks: blocks 0:10 and 5:20 overlap: expected disjoint seed blocks"),
    (" ", "--seed-blocks ' ': expected comma-separated blocks first:last"),
])
def test_bad_seed_blocks_are_one_line(text, message) -> None:
    with pytest.raises(InputError) as err:
        parse_seed_blocks(text)
    assert str(err.value).startswith(message)


def test_detection_per_block_minimum_and_episodes_needed_by_hand() -> None:
    intact = {s: 1.0 for s in range(8)}
    # block 0..3: d = 1, 1, 1, 1 -> 1 ± 0, detected, needed 2 (the first prefix with an interval)
    # block 4..7: d = 0.5, 2, 1, 1.5 -> 1.25 ± t3·0.6455/2 = 1.25 ± 1.0271: detected only with all 4
    #   (prefix 2: 1.25 ± 9.53, prefix 3: 1.167 ± 1.897), so needed 4
    steady = {0: 0.0, 1: 0.0, 2: 0.0, 3: 0.0, 4: 0.5, 5: -1.0, 6: 0.0, 7: -0.5}
    # block 0..3: d = 1, −1, 1, −1 -> 0, not detected; block 4..7 as steady's
    flaky = {0: 0.0, 1: 2.0, 2: 0.0, 3: 2.0, 4: 0.5, 5: -1.0, 6: 0.0, 7: -0.5}
    blocks = consecutive_blocks(0, 2, 4)
    s = block_detection(intact, steady, blocks)
    (a, b) = s.per_block
    assert (a.diff.mean, a.diff.half, a.diff.n, a.detected, a.needed) == (1.0, 0.0, 4, True, 2)
    sd = math.sqrt((0.75 ** 2 * 2 + 0.25 ** 2 * 2) / 3)
    assert b.diff.mean == pytest.approx(1.25) and b.diff.half == pytest.approx(T975_DF3 * sd / 2)
    assert b.detected and b.needed == 4 and s.detected_in_every_block
    f = block_detection(intact, flaky, blocks)
    assert f.per_block[0].diff.mean == 0.0 and not f.per_block[0].detected and f.per_block[0].needed is None
    assert f.per_block[1].detected and f.detected_blocks == 1 and not f.detected_in_every_block
    scores = block_scores({"steady": s, "flaky": f}, blocks)
    assert scores.detected == (1, 2) and scores.scores == (0.5, 1.0)
    assert scores.min_detected == 1 and scores.min_block == SeedBlock(0, 3)  # the minimum comes from block 0..3
    assert scores.every_block == 1 and scores.applicable == 2


def test_mutants_that_do_not_apply_are_split_off() -> None:
    chosen = ["tailgating", "frozen", "over_eager", "stale"]
    assert applicable_split("mobil", chosen) == (chosen, [])
    assert applicable_split("sumo_sut", chosen) == (["frozen", "stale"], ["tailgating", "over_eager"])
    assert applicable_split("level0", chosen) == (["tailgating", "stale"], ["frozen", "over_eager"])
    assert applicable_split("fiss", chosen) == (["tailgating", "frozen", "stale"], ["over_eager"])


def test_kendall_tau_by_hand() -> None:
    x = {"a": 4.0, "b": 3.0, "c": 2.0, "d": 1.0}
    assert kendall_tau(x, x) == (1.0, 6, 0, 4)
    # one swapped pair (a, b) of 6: (5 − 1) / 6
    tau, c, d, n = kendall_tau(x, {"a": 3.0, "b": 4.0, "c": 2.0, "d": 1.0})
    assert (c, d, n) == (5, 1, 4) and tau == pytest.approx(4 / 6)
    assert kendall_tau(x, {k: -v for k, v in x.items()})[0] == -1.0
    # a tie in x: (a, b) tied, (a, c) and (b, c) concordant: τ-b = 2 / √((3 − 1)(3 − 0))
    tau, c, d, n = kendall_tau({"a": 1.0, "b": 1.0, "c": 2.0}, {"a": 1.0, "b": 2.0, "c": 3.0, "z": 9.0})
    assert (c, d, n) == (2, 0, 3) and tau == pytest.approx(2 / math.sqrt(6))
    assert math.isnan(kendall_tau({"a": 1.0}, {"a": 1.0})[0])


def test_pairwise_words_by_hand() -> None:
    values = {"a": {0: 1.0, 1: 1.1}, "b": {0: 0.0, 1: 0.1}, "c": {0: 0.5, 1: 0.0}}
    pairs = {(p.a, p.b): p for p in pairwise(["a", "b", "c"], values)}
    assert list(pairs) == [("a", "b"), ("a", "c"), ("b", "c")]
    ab = pairs[("a", "b")]
    assert (ab.diff.mean, ab.diff.half, ab.diff.n) == (pytest.approx(1.0), pytest.approx(0.0), 2)
    assert ab.words == "significantly higher" and ab.significant
    # b − c = −0.5, +0.1: −0.2 ± 12.706·0.4243/√2 = −0.2 ± 3.81
    assert pairs[("b", "c")].words == "no significant difference" and not pairs[("b", "c")].significant
    low = pairwise(["b", "a"], values)[0]
    assert low.words == "significantly lower" and low.diff.mean == pytest.approx(-1.0)
