"""The planner leaderboard (scripts/leaderboard.py, its logic in evoscen_experiments.leaderboard): which SUTs
it ranks, the ranking, the paired interval against the reference (by hand from the per-episode CSV), a
failing plug-in, bad input."""

from __future__ import annotations

import csv
import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import pytest

from evoscen_experiments import leaderboard as lb

REPO = Path(__file__).resolve().parents[1]
T975_DF3 = 3.182446305  # Student-t 0.975 quantile, 3 degrees of freedom
Z975 = 1.959963985
SEEDS = (7, 8, 9, 10)
BAD_LINE = ("failed: bad_sut: 4/4 episodes: InputError: sut model 'bad_sut': act() returned throttle nan "
            "(entry 0); expected a finite number in [-1, 1]")


@pytest.fixture(scope="module")
def board():
    """The script as a module (scripts/ on sys.path for its _bootstrap import)."""
    sys.path.insert(0, str(REPO / "scripts"))
    try:
        spec = importlib.util.spec_from_file_location("leaderboard", REPO / "scripts" / "leaderboard.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(REPO / "scripts"))
    return module


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_every_installed_sut_model_but_the_mutant_wrapper_is_ranked(board):
    suts = lb.installed_suts()
    assert suts[:4] == ["level0", "nilsson", "mobil", "stackelberg"]  # the built-ins, in registration order
    assert "mutant" not in suts
    assert lb.resolve_suts("all", "mobil") == suts


def test_ranked_by_mean_intelligence_ties_by_name_undefined_last(board):
    means = {"b": 0.5, "a": 0.5, "c": 0.7, "d": math.nan, "e": 0.1}
    assert lb.ranked(means) == ["c", "a", "b", "e", "d"]


@pytest.mark.parametrize("args, expected", [
    (["--suts", "mobil,warp"], "error: --suts: 'warp' is no installed SUT model to rank: expected 'all' or names "
                               "from level0, nilsson, mobil, stackelberg"),
    (["--suts", "mobil,mutant"], "error: --suts: 'mutant' is no installed SUT model to rank"),
    (["--suts", "mobil,mobil"], "error: --suts 'mobil,mobil': expected distinct comma-separated SUT model names"),
    (["--suts", "nilsson,stackelberg"], "error: --reference 'mobil' is not among the SUTs ranked "
                                        "(nilsson, stackelberg)"),
    (["--episodes", "0"], "error: --episodes = '0': expected an integer >= 1"),
    (["--episode-steps", "x"], "error: --episode-steps = 'x': expected an integer >= 1"),
    (["--first-seed", "-1"], "error: --first-seed = '-1': expected an integer >= 0"),
    (["--jobs", "0"], "error: --jobs = '0': expected an integer >= 1"),
    (["--episodes", "3", "--blocks", "2"], "error: --episodes and --blocks together: --episodes is one block"),
    (["--seed-blocks", "5:3"], "error: --seed-blocks: block '5:3': expected first:last"),
    (["--seed-blocks", "0:9", "--first-seed", "4"], "error: --seed-blocks and --first-seed together"),
    (["--block-size", "0"], "error: --block-size = '0': expected an integer >= 1"),
    (["--mutant-refs", "nosuch"], "error: --mutant-refs: unknown mutant 'nosuch'"),
    (["--suts", "level0,mobil", "--mutant-base", "level0", "--mutant-refs", "frozen"],
     "error: --mutant-refs: 'frozen' does not apply to --mutant-base 'level0'"),
    (["--suts", "nilsson,mobil", "--mutant-base", "fiss"], "error: --mutant-base 'fiss' is not among the SUTs ranked"),
])
def test_bad_input_is_one_line_and_exit_2_before_anything_is_written(board, tmp_path, capsys, args, expected):
    out = tmp_path / "out"
    assert board.main([*args, "--out", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith(expected), err
    assert not out.exists()


def test_seed_blocks_default_to_two_blocks_of_100_from_20000(board):
    from evoscen_experiments.replication import SeedBlock

    assert lb.resolve_blocks(board.parse_args([])) == [SeedBlock(20000, 20099), SeedBlock(20100, 20199)]
    assert lb.resolve_blocks(board.parse_args(["--episodes", "3", "--first-seed", "7"])) == [SeedBlock(7, 9)]
    assert lb.resolve_blocks(board.parse_args(["--blocks", "3", "--block-size", "2", "--first-seed", "0"])) == [
        SeedBlock(0, 1), SeedBlock(2, 3), SeedBlock(4, 5)]
    assert lb.resolve_blocks(board.parse_args(["--seed-blocks", "10:11,30:32"])) == [SeedBlock(10, 11),
                                                                                      SeedBlock(30, 32)]
    assert lb.resolve_mutant_refs("timid,frozen", "mobil", ["mobil", "nilsson"]) == ["timid", "frozen"]
    assert lb.resolve_mutant_refs("none", "fiss", ["mobil"]) == []
    assert lb.ref_label("timid", "mobil") == "timid(mobil)"


def test_terms_pairs_and_block_orders_by_hand(board):
    from evoscen_experiments.replication import consecutive_blocks

    def t(d, s, p, i_i=0.5):
        return {"D": d, "S": s, "P": p, "L": 0.5, "X": 0.5, "I": d, "I_s": s, "I_e": p, "I_i": i_i}

    terms = {"a": {0: t(0.8, 1.0, 1.0), 1: t(0.6, 0.5, 1.0, math.nan)}, "b": {0: t(0.4, 1.0, 0.5), 1: t(0.2, 0.5, 0.5)}}
    md, rows = lb.term_rows(terms, ["a", "b"])
    # a's D: 0.7 ± t(0.975, 1)·0.1414/√2 = 0.7 ± 12.706·0.1 = 0.7 ± 1.271; a's I_i defined in 1 of 2 episodes
    assert md[0][0] == "a" and md[0][1] == "0.700 ± 1.271" and md[0][9].endswith("(n 1)") and md[0][-1] == "2"
    assert rows[1][1:4] == [pytest.approx(0.3), pytest.approx(12.706204736 * 0.1), 2]
    values = {"a": {0: 0.8, 1: 0.6}, "b": {0: 0.4, 1: 0.2}, "c": {0: 0.5, 1: 0.7}}
    # orders per block: block 0..0 ranks a (0.8), c (0.5), b (0.4); block 1..1 c (0.7), a (0.6), b (0.2):
    # one discordant pair (a, c) of 3 -> τ = (2 − 1) / 3
    b_rows, taus = lb.block_orders(values, consecutive_blocks(0, 2, 1), ["a", "b", "c"])
    assert [(r[1], r[3]) for r in b_rows if r[0] == "1–1"] == [("a", 2), ("b", 3), ("c", 1)]
    assert taus == [["0–0", "1–1", pytest.approx(1 / 3), 2, 1, 3]]


@pytest.fixture(scope="module")
def bad_plugin(tmp_path_factory) -> Path:
    """A plug-in SUT ``bad_sut`` on a path of its own (an ``evoscen.sut`` entry point): its driver
    answers NaN throttle, which every runner refuses with one line."""
    root = tmp_path_factory.mktemp("plugin")
    (root / "bad_sut.py").write_text(
        "import numpy as np\nfrom evoscen_sim.model_registry import ModelSpec\n\n\nclass Bad:\n"
        "    def __init__(self, vehicles):\n        self.n = len(vehicles)\n\n"
        "    def act(self, view):\n        return np.full(self.n, np.nan), np.zeros(self.n, dtype=np.int64)\n\n\n"
        "SPEC = ModelSpec(name='bad_sut', roles=('sut',), factory=lambda v, p, c, r: Bad(v))\n", encoding="utf-8")
    info = root / "evoscen_bad_sut-0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: evoscen-bad-sut\nVersion: 0\n", encoding="utf-8")
    (info / "entry_points.txt").write_text("[evoscen.sut]\nbad_sut = bad_sut:SPEC\n", encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def small(tmp_path_factory, bad_plugin, env_with_path):
    """Two built-in SUTs, the failing plug-in and MOBIL's ``frozen`` as a reference, 2 blocks of 2 episodes of 50
    steps."""
    out = tmp_path_factory.mktemp("board") / "lb"
    env = env_with_path(bad_plugin)
    res = subprocess.run([sys.executable, "scripts/leaderboard.py", "--suts", "nilsson,mobil,bad_sut", "--seed-blocks", "7:8,9:10",
                          "--episode-steps", "50", "--mutant-refs", "frozen", "--jobs", "2", "--out", str(out)],
                         cwd=REPO, capture_output=True, text=True, timeout=300, check=False, env=env)
    return out, res


@pytest.mark.e2e
def test_ranked_table_and_paired_interval_by_hand(small):
    out, res = small
    assert res.returncode == 0, res.stderr
    for name in ("leaderboard.md", "leaderboard.csv", "episodes.csv", "leaderboard.png"):
        assert (out / name).stat().st_size > 0, name
    episodes = read_csv(out / "episodes.csv")
    assert sorted((e["sut"], int(e["seed"]), e["steps"]) for e in episodes) == [
        (s, seed, "50") for s in ("frozen(mobil)", "mobil", "nilsson") for seed in SEEDS]
    intel = {(e["sut"], int(e["seed"])): float(e["d"]) for e in episodes}
    mean = {s: sum(intel[(s, k)] for k in SEEDS) / 4 for s in ("frozen(mobil)", "mobil", "nilsson")}
    board = read_csv(out / "leaderboard.csv")
    ok = [r for r in board if r["status"] == "ok"]
    # ranked by mean D, highest first
    expected = sorted(mean, key=lambda s: -mean[s])
    assert [r["sut"] for r in ok] == expected and [r["rank"] for r in ok] == ["1", "2", "3"]
    for row in ok:
        assert float(row["d_mean"]) == pytest.approx(mean[row["sut"]])
        assert row["episodes"] == "4"
        terms = sum(float(row[f"{t}_mean"]) for t in ("p_is_s", "p_ie_l", "p_ii_x"))
        assert terms == pytest.approx(mean[row["sut"]])
    # the paired difference nilsson − mobil per episode: mean ± t(0.975, 3)·sd/√4
    d = [intel[("nilsson", k)] - intel[("mobil", k)] for k in SEEDS]
    d_mean = sum(d) / 4
    sd = math.sqrt(sum((x - d_mean) ** 2 for x in d) / 3)
    half = T975_DF3 * sd / math.sqrt(4)
    nilsson = next(r for r in ok if r["sut"] == "nilsson")
    assert float(nilsson["delta_d_vs_mobil_mean"]) == pytest.approx(d_mean)
    assert float(nilsson["delta_d_vs_mobil_ci95"]) == pytest.approx(half)
    assert nilsson["paired_n"] == "4" and nilsson["significant"] == str(int(abs(d_mean) > half))
    mobil = next(r for r in ok if r["sut"] == "mobil")
    assert mobil["delta_d_vs_mobil_mean"] == "nan" and mobil["paired_n"] == "0"
    text = (out / "leaderboard.md").read_text(encoding="utf-8")
    assert f"| 1 | {expected[0]} |" in text and "| reference |" in text and "TTC<3 s front /km" in text
    assert f"| 1 | {expected[0]} |" in res.stdout
    assert "blocks 7–8 and 9–10: τ = " in text and "## Every term" in text
    assert "| rank | rank range | letters | SUT | D ± 95 % | P·i_s·S (safety) | P·i_e·L (lane-change time) |" in text
    assert "this command's wall time" in text
    pairs = read_csv(out / "pairs.csv")
    assert [(r["a"], r["b"]) for r in pairs] == [(a, b) for i, a in enumerate(expected) for b in expected[i + 1:]]


@pytest.mark.e2e
def test_rank_ranges_letters_and_verdicts_agree_with_pairs_csv(small):
    out, res = small
    assert res.returncode == 0, res.stderr
    intel = {(e["sut"], int(e["seed"])): float(e["d"]) for e in read_csv(out / "episodes.csv")}
    pairs = read_csv(out / "pairs.csv")
    above = set()
    for p in pairs:
        # the verdict's interval by hand: mean ± z(0.975)·sd/√n over the 4 paired episodes
        d = [intel[(p["a"], k)] - intel[(p["b"], k)] for k in SEEDS]
        mean = sum(d) / 4
        half = Z975 * math.sqrt(sum((x - mean) ** 2 for x in d) / 3) / 2
        low, high = float(p["delta_d_low"]), float(p["delta_d_high"])
        assert (float(p["delta_d_mean"]), low, high) == pytest.approx((mean, mean - half, mean + half), abs=1e-9)
        expected = ("a_higher" if low > 0 else "b_higher" if high < 0 else
                    "equivalent" if -0.005 < low and high < 0.005 else "unresolved")
        assert p["verdict"] == expected and p["n"] == "4"
        assert (p["episodes_needed"] != "") == (expected == "unresolved" and mean != 0)
        blocks = (p["verdict_block_7_8"], p["verdict_block_9_10"])
        assert p["contradiction"] == str(int({"a_higher", "b_higher"} <= set(blocks)))
        if expected == "a_higher":
            above.add((p["a"], p["b"]))
        elif expected == "b_higher":
            above.add((p["b"], p["a"]))
    ok = [r for r in read_csv(out / "leaderboard.csv") if r["status"] == "ok"]
    for r in ok:
        s = r["sut"]
        assert int(r["rank_best"]) == 1 + sum(lo == s for _, lo in above)
        assert int(r["rank_worst"]) == len(ok) - sum(hi == s for hi, _ in above)
    letters = {r["sut"]: set(r["letters"]) for r in ok}
    for p in pairs:
        assert bool(letters[p["a"]] & letters[p["b"]]) == ((p["a"], p["b"]) not in above and (p["b"], p["a"]) not in above)
    assert "pairs: " in res.stdout and "contradictions" in res.stdout


@pytest.mark.e2e
def test_a_failing_sut_is_reported_as_failed_not_dropped(small):
    out, res = small
    assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr
    assert [line for line in res.stderr.splitlines() if line.startswith("failed: ")] == [BAD_LINE]
    row = read_csv(out / "leaderboard.csv")[-1]
    assert (row["rank"], row["sut"], row["status"]) == ("", "bad_sut", "failed")
    assert row["error"] == BAD_LINE.removeprefix("failed: bad_sut: ")
    assert "| – | – | – | bad_sut | failed (4/4 episodes): InputError: sut model 'bad_sut'" in (out / "leaderboard.md").read_text(
        encoding="utf-8")
    assert "bad_sut" not in {e["sut"] for e in read_csv(out / "episodes.csv")}
