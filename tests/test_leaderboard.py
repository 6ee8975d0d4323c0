"""The planner leaderboard (scripts/leaderboard.py): which SUTs it ranks, the ranking, the paired
interval against the reference (by hand from the per-episode CSV), a failing plug-in, bad input."""

from __future__ import annotations

import csv
import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
T975_DF2 = 4.302652730  # Student-t 0.975 quantile, 2 degrees of freedom
BAD_LINE = ("failed: bad_sut: 3/3 episodes: InputError: sut model 'bad_sut': act() returned throttle nan "
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
    suts = board.installed_suts()
    assert suts[:4] == ["level0", "nilsson", "mobil", "stackelberg"]  # the built-ins, in registration order
    assert "mutant" not in suts
    assert board.resolve_suts("all", "mobil") == suts


def test_ranked_by_mean_intelligence_ties_by_name_undefined_last(board):
    means = {"b": 0.5, "a": 0.5, "c": 0.7, "d": math.nan, "e": 0.1}
    assert board.ranked(means) == ["c", "a", "b", "e", "d"]


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
])
def test_bad_input_is_one_line_and_exit_2_before_anything_is_written(board, tmp_path, capsys, args, expected):
    out = tmp_path / "out"
    assert board.main([*args, "--out", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith(expected), err
    assert not out.exists()


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
    """Two built-in SUTs and the failing plug-in, 3 episodes of 50 steps."""
    out = tmp_path_factory.mktemp("board") / "lb"
    env = env_with_path(bad_plugin)
    res = subprocess.run([sys.executable, "scripts/leaderboard.py", "--suts", "nilsson,mobil,bad_sut", "--episodes", "3",
                          "--episode-steps", "50", "--first-seed", "7", "--jobs", "2", "--out", str(out)],
                         cwd=REPO, capture_output=True, text=True, timeout=300, check=False, env=env)
    return out, res


@pytest.mark.e2e
def test_ranked_table_and_paired_interval_by_hand(small):
    out, res = small
    assert res.returncode == 0, res.stderr
    for name in ("leaderboard.md", "leaderboard.csv", "episodes.csv", "leaderboard.png"):
        assert (out / name).stat().st_size > 0, name
    episodes = read_csv(out / "episodes.csv")
    assert sorted((e["sut"], e["seed"], e["steps"]) for e in episodes) == [
        (s, str(seed), "50") for s in ("mobil", "nilsson") for seed in (7, 8, 9)]
    intel = {(e["sut"], int(e["seed"])): float(e["intelligence"]) for e in episodes}
    mean = {s: sum(intel[(s, k)] for k in (7, 8, 9)) / 3 for s in ("mobil", "nilsson")}
    board = read_csv(out / "leaderboard.csv")
    ok = [r for r in board if r["status"] == "ok"]
    # ranked by mean intelligence, highest first
    expected = sorted(mean, key=lambda s: -mean[s])
    assert [r["sut"] for r in ok] == expected and [r["rank"] for r in ok] == ["1", "2"]
    for row in ok:
        assert float(row["intelligence_mean"]) == pytest.approx(mean[row["sut"]])
        assert row["episodes"] == "3"
        terms = sum(float(row[f"{t}_weighted_mean"]) for t in ("safety", "efficiency", "interaction"))
        assert terms == pytest.approx(mean[row["sut"]])
    # the paired difference nilsson − mobil per episode: mean ± t(0.975, 2)·sd/√3
    d = [intel[("nilsson", k)] - intel[("mobil", k)] for k in (7, 8, 9)]
    d_mean = sum(d) / 3
    sd = math.sqrt(sum((x - d_mean) ** 2 for x in d) / 2)
    half = T975_DF2 * sd / math.sqrt(3)
    nilsson = next(r for r in ok if r["sut"] == "nilsson")
    assert float(nilsson["d_intelligence_vs_mobil_mean"]) == pytest.approx(d_mean)
    assert float(nilsson["d_intelligence_vs_mobil_ci95"]) == pytest.approx(half)
    assert nilsson["paired_n"] == "3" and nilsson["significant"] == str(int(abs(d_mean) > half))
    mobil = next(r for r in ok if r["sut"] == "mobil")
    assert mobil["d_intelligence_vs_mobil_mean"] == "nan" and mobil["paired_n"] == "0"
    text = (out / "leaderboard.md").read_text(encoding="utf-8")
    assert f"| 1 | {expected[0]} |" in text and "| reference |" in text and "TTC<3 s front /km" in text
    assert f"| 1 | {expected[0]} |" in res.stdout


@pytest.mark.e2e
def test_a_failing_sut_is_reported_as_failed_not_dropped(small):
    out, res = small
    assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr
    assert [line for line in res.stderr.splitlines() if line.startswith("failed: ")] == [BAD_LINE]
    row = read_csv(out / "leaderboard.csv")[-1]
    assert (row["rank"], row["sut"], row["status"]) == ("", "bad_sut", "failed")
    assert row["error"] == BAD_LINE.removeprefix("failed: bad_sut: ")
    assert "| – | bad_sut | failed (3/3 episodes): InputError: sut model 'bad_sut'" in (out / "leaderboard.md").read_text(
        encoding="utf-8")
    assert "bad_sut" not in {e["sut"] for e in read_csv(out / "episodes.csv")}
