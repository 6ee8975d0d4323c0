"""The leaderboard's sequential pair verdicts (``scripts/leaderboard.py --sequential``,
evoscen_experiments.leaderboard_sequential): the option errors, the looks on synthetic D values (which SUTs run
a look, which pairs close, values by hand), the tables turned to the ranking, and one small real run."""

from __future__ import annotations

import csv
import dataclasses
import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from evoscen_experiments import leaderboard_sequential as ls
from evoscen_experiments.experiments import config_loader
from evoscen_experiments.replication import SeedBlock
from evoscen_experiments.sensitivity_sequential import Plan
from evoscen_experiments.sequential import boundaries

REPO = Path(__file__).resolve().parents[1]
FIRST = 700
PLAN = Plan(round_size=4, budget=8, delta=0.05, spending="obrien_fleming", steps=20, first_seed=FIRST)
W = [0.1, -0.1] * 4
D = {
    # a − b = [0.5, 0.502, 0.498, 0.5]: mean 0.5, sd 0.001633, half <= 3 x 0.001633 / 2 -> above 0 at look 1
    "a": [1.0, 1.002, 0.998, 1.0, 1.0, 1.0, 1.0, 1.0],
    "b": [0.5] * 8,
    # b − c = 0.05 − w: look 1 mean 0.05, sd 0.1155, half > 2.5 x 0.1155 / 2 = 0.144 -> holds 0, not within
    # ±0.05: open; look 2 sd 0.1069, half > 1.9 x 0.1069 / √8 = 0.0718 -> holds 0: unresolved at the budget.
    # a − c = [0.45, 0.652, 0.448, 0.65]: mean 0.55, sd 0.1160, half < 3 x 0.1160 / 2 = 0.174 -> above 0 at look 1
    "c": [0.45 + w for w in W],
}
NAMES = ["c", "b", "a"]  # the pairs (c, b), (c, a), (b, a) are judged as c − b, c − a, b − a
SEEDS = range(FIRST, FIRST + 8)


def d_of(n: int, names=NAMES) -> dict[str, dict[int, float]]:
    return {s: {seed: D[s][seed - FIRST] for seed in SEEDS[:n]} for s in names}


def test_boundaries_the_hand_values_assume():
    c1, c2 = boundaries((0.5, 1.0), 0.05, "obrien_fleming")
    assert 2.5 < c1 < 3.0 and 1.9 < c2 < 2.1


def test_a_look_closes_the_resolved_pairs_and_only_suts_with_an_open_pair_run_the_next():
    start = {p: PLAN.judge([]) for p in ls.all_pairs(NAMES)}
    assert list(start) == [("c", "b"), ("c", "a"), ("b", "a")]
    assert ls.needing(NAMES, start) == NAMES
    first = ls.judge_open(PLAN, start, d_of(4), 4)
    assert {p: (v.verdict, v.episodes, v.looks) for p, v in first.items()} == {
        ("c", "b"): ("continue", 4, 1), ("c", "a"): ("b_higher", 4, 1), ("b", "a"): ("b_higher", 4, 1)}
    c1, c2 = boundaries((0.5, 1.0), 0.05, "obrien_fleming")
    b_a = [-0.5, -0.502, -0.498, -0.5]
    sd = math.sqrt(sum((x + 0.5) ** 2 for x in b_a) / 3)
    v = first[("b", "a")]
    assert (v.mean, v.low, v.high) == pytest.approx((-0.5, -0.5 - c1 * sd / 2, -0.5 + c1 * sd / 2))
    assert ls.needing(NAMES, first) == ["c", "b"]  # a's pairs are closed: a runs no more
    # the closed pairs keep their verdict at look 1; the open one is judged on all 8 episodes
    second = ls.judge_open(PLAN, first, d_of(8), 8)
    assert second[("b", "a")] == first[("b", "a")] and second[("c", "a")] == first[("c", "a")]
    c_b = [D["c"][i] - 0.5 for i in range(8)]
    mean = sum(c_b) / 8
    half = c2 * math.sqrt(sum((x - mean) ** 2 for x in c_b) / 7) / math.sqrt(8)
    v = second[("c", "b")]
    assert (v.verdict, v.episodes, v.looks) == ("unresolved", 8, 2)
    assert (v.mean, v.low, v.high) == pytest.approx((-0.05, -0.05 - half, -0.05 + half))
    assert ls.needing(NAMES, second) == []


class Engine:
    """A stand-in for the run engine: D of :data:`D` per SUT (the round's label) and seed, each run computed once."""

    def __init__(self) -> None:
        self.saved: dict[str, dict] = {}
        self.computed: list[tuple[str, int]] = []

    def __call__(self, rounds: list) -> dict:
        for rnd in rounds:
            if rnd.key not in self.saved:
                d = D[rnd.label][rnd.cfg.seed - FIRST]
                self.saved[rnd.key] = {"seed": rnd.cfg.seed, "report": {
                    "settings": {"score_form": "comparative"}, "comparative": {
                    "score": d, "safety": {"score": 1.0}, "progress": {"score": d}, "interaction": {"score": 1.0}}}}
                self.computed.append((rnd.label, rnd.cfg.seed))
        return {r.key: self.saved[r.key] for r in rounds}


def test_the_looks_run_each_sut_while_it_has_an_open_pair_and_the_tables_rank_and_turn_the_pairs(tmp_path):
    engine = Engine()
    load = config_loader(None)
    overrides = {"c": {"sut.model": "level0"}, "b": {"sut.model": "nilsson"}, "a": {"sut.model": "mobil"}}
    verdicts, d, rounds, _ = ls.run_looks(PLAN, NAMES, overrides, load, engine)
    look1 = [(s, seed) for s in NAMES for seed in range(700, 704)]
    look2 = [(s, seed) for s in ("c", "b") for seed in range(704, 708)]
    assert engine.computed == look1 + look2 and len(rounds) == 20
    assert {s: sorted(v) for s, v in d.items()} == {"c": list(SEEDS), "b": list(SEEDS), "a": list(SEEDS[:4])}
    assert {p: v.verdict for p, v in verdicts.items()} == {("c", "b"): "unresolved", ("c", "a"): "b_higher",
                                                            ("b", "a"): "b_higher"}

    text, printed = ls.write_tables(tmp_path, PLAN, d, verdicts, rounds, ["--sequential"], 1.0)
    with (tmp_path / "leaderboard.csv").open(newline="") as f:
        suts = list(csv.DictReader(f))
    # ranked by mean D over each SUT's own episodes: a 1.0 (4), b 0.5 (8), c 0.45 (8); a above both (resolved),
    # b and c not told apart: ranks 1, 2–3, 2–3, letters a, b, b
    assert [(r["sut"], r["rank_best"], r["rank_worst"], r["letters"], r["episodes"]) for r in suts] == [
        ("a", "1", "1", "a", "4"), ("b", "2", "3", "b", "8"), ("c", "2", "3", "b", "8")]
    assert [float(r["d_mean"]) for r in suts] == pytest.approx([1.0, 0.5, 0.45])
    with (tmp_path / "pairs.csv").open(newline="") as f:
        pairs = list(csv.DictReader(f))
    assert [(p["a"], p["b"], p["verdict"], p["episodes"], p["looks"]) for p in pairs] == [
        ("a", "b", "a_higher", "4", "1"), ("a", "c", "a_higher", "4", "1"), ("b", "c", "unresolved", "8", "2")]
    # b − c = 0.05 ∓ 0.1 over 8 episodes: sd 0.1069, ((1.95996 + 0.84162) x 0.1069 / 0.05)² = 35.88 -> 36 needed
    # by a fixed design; the resolved pairs state none
    assert [p["episodes_needed"] for p in pairs] == ["", "", "36"]
    # turned round: a − b is −(b − a), its interval [−high, −low]
    ba = verdicts[("b", "a")]
    assert [float(pairs[0][f"delta_d_{k}"]) for k in ("mean", "low", "high")] == pytest.approx(
        [-ba.mean, -ba.high, -ba.low])
    assert float(pairs[1]["delta_d_mean"]) == pytest.approx(0.55) and float(pairs[2]["delta_d_mean"]) == pytest.approx(0.05)
    assert "| a | b | a > b | +0.5000 [" in printed and "| b | c | unresolved | +0.0500 [" in printed and "| 8 | 2 | 36 |" in printed
    assert "| 2 | 2–3 | b | b |" in printed and text.endswith("python scripts/leaderboard.py --sequential\n")


def test_seed_blocks_give_a_ranking_per_block_and_the_pairs_side_by_side(tmp_path):
    plan = ls.plan_of(SimpleNamespace(sequential=True, budget="8", round_size="4", delta="0.05", spending="obrien_fleming",
                                      episode_steps="20", first_seed="20000", seed_blocks="700:707,800:807"),
                      {}, "20", "20000")
    load = config_loader(None)
    overrides = {"c": {"sut.model": "level0"}, "b": {"sut.model": "nilsson"}, "a": {"sut.model": "mobil"}}

    class Blocks(Engine):  # block 800: b and c swapped, so c − b turns round
        def __call__(self, rounds):
            for rnd in rounds:
                seed = rnd.cfg.seed
                if seed >= 800 and rnd.key not in self.saved:
                    label = {"b": "c", "c": "b"}.get(rnd.label, rnd.label)
                    d = {"a": 1.0, "b": 0.5, "c": 0.3}[label]
                    self.saved[rnd.key] = {"seed": seed, "report": {
                        "settings": {"score_form": "comparative"}, "comparative": {
                            "score": d, "safety": {"score": 1.0}, "progress": {"score": d},
                            "interaction": {"score": 1.0}}}}
            return super().__call__(rounds)

    engine = Blocks()
    parts = []
    for part in plan.parts:
        verdicts, d, rounds, _ = ls.run_looks(part, NAMES, overrides, load, engine)
        parts.append((part, verdicts, d, rounds))
    # block 800: constant differences, every pair resolved at the first look: c − b = 0.5 − 0.3 > 0 there, while
    # block 700 leaves c − b unresolved (the first test's hand values); b − a, c − a below 0 in both
    assert {p: v.verdict for p, v in parts[1][1].items()} == {("c", "b"): "a_higher", ("c", "a"): "b_higher",
                                                               ("b", "a"): "b_higher"}
    text, printed = ls.write_blocks(tmp_path, plan, parts, ["--sequential"], 1.0)
    with (tmp_path / "replication.csv").open(newline="") as f:
        rep = [(r["x"], r["y"], r["verdict_block_700_707"], r["verdict_block_800_807"], r["contradiction"])
               for r in csv.DictReader(f)]
    assert rep == [("c", "b", "unresolved", "a_higher", ""), ("c", "a", "b_higher", "b_higher", ""),
                   ("b", "a", "b_higher", "b_higher", "")]
    with (tmp_path / "pairs.csv").open(newline="") as f:
        assert [(p["a"], p["b"], p["block"]) for p in csv.DictReader(f)] == [
            ("a", "b", "700–707"), ("a", "c", "700–707"), ("b", "c", "700–707"),
            ("a", "c", "800–807"), ("a", "b", "800–807"), ("c", "b", "800–807")]
    assert "### Seeds 800–807" in printed and "| c | b | unresolved | x > y |  |" in printed
    assert "Contradictions (x above y in one block, below in another): none." in printed
    assert "seed blocks 700–707, 800–807, each a design of its own" in text
    # a contradiction: the same verdicts with block 800's c − b turned round against a block where it resolved
    flipped = {**parts[1][1], ("c", "b"): dataclasses.replace(parts[1][1][("c", "b")], verdict="b_higher")}
    rows, _, clashes = ls.replication(NAMES, ["1", "2"], [parts[1][1], flipped])
    assert clashes == [("c", "b")] and rows[0][-1] == "yes"


def test_replication_keeps_a_sut_missing_from_the_first_block_and_reads_each_block_in_its_own_order(tmp_path):
    # block 1: b failed (its pairs dropped, its D gone); block 2: all three, b ranked between them
    v = ls.Verdict
    block1 = {("c", "a"): v("b_higher", 4, -0.5, -0.6, -0.4, 1)}
    block2 = {("c", "b"): v("b_higher", 4, -0.2, -0.3, -0.1, 1), ("c", "a"): v("b_higher", 4, -0.5, -0.6, -0.4, 1),
              ("b", "a"): v("continue", 8, -0.1, -0.3, 0.1, 2)}
    d1 = {"c": {FIRST: 0.0}, "a": {FIRST: 0.5}}
    d2 = {"c": {FIRST: 0.0}, "b": {FIRST: 0.2}, "a": {FIRST: 0.5}}
    plan = dataclasses.replace(PLAN, blocks=(SeedBlock(FIRST, FIRST + 7), SeedBlock(FIRST + 100, FIRST + 107)))
    parts = [(p, verdicts, d, []) for p, verdicts, d in zip(plan.parts, (block1, block2), (d1, d2))]
    ls.write_blocks(tmp_path, plan, parts, ["--sequential"], 1.0)
    with (tmp_path / "replication.csv").open(newline="") as f:
        rep = [(r["x"], r["y"], r["verdict_block_700_707"], r["verdict_block_800_807"]) for r in csv.DictReader(f)]
    # the SUTs in their first-seen order c, a, b: (a, b) is block 2's (b, a) turned round, open -> unresolved
    assert rep == [("c", "a", "b_higher", "b_higher"), ("c", "b", "", "b_higher"), ("a", "b", "", "unresolved")]
    # a pair seen the other way round in a block: its verdict turned, a contradiction found across orientations
    turned = {("a", "c"): v("b_higher", 4, -0.5, -0.6, -0.4, 1)}
    rows, _, clashes = ls.replication(["c", "a"], ["1", "2"], [block1, turned])
    assert rows == [["c", "a", "b_higher", "a_higher", "yes"]] and clashes == [("c", "a")]
    with pytest.raises(ValueError, match="2 block labels for 1 blocks"):
        ls.replication(["c", "a"], ["1", "2"], [block1])


def test_a_sut_whose_episode_fails_leaves_the_ranking_and_is_listed(tmp_path):
    class Failing(Engine):  # b's episode 702 fails: its result never comes back
        def __call__(self, rounds):
            got = super().__call__(rounds)
            return {k: v for k, v in got.items() if not (v["report"] and k in self.broken)}

    engine = Failing()
    load = config_loader(None)
    overrides = {"c": {"sut.model": "level0"}, "b": {"sut.model": "nilsson"}, "a": {"sut.model": "mobil"}}
    engine.broken = {r.key for r in ls.look_rounds(PLAN, ["b"], 0, load, overrides) if r.cfg.seed == 702}
    verdicts, d, rounds, _ = ls.run_looks(PLAN, NAMES, overrides, load, engine)
    # b's pairs dropped after look 1; c − a as in the first test (a above c at look 1): nothing open, no look 2
    assert set(verdicts) == {("c", "a")} and verdicts[("c", "a")].verdict == "b_higher"
    assert set(d) == {"c", "a"} and len(rounds) == 12
    failed = {"b": (1, "RuntimeError: the planner raised")}
    text, printed = ls.write_tables(tmp_path, PLAN, d, verdicts, rounds, ["--sequential"], 1.0, failed)
    assert "Failed, not ranked: b (1 episode(s): RuntimeError: the planner raised)" in printed
    with (tmp_path / "leaderboard.csv").open(newline="") as f:
        assert [r["sut"] for r in csv.DictReader(f)] == ["a", "c"]
    with (tmp_path / "episodes.csv").open(newline="") as f:
        eps = list(csv.DictReader(f))
    assert [(r["sut"], r["seed"]) for r in eps] == [("c", str(s)) for s in SEEDS[:4]] + [("a", str(s)) for s in SEEDS[:4]]
    assert [float(r["d"]) for r in eps if r["sut"] == "a"] == pytest.approx(D["a"][:4])


@pytest.fixture(scope="module")
def door(load_door):
    """The script as a module."""
    return load_door("leaderboard")


@pytest.mark.parametrize("args, expected", [
    (["--sequential", "--episodes", "3"], "error: --sequential and --episodes together: the sequential design "
                                          "runs rounds of --round-size episodes from --first-seed up to --budget"),
    (["--sequential", "--blocks", "2"], "error: --sequential and --blocks together"),
    (["--sequential", "--block-size", "5"], "error: --sequential and --block-size together"),
    (["--sequential", "--seed-blocks", "1:400", "--first-seed", "7"], "error: --seed-blocks and --first-seed "
                                                                      "together: the blocks name their seeds"),
    (["--sequential", "--seed-blocks", "1:50"], "error: --seed-blocks: block 1–50 holds 50 seeds, fewer than "
                                                "--round-size 100"),
    (["--budget", "8"], "error: --budget applies with --sequential only"),
    (["--spending", "pocock"], "error: --spending applies with --sequential only"),
    (["--sequential", "--round-size", "9", "--budget", "8"], "error: --round-size 9 exceeds --budget 8"),
    (["--sequential", "--round-size", "1"], "error: --round-size = '1': expected an integer >= 2"),
    (["--sequential", "--delta", "0"], "error: --delta = '0': expected a number > 0"),
    (["--sequential", "--spending", "linear"], "error: --spending 'linear': expected one of obrien_fleming, pocock"),
    (["--sequential", "--suts", "mobil,warp"], "error: --suts: 'warp' is no installed SUT model to rank"),
    (["--sequential", "--mutant-refs", "nosuch"], "error: --mutant-refs: unknown mutant 'nosuch'"),
])
def test_bad_input_is_one_line_and_exit_2_before_anything_is_written(door, tmp_path, capsys, args, expected):
    out = tmp_path / "out"
    assert door.main([*args, "--out", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith(expected), err
    assert not out.exists()


@pytest.mark.e2e
def test_a_small_real_run_uses_whole_rounds_within_the_budget(tmp_path):
    out = tmp_path / "lb"
    res = subprocess.run([sys.executable, "scripts/leaderboard.py", "--suts", "mobil,level0", "--reference", "level0",
                          "--mutant-refs", "none", "--sequential", "--round-size", "2", "--budget", "4",
                          "--episode-steps", "30", "--jobs", "1", "--challenge", "none", "--out", str(out)],
                         cwd=REPO, capture_output=True, text=True, timeout=300, check=False)
    assert res.returncode == 0, res.stderr
    with (out / "pairs.csv").open(newline="") as f:
        (pair,) = csv.DictReader(f)
    with (out / "leaderboard.csv").open(newline="") as f:
        suts = list(csv.DictReader(f))
    n = int(pair["episodes"])
    assert n in (2, 4) and int(pair["looks"]) == n // 2  # whole rounds of 2, at most the budget of 4
    assert {pair["a"], pair["b"]} == {"mobil", "level0"} and pair["a"] == suts[0]["sut"]
    assert [r["episodes"] for r in suts] == [str(n), str(n)]  # the pair's episodes, run by both
    # both ran the same seeds: the pair's mean difference is the difference of the SUTs' means
    assert float(pair["delta_d_mean"]) == pytest.approx(float(suts[0]["d_mean"]) - float(suts[1]["d_mean"]), abs=1e-12)
    low, high = float(pair["delta_d_low"]), float(pair["delta_d_high"])
    assert low < float(pair["delta_d_mean"]) < high
    expected = ("a_higher" if low > 0 else "b_higher" if high < 0 else
                "equivalent" if -0.005 < low and high < 0.005 else "unresolved" if n == 4 else None)
    assert pair["verdict"] == expected
    text = (out / "leaderboard.md").read_text(encoding="utf-8")
    assert "# Planner leaderboard: sequential verdicts" in text and "| a | b | verdict | ΔD = a − b [RCI] |" in text
    assert f"| {pair['a']} | {pair['b']} |" in res.stdout and (out / "timing.json").is_file()
