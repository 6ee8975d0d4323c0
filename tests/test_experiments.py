"""The method's experiments at reduced size: tables, files, intervals, resumption, bad input."""

from __future__ import annotations

import csv
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
from scipy import stats

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.e2e


def script(name: str, *args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, f"scripts/{name}", *map(str, args)], cwd=REPO, capture_output=True,
                          text=True, timeout=300, check=False)


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def intelligence(tmp_path_factory):
    out = tmp_path_factory.mktemp("exp") / "intel"
    res = script("experiment_intelligence.py", "--out", out, "--seeds", 2, "--steps", 200, "--jobs", 2)
    return out, res


def test_intelligence_table_and_files(intelligence):
    out, res = intelligence
    assert res.returncode == 0, res.stderr
    for name in ("intelligence.csv", "intelligence.md", "rounds.csv", "ttc.png", "speed.png"):
        assert (out / name).stat().st_size > 0, name
    table = read_csv(out / "intelligence.csv")
    assert [r["sut"] for r in table] == ["nilsson", "mobil", "stackelberg"]
    rounds = read_csv(out / "rounds.csv")
    assert len(rounds) == 6 and {r["steps"] for r in rounds} == {"200"}
    for row in table:
        vals = [float(r["i"]) for r in rounds if r["sut"] == row["sut"]]
        mean = sum(vals) / 2
        half = stats.t.ppf(0.975, 1) * abs(vals[0] - vals[1]) / math.sqrt(2) / math.sqrt(2)
        assert float(row["i_mean"]) == pytest.approx(mean)
        assert float(row["i_ci95"]) == pytest.approx(half)
        # the method's I is the sum of its three weighted terms (each averaged over seeds)
        total = sum(float(row[f"{k}_weighted_mean"]) for k in ("safety", "efficiency", "interaction"))
        assert total == pytest.approx(mean)
    assert "| mobil |" in res.stdout and "| SUT | I_s (weighted)" in res.stdout
    # surrogate-safety rates per SUT-km: each SUT's mean ± interval of its rounds' rates
    ssm = read_csv(out / "surrogate_safety.csv")
    assert [r["sut"] for r in ssm] == ["nilsson", "mobil", "stackelberg"]
    for row in ssm:
        for col in ("front_ttc_episodes_per_km", "rear_pet_events_per_km", "rear_tit_s2_per_km"):
            vals = [float(r[f"ssm_{col}"]) for r in rounds if r["sut"] == row["sut"]]
            assert float(row[f"{col}_mean"]) == pytest.approx(sum(vals) / 2)
            assert float(row[f"{col}_ci95"]) == pytest.approx(stats.t.ppf(0.975, 1) * abs(vals[0] - vals[1]) / 2,
                                                              abs=1e-12)
    assert "| SUT | TTC<3 s front /km" in res.stdout


def test_intelligence_ends_with_its_start_up_and_throughput(intelligence):
    out, res = intelligence
    assert res.returncode == 0, res.stderr
    last = res.stdout.strip().splitlines()[-1]
    timing = json.loads((out / "timing.json").read_text())
    assert last == timing["line"]
    assert re.fullmatch(r"wall [\d.,]+ s: start-up [\d.,]+ s \(set-up [\d.,]+ s, Ray [\d.,]+ s, workers' first task "
                        r"[\d.,]+ s\), 6 runs × 200 SUT steps = [\d,]+ SUT-steps/s", last), last
    parts = timing["setup_s"] + timing["ray_s"] + timing["first_task_s"]
    assert timing["startup_s"] == pytest.approx(parts) and 0 < parts <= timing["wall_s"]
    assert timing["ray_s"] > 0 and timing["first_task_s"] > 0 and (timing["runs"], timing["sut_steps"]) == (6, 1200)
    assert timing["sut_steps_per_s"] == pytest.approx(1200 / timing["wall_s"])
    assert "SUT-steps/s" in res.stderr  # the progress bar: the same measure as it goes


def test_intelligence_paired_comparisons(intelligence):
    out, res = intelligence
    assert res.returncode == 0, res.stderr
    rounds = read_csv(out / "rounds.csv")
    score = {(r["sut"], int(r["seed"])): float(r["d"]) for r in rounds}  # evaluation.score_form's default
    pairs = read_csv(out / "paired.csv")
    assert [(p["sut_a"], p["sut_b"]) for p in pairs] == [("nilsson", "mobil"), ("nilsson", "stackelberg"),
                                                         ("mobil", "stackelberg")]
    for p in pairs:
        d = [score[(p["sut_a"], s)] - score[(p["sut_b"], s)] for s in (0, 1)]
        half = stats.t.ppf(0.975, 1) * abs(d[0] - d[1]) / math.sqrt(2) / math.sqrt(2)
        assert float(p["delta_d_mean"]) == pytest.approx(sum(d) / 2)
        assert float(p["delta_d_ci95"]) == pytest.approx(half)
        assert p["seeds"] == "2" and p["significant"] == str(int(abs(sum(d) / 2) > half))
    assert "paired by seed" in (out / "intelligence.md").read_text()
    # the efficiency term, paired the same way (rounds.csv holds the unweighted I_e)
    eff = {(r["sut"], int(r["seed"])): float(r["i_e"]) for r in rounds}
    for p in read_csv(out / "paired_efficiency.csv"):
        d = [eff[(p["sut_a"], s)] - eff[(p["sut_b"], s)] for s in (0, 1)]
        assert float(p["d_efficiency_mean"]) == pytest.approx(sum(d) / 2)
        assert float(p["d_efficiency_ci95"]) == pytest.approx(stats.t.ppf(0.975, 1) * abs(d[0] - d[1]) / 2)
    assert "I_e(A) − I_e(B), paired by seed" in (out / "intelligence.md").read_text()


def test_intelligence_resumes_without_recomputing(intelligence):
    out, _ = intelligence
    files = sorted((out / "runs").glob("*/result.json"))
    assert len(files) == 6
    stamps = {f: f.stat().st_mtime_ns for f in files}
    res = script("experiment_intelligence.py", "--out", out, "--seeds", 2, "--steps", 200, "--jobs", 2)
    assert res.returncode == 0 and "6 rounds already done" in res.stderr
    assert {f: f.stat().st_mtime_ns for f in files} == stamps
    # a third seed runs only the three new rounds
    res = script("experiment_intelligence.py", "--out", out, "--seeds", 3, "--steps", 200, "--jobs", 2)
    assert res.returncode == 0 and "6 rounds already done" in res.stderr
    assert len(list((out / "runs").glob("*/result.json"))) == 9


def test_complexity_table_and_files(tmp_path):
    out = tmp_path / "cx"
    res = script("experiment_complexity.py", "--out", out, "--rounds", 2, "--steps", 200, "--jobs", 2,
                 "--scenarios", "evolving,nilsson,mobil")
    assert res.returncode == 0, res.stderr
    for name in ("complexity.csv", "complexity.md", "rounds.csv", "complexity.png"):
        assert (out / name).stat().st_size > 0, name
    table = read_csv(out / "complexity.csv")
    assert [r["scenario"] for r in table] == ["evolving", "nilsson", "mobil"]
    assert [r["bv_driver"] for r in table][1:] == ["nilsson", "mobil"]
    rounds = read_csv(out / "rounds.csv")
    assert len(rounds) == 6 and {r["windows"] for r in rounds} == {"2"}
    for row in table:
        rs = [r for r in rounds if r["scenario"] == row["scenario"]]
        lc, ad, e = (sum(float(r[k]) for r in rs) / 2 for k in ("lc", "ad", "e"))
        assert float(row["lc_mean"]) == pytest.approx(lc) and float(row["ad_mean"]) == pytest.approx(ad)
        c = 0.4 * (1 - math.exp(-e / 25)) + 0.3 * (2 - math.exp(-lc / 8) - math.exp(-ad / 1400))
        assert float(row["complexity"]) == pytest.approx(c)
    assert "| evolving |" in res.stdout
    # on the default make-up (highD's cars and trucks), the baselines too: every round had trucks among its
    # 20 BVs (floor(20 x 0.229) = 4 or 5: docs/bv-profiles.md)
    assert {(r["makeup"], r["bv_trucks"] in ("4", "5")) for r in rounds} == {("highd", True)}


def test_sensitivity_paired_by_seed_tables_and_resumption(tmp_path):
    out = tmp_path / "sens"
    args = ("--out", out, "--seeds", 3, "--steps", 300, "--jobs", 2, "--base", "mobil",
            "--mutants", "stale,weak_braking", "--scenarios", "evolving,level0")
    res = script("experiment_sensitivity.py", *args)
    assert res.returncode == 0, res.stderr
    for name in ("sensitivity.md", "sensitivity.csv", "mutation_scores.csv", "rounds.csv", "sensitivity.png"):
        assert (out / name).stat().st_size > 0, name
    rounds = read_csv(out / "rounds.csv")
    assert len(rounds) == 2 * 3 * 3  # scenarios x (intact + 2 mutants) x seeds
    val = {(r["scenario"], r["variant"], int(r["seed"])): float(r["d"]) for r in rounds}
    t2 = stats.t.ppf(0.975, 2)
    rows = read_csv(out / "sensitivity.csv")
    assert [(r["scenario"], r["mutant"]) for r in rows] == [("evolving", "stale"), ("evolving", "weak_braking"),
                                                            ("level0", "stale"), ("level0", "weak_braking")]
    for r in rows:
        d = [val[(r["scenario"], "intact", s)] - val[(r["scenario"], r["mutant"], s)] for s in (0, 1, 2)]
        mean = sum(d) / 3
        sd = math.sqrt(sum((x - mean) ** 2 for x in d) / 2)
        half = t2 * sd / math.sqrt(3)
        assert float(r["delta_d_mean"]) == pytest.approx(mean)
        assert float(r["delta_d_ci95"]) == pytest.approx(half)
        assert r["detected"] == str(int(mean - half > 0)) and r["seeds"] == "3"
        assert r["class"] == {"stale": "perception", "weak_braking": "control"}[r["mutant"]]
        a = [val[(r["scenario"], "intact", s)] for s in (0, 1, 2)]
        b = [val[(r["scenario"], r["mutant"], s)] for s in (0, 1, 2)]
        assert float(r["pairing_r"]) == pytest.approx(stats.pearsonr(a, b)[0])
    scores = read_csv(out / "mutation_scores.csv")
    for sc in scores:
        hits = [r for r in rows if r["scenario"] == sc["scenario"] and r["detected"] == "1"]
        assert int(sc["detected"]) == len(hits) and sc["mutants"] == "2"
        assert float(sc["mutation_score"]) == pytest.approx(len(hits) / 2)
        r_s = sorted(float(r["pairing_r"]) for r in rows if r["scenario"] == sc["scenario"])
        assert float(sc["median_pairing_r"]) == pytest.approx(sum(r_s) / 2)  # the median of two
    assert "| evolving | learned | mobil |" in res.stdout
    res = script("experiment_sensitivity.py", *args)  # resumable: nothing recomputed
    assert res.returncode == 0 and "18 rounds already done" in res.stderr


def _paired_by_hand(val: dict, variant: str, seeds: list[int]) -> tuple[float, float]:
    d = [val[("intact", s)] - val[(variant, s)] for s in seeds]
    mean = sum(d) / len(d)
    sd = math.sqrt(sum((x - mean) ** 2 for x in d) / (len(d) - 1))
    return mean, stats.t.ppf(0.975, len(d) - 1) * sd / math.sqrt(len(d))


def test_sensitivity_episodes_design(tmp_path):
    out = tmp_path / "ep"
    res = script("experiment_sensitivity.py", "--out", out, "--design", "episodes", "--episodes", 2,
                 "--episode-steps", 20, "--first-seed", 5, "--jobs", 1, "--mutants", "stale", "--scenarios", "level0")
    assert res.returncode == 0, res.stderr
    rounds = read_csv(out / "rounds.csv")
    assert sorted((r["variant"], int(r["seed"])) for r in rounds) == [("intact", 5), ("intact", 6), ("stale", 5),
                                                                     ("stale", 6)]
    assert {(r["design"], r["steps"]) for r in rounds} == {("episodes", "20")}
    val = {(r["variant"], int(r["seed"])): float(r["d"]) for r in rounds}
    (row,) = read_csv(out / "sensitivity.csv")
    mean, half = _paired_by_hand(val, "stale", [5, 6])
    assert float(row["delta_d_mean"]) == pytest.approx(mean)
    assert float(row["delta_d_ci95"]) == pytest.approx(half) and row["seeds"] == "2"
    assert ("Design episodes: 2 episodes (seeds 5..6) x 20 steps = 40 SUT steps per variant and scenario; the "
            "warm-up (traffic.warmup_s = 20 s, 200 steps) runs before every run and is extra compute") in res.stdout
    assert "paired by episode" in (out / "sensitivity.md").read_text()
    # the surrogate-safety rates per SUT-km: paired mutant − intact from the rounds' own rates
    for col in ("ssm_front_ttc_episodes_per_km", "ssm_rear_pet_events_per_km", "ssm_rear_tit_s2_per_km"):
        rate = {(r["variant"], int(r["seed"])): float(r[col]) for r in rounds}
        d = [rate[("stale", s)] - rate[("intact", s)] for s in (5, 6)]
        assert float(row[f"d_{col}_mean"]) == pytest.approx(sum(d) / 2)
        assert float(row[f"d_{col}_ci95"]) == pytest.approx(stats.t.ppf(0.975, 1) * abs(d[0] - d[1]) / 2, abs=1e-12)
    assert row["ssm_n"] == "2"
    assert "Surrogate safety of the SUT per SUT-km" in (out / "sensitivity.md").read_text()


def test_sensitivity_seed_blocks_and_a_base_a_mutant_does_not_apply_to(tmp_path):
    out = tmp_path / "blk"
    res = script("experiment_sensitivity.py", "--out", out, "--seed-blocks", "5:6,9:10", "--episode-steps", 20,
                 "--jobs", 1, "--mutants", "frozen", "--scenarios", "level0", "--base", "mobil,level0")
    assert res.returncode == 0, res.stderr
    rounds = read_csv(out / "rounds.csv")
    # frozen does not apply to level0 (it changes no lane by choice): not run there
    assert sorted({(r["base"], r["variant"]) for r in rounds}) == [("level0", "intact"), ("mobil", "frozen"),
                                                                   ("mobil", "intact")]
    val = {(r["variant"], int(r["seed"])): float(r["d"]) for r in rounds if r["base"] == "mobil"}
    blocks = read_csv(out / "blocks.csv")
    assert [(b["base"], b["mutant"], b["block_first_seed"], b["block_last_seed"]) for b in blocks] == [
        ("mobil", "frozen", "5", "6"), ("mobil", "frozen", "9", "10")]
    for b, seeds in zip(blocks, ([5, 6], [9, 10])):
        mean, half = _paired_by_hand(val, "frozen", seeds)
        assert float(b["delta_d_mean"]) == pytest.approx(mean) and b["n"] == "2"
        assert float(b["delta_d_ci95"]) == pytest.approx(half)
        assert b["detected"] == str(int(mean - half > 0)) and b["better"] == str(int(mean + half < 0))
    scores = {r["base"]: r for r in read_csv(out / "mutation_scores.csv")}
    assert scores["mobil"]["contradictions"] == "0"  # profiles are not counted
    assert (scores["level0"]["mutants"], scores["level0"]["not_applicable"]) == ("0", "1")
    # frozen is a profile, not a defect: its blocks are reported, never counted
    assert (scores["mobil"]["mutants"], scores["mobil"]["detected"]) == ("0", "0")
    assert scores["mobil"]["detected_per_block"] == "0;0" and scores["mobil"]["min_detected_over_blocks"] == "0"
    assert [r["role"] for r in read_csv(out / "sensitivity.csv")] == ["profile"]
    assert [(r["base"], r["mutant"]) for r in read_csv(out / "not_applicable.csv")] == [("level0", "frozen")]
    (sp,) = read_csv(out / "speeds.csv")  # mutant − intact speeds, paired over all 4 episodes
    assert (sp["base"], sp["mutant"], sp["n"]) == ("mobil", "frozen", "4")
    text = (out / "sensitivity.md").read_text()
    assert "| frozen | decision | not applicable to level0 |" in text and "ΔD block 9–10" in text
    assert "| frozen | decision, profile |" in text and "not counted: frozen (a profile, not a defect)" in text
    assert "detected 0/0 applicable (base, mutant) pairs" in text
    assert "contradictions (worse in one block, better in another) 0" in text


def test_sensitivity_compare_designs(tmp_path):
    out = tmp_path / "cmp"
    res = script("experiment_sensitivity.py", "--out", out, "--compare-designs", "--episodes", 4, "--episode-steps",
                 20, "--seeds", 2, "--steps", 40, "--jobs", 2, "--mutants", "stale", "--scenarios", "level0")
    assert res.returncode == 0, res.stderr
    for name in ("designs.md", "designs.csv", "designs_mutants.csv", "episodes/sensitivity.md", "long/rounds.csv"):
        assert (out / name).stat().st_size > 0, name
    (mrow,) = read_csv(out / "designs_mutants.csv")
    rows = {r["design"]: r for r in read_csv(out / "designs.csv")}
    for design, seeds, steps in (("episodes", [0, 1, 2, 3], 20), ("long", [4, 5], 40)):  # disjoint seeds
        rounds = read_csv(out / design / "rounds.csv")
        assert sorted({int(r["seed"]) for r in rounds}) == seeds and {r["steps"] for r in rounds} == {str(steps)}
        val = {(r["variant"], int(r["seed"])): float(r["d"]) for r in rounds}
        mean, half = _paired_by_hand(val, "stale", seeds)
        assert float(mrow[f"{design}_delta_d_mean"]) == pytest.approx(mean)
        assert float(mrow[f"{design}_delta_d_ci95"]) == pytest.approx(half)
        assert mrow[f"{design}_n"] == str(len(seeds)) and mrow[f"{design}_detected"] == str(int(mean - half > 0))
        row = rows[design]
        assert float(row["median_ci95"]) == pytest.approx(half)  # one mutant: its half-width
        assert row["detected"] == mrow[f"{design}_detected"] and row["sut_steps"] == "80"  # 4 x 20 = 2 x 40
        assert row["warmup_steps"] == str(200 * len(seeds))
        assert row["simulated_steps"] == str(80 + 200 * len(seeds))
    assert "sharper design: " in res.stdout


def test_sensitivity_sequential_verdicts_and_resumption(tmp_path):
    """--sequential through the script: rounds of 4 paired episodes up to 8; each comparison's verdict, interval
    and episodes follow from rounds.csv; a rerun computes nothing."""
    from evoscen_experiments.sequential import verdict

    out = tmp_path / "seq"
    args = ("--out", out, "--sequential", "--budget", 8, "--round-size", 4, "--episode-steps", 20, "--first-seed", 5,
            "--mutants", "stale,frozen", "--scenarios", "level0", "--jobs", 2)
    res = script("experiment_sensitivity.py", *args)
    assert res.returncode == 0, res.stderr
    rounds = read_csv(out / "rounds.csv")
    d = {(r["variant"], int(r["seed"])): float(r["d"]) for r in rounds}
    rows = {r["mutant"]: r for r in read_csv(out / "verdicts.csv")}
    assert [(r["role"], r["budget"]) for r in rows.values()] == [("defect", "8"), ("profile", "8")]
    for m, row in rows.items():
        seeds = sorted(s for v, s in d if v == m)
        n = int(row["episodes"])
        assert seeds == list(range(5, 5 + n)) and n in (4, 8)  # the first n seeds, in order; only looks' sizes
        diffs = [d[("intact", s)] - d[(m, s)] for s in seeds]
        assert float(row["delta_d_mean"]) == pytest.approx(sum(diffs) / n)
        v = verdict(diffs, round_size=4, budget=8, delta=0.005, spending="pocock")  # the default
        assert (v.episodes, v.looks) == (n, int(row["looks"])) and v.low == pytest.approx(float(row["delta_d_low"]))
        word = row["verdict"]
        # open after its episodes: unresolved (a defect at the budget; the profile frozen after the first look)
        assert word == {"a_higher": "worse", "b_higher": "better", "continue": "unresolved"}.get(v.verdict, v.verdict)
        profile = row["role"] == "profile"
        assert (word == "worse") == (float(row["delta_d_low"]) > 0) and (word != "unresolved" or n == (4 if profile else 8))
    # the intact seeds run while any mutant needs them, once
    assert sorted(s for v, s in d if v == "intact") == list(range(5, 5 + max(int(r["episodes"]) for r in rows.values())))
    (count,) = read_csv(out / "verdict_counts.csv")
    assert (count["defects"], count["profiles"], count["runs"]) == ("1", "1", str(len(rounds)))
    assert count["worse"] == str(int(rows["stale"]["verdict"] == "worse"))  # frozen never counted
    assert "## Sequential verdicts" in (out / "sensitivity.md").read_text()
    files = sorted((out / "runs").glob("*/result.json"))
    stamps = {f: f.stat().st_mtime_ns for f in files}
    res = script("experiment_sensitivity.py", *args)  # resumable: the same looks read back, nothing recomputed
    assert res.returncode == 0 and "rounds already done" in res.stderr
    assert {f: f.stat().st_mtime_ns for f in sorted((out / "runs").glob("*/result.json"))} == stamps
    assert {r["mutant"]: r["verdict"] for r in read_csv(out / "verdicts.csv")} == {
        m: r["verdict"] for m, r in rows.items()}


@pytest.mark.parametrize("name, args, expected", [
    ("experiment_sensitivity.py", ["--design", "long", "--episodes", "5"],
     "error: --episodes does not apply to --design long"),
    ("experiment_sensitivity.py", ["--compare-designs", "--seeds", "5"],
     "error: --compare-designs needs equal compute: episodes 100 x 300 = 30000 SUT steps per variant, long 5 x 3000"),
    ("experiment_sensitivity.py", ["--mutants", "stale,bogus"], "error: --mutants: unknown mutant 'bogus'"),
    ("experiment_sensitivity.py", ["--sequential", "--seeds", "5"], "error: --sequential and --seeds together"),
    ("experiment_sensitivity.py", ["--base", "mobil,mobil"], "error: --base 'mobil,mobil': expected distinct"),
    ("experiment_sensitivity.py", ["--seeds", "-1"], "error: --seeds = '-1': expected an integer >= 1"),
    ("experiment_sensitivity.py", ["--scenarios", "evolving,nope"], "error: command line: key 'bvs.driver' = 'nope'"),
    ("experiment_intelligence.py", ["--seeds", "0"], "error: --seeds = '0': expected an integer >= 1"),
    ("experiment_intelligence.py", ["--suts", "nilsson,bogus"], "error: command line: key 'sut.model' = 'bogus'"),
    ("experiment_complexity.py", ["--rounds", "x"], "error: --rounds = 'x': expected an integer >= 1"),
    ("experiment_complexity.py", ["--scenarios", "evolving,nope"], "error: command line: key 'bvs.driver' = 'nope'"),
])
def test_bad_input_is_one_line(tmp_path, name, args, expected):
    res = script(name, "--out", tmp_path / "o", *args)
    assert res.returncode == 2
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(expected), lines
