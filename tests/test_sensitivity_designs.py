"""The sensitivity experiment's test designs (scripts/experiment_sensitivity.py, its logic in
evoscen_experiments.sensitivity_experiment and sensitivity_tables), in-process: argument validation, the
rounds a design builds, equal compute, the design comparison table (values by hand)."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

from evoscen_experiments import sensitivity_experiment as se
from evoscen_experiments import sensitivity_tables as st
from evoscen_experiments.sensitivity import Design, design_compute, summarise_design

REPO = Path(__file__).resolve().parents[1]
T975_DF1 = 12.706204736   # Student-t 0.975 quantile, 1 degree of freedom
T975_DF3 = 3.182446305    # 3 degrees of freedom


@pytest.fixture(scope="module")
def exp():
    """The experiment script as a module (scripts/ on sys.path for its _bootstrap import)."""
    import sys

    sys.path.insert(0, str(REPO / "scripts"))
    try:
        spec = importlib.util.spec_from_file_location("experiment_sensitivity", REPO / "scripts" /
                                                      "experiment_sensitivity.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(REPO / "scripts"))
    return module


@pytest.mark.parametrize("args, expected", [
    (["--design", "short"], "error: --design 'short': expected one of episodes, long"),
    (["--design", "long", "--episodes", "5"], "error: --episodes does not apply to --design long (episodes: "
                                              "--episodes, --episode-steps; long: --seeds, --steps)"),
    (["--design", "episodes", "--steps", "300"], "error: --steps does not apply to --design episodes"),
    (["--episode-steps", "300", "--seeds", "3"], "error: --episode-steps (episodes design) and --seeds (long design) "
                                                 "together: choose one --design, or --compare-designs to run both"),
    (["--compare-designs", "--design", "episodes"], "error: --compare-designs runs both designs: leave out --design"),
    (["--long-first-seed", "5"], "error: --long-first-seed applies with --compare-designs only"),
    (["--compare-designs", "--episodes", "50"], "error: --compare-designs needs equal compute: episodes 50 x 300 = "
                                                "15000 SUT steps per variant, long 10 x 3000 = 30000"),
    (["--compare-designs", "--episode-steps", "600"], "error: --compare-designs needs equal compute: episodes "
                                                      "100 x 600 = 60000 SUT steps per variant, long 10 x 3000 = "
                                                      "30000"),
    (["--design", "episodes", "--episodes", "0"], "error: --episodes = '0': expected an integer >= 1"),
    (["--episode-steps", "x"], "error: --episode-steps = 'x': expected an integer >= 1"),
    (["--compare-designs", "--long-first-seed", "-3"], "error: --long-first-seed = '-3': expected an integer >= 0"),
    (["--seeds", "0"], "error: --seeds = '0': expected an integer >= 1"),
    (["--episodes", "5", "--blocks", "2"], "error: --episodes and --blocks together: a blocked design's runs are "
                                           "its blocks' seeds"),
    (["--seed-blocks", "0:9", "--blocks", "2"], "error: --seed-blocks and --blocks together: the blocks name their "
                                                "seeds"),
    (["--seed-blocks", "0:9,5:12"], "error: --seed-blocks: blocks 0:9 and 5:12 overlap"),
    (["--compare-designs", "--blocks", "2"], "error: --blocks does not apply with --compare-designs"),
    (["--blocks", "0"], "error: --blocks = '0': expected an integer >= 1"),
])
def test_bad_design_arguments_are_one_line(exp, tmp_path, capsys, args, expected):
    out = tmp_path / "o"
    assert exp.main(["--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(expected), lines
    assert not out.exists()  # nothing started


def test_compare_designs_accepts_equal_compute_other_than_the_default(exp):
    # 100 x 600 = 20 x 3000 = 60,000: equal, accepted (the case above is 100 x 600 against 10 x 3000)
    ep, lg = se.resolve_designs(exp.parse_args(["--compare-designs", "--seeds", "20", "--episode-steps", "600"]))
    assert (ep.runs * ep.steps, lg.runs * lg.steps) == (60_000, 60_000)


def test_which_design_runs(exp):
    def designs(*args: str) -> list[tuple]:
        return [(d.name, d.runs, d.steps, d.first_seed) for d in se.resolve_designs(exp.parse_args(list(args)))]

    default = {"episodes": ("episodes", 100, 300, 0), "long": ("long", 10, 3000, 0)}[se.DEFAULT_DESIGN]
    assert designs() == [default]
    assert designs("--seeds", "3", "--steps", "300") == [("long", 3, 300, 0)]          # the old flags: long
    assert designs("--steps", "500", "--first-seed", "4") == [("long", 10, 500, 4)]
    assert designs("--episodes", "7") == [("episodes", 7, 300, 0)]                      # its own flags: episodes
    assert designs("--design", "episodes") == [("episodes", 100, 300, 0)]
    assert designs("--design", "long", "--seeds", "2") == [("long", 2, 3000, 0)]
    # both at equal compute; the long design's seeds follow the episodes' unless given
    assert designs("--compare-designs", "--first-seed", "20000") == [("episodes", 100, 300, 20000),
                                                                     ("long", 10, 3000, 20100)]
    assert designs("--compare-designs", "--first-seed", "20000", "--long-first-seed", "30000") == [
        ("episodes", 100, 300, 20000), ("long", 10, 3000, 30000)]
    assert designs("--compare-designs", "--episodes", "4", "--episode-steps", "30", "--seeds", "2",
                   "--steps", "60") == [("episodes", 4, 30, 0), ("long", 2, 60, 4)]


def test_episodes_design_builds_n_x_variants_paired_rounds(exp):
    (design,) = se.resolve_designs(exp.parse_args(["--design", "episodes", "--episodes", "3", "--episode-steps",
                                                    "20", "--first-seed", "7"]))
    rounds, meta = se.build_rounds([design], ["mobil"], ["level0", "evolving", "nilsson", "mobil"],
                                    ["stale", "tailgating"], None)
    assert len(rounds) == 3 * 3 * 4  # episodes x (intact + 2 mutants) x scenarios
    # the default scenarios run on the default make-up (highD's cars and trucks), the baselines too: a
    # baseline differs from the evolving scenario only in the cars' driver (docs/bv-profiles.md)
    assert {r.cfg.bvs.makeup for r in rounds} == {"highd"}
    assert len({r.key for r in rounds}) == len(rounds) == len(meta)
    assert {r.cfg.steps for r in rounds} == {20}
    assert {meta[r.key][0] for r in rounds} == {"episodes"}
    by = {}
    for r in rounds:
        _, scenario, base, variant = meta[r.key]
        by.setdefault((scenario, variant), {})[r.cfg.seed] = r.cfg
    assert sorted(by) == [(s, v) for s in ("evolving", "level0", "mobil", "nilsson")
                          for v in ("intact", "stale", "tailgating")]
    for (scenario, variant), cfgs in by.items():
        assert sorted(cfgs) == [7, 8, 9]  # every variant on the same episodes (seeds)
        for cfg in cfgs.values():
            assert cfg.bvs.driver == {"level0": "level0", "evolving": "learned", "nilsson": "nilsson",
                                      "mobil": "mobil"}[scenario]
            assert cfg.sut.model == ("mobil" if variant == "intact" else "mutant")
            assert not cfg.recording.enabled
            # paired: a mutant's episode differs from the intact one's only in the SUT model
            intact = by[(scenario, "intact")][cfg.seed]
            assert (cfg.traffic, cfg.bvs, cfg.sut.s_m, cfg.sut.lane, cfg.dt_s) == (
                intact.traffic, intact.bvs, intact.sut.s_m, intact.sut.lane, intact.dt_s)
    assert by[("level0", "stale")][7].models["mutant"].operator == "stale"


def _sumo_sut_installed() -> bool:
    from evoscen_sim.model_registry import model_names

    return "sumo_sut" in model_names("sut")


@pytest.mark.skipif("not _sumo_sut_installed()", reason="the SUMO SUT example plug-in is not installed (make setup)")
def test_seed_blocks_build_every_block_and_only_applicable_mutants(exp):
    (design,) = se.resolve_designs(exp.parse_args(["--blocks", "2", "--block-size", "2", "--first-seed", "10",
                                                    "--episode-steps", "20"]))
    assert (design.name, design.runs, design.steps, design.block_bounds) == ("episodes", 4, 20, ((10, 11), (12, 13)))
    (explicit,) = se.resolve_designs(exp.parse_args(["--seed-blocks", "5:6,90:90", "--design", "long"]))
    assert (explicit.name, explicit.runs, explicit.steps, list(explicit.seeds)) == ("long", 3, 3000, [5, 6, 90])
    rounds, meta = se.build_rounds([explicit], ["mobil", "sumo_sut"], ["level0"], ["tailgating", "frozen"], None)
    variants = sorted({meta[r.key][2:] for r in rounds})
    # sumo_sut: tailgating needs two driver instances, not applicable, so not run
    assert variants == [("mobil", "frozen"), ("mobil", "intact"), ("mobil", "tailgating"), ("sumo_sut", "frozen"),
                        ("sumo_sut", "intact")]
    assert sorted(r.cfg.seed for r in rounds if meta[r.key][2:] == ("sumo_sut", "frozen")) == [5, 6, 90]
    assert st.compute_text(explicit, rounds[0].cfg, 5).startswith(
        "Design long: 3 seeds (seed blocks 5..6, 90..90) x 3,000 steps = 9,000 SUT steps")


def test_compare_designs_builds_both_on_disjoint_seeds(exp):
    designs = se.resolve_designs(exp.parse_args(["--compare-designs", "--episodes", "4", "--episode-steps", "30",
                                                  "--seeds", "2", "--steps", "60"]))
    rounds, meta = se.build_rounds(designs, ["mobil"], ["level0"], ["stale"], None)
    seeds = {name: {r.cfg.seed for r in rounds if meta[r.key][0] == name} for name in ("episodes", "long")}
    steps = {name: {r.cfg.steps for r in rounds if meta[r.key][0] == name} for name in ("episodes", "long")}
    assert seeds == {"episodes": {0, 1, 2, 3}, "long": {4, 5}} and steps == {"episodes": {30}, "long": {60}}
    assert len(rounds) == (4 + 2) * 2
    cfg = rounds[0].cfg
    assert st.warmup_steps(cfg) == 200  # 20 s at 0.1 s
    text = st.compute_text(designs[0], cfg, 2)
    assert text == ("Design episodes: 4 episodes (seeds 0..3) x 30 steps = 120 SUT steps per variant and scenario; "
                    "the warm-up (traffic.warmup_s = 20 s, 200 steps) runs before every run and is extra compute, "
                    "the same per run in either design: 4 x 200 = 800 steps; 920 simulated steps per variant and "
                    "scenario, 1,840 in all (2 variant-scenario pairs, 8 runs); challenge.mode none "
                    "(docs/challenges.md).")
    nade, _ = se.build_rounds(designs[:1], ["mobil"], ["level0"], ["stale"], None, "nade")
    assert {r.cfg.challenge.mode for r in nade} == {"nade"} and len(nade) == 4 * 2


def test_comparison_table_by_hand(exp):
    episodes, long = Design("episodes", 4, 300, 0), Design("long", 2, 600, 10)
    intact = {0: 1.0, 1: 2.0, 2: 3.0, 3: 4.0}
    summaries = {
        "episodes": {("evolving", "mobil"): summarise_design(intact, {
            "m1": {0: 0.0, 1: 1.0, 2: 2.0, 3: 3.0},   # d = [1, 1, 1, 1]: 1 ± 0, detected
            "m2": {0: 0.0, 1: 3.0, 2: 2.0, 3: 5.0},   # d = [1, -1, 1, -1]: 0 ± t3/sqrt(3), not detected
        })},
        "long": {("evolving", "mobil"): summarise_design({10: 0.8, 11: 0.6}, {
            "m1": {10: 0.7, 11: 0.4},                 # d = [0.1, 0.2]: 0.15 ± t1 * 0.05, not detected
            "m2": {10: 0.5, 11: 0.2},                 # d = [0.3, 0.4]: 0.35 ± t1 * 0.05, not detected
        })},
    }
    computes = {"episodes": design_compute(episodes, 200), "long": design_compute(long, 200)}
    walls = {"episodes": {("evolving", "mobil"): 12.4}, "long": {("evolving", "mobil"): 7.6}}
    md, rows, md_m, rows_m = se.comparison_rows([episodes, long], summaries, computes, walls)
    h3 = T975_DF3 / math.sqrt(3)
    ep_row, lg_row = rows
    assert ep_row[:8] == ["evolving", "mobil", "episodes", 4, 300, 1, 2, 0.5]
    assert ep_row[8] == pytest.approx(h3 / 2, rel=1e-9)                         # median of 0 and t3/sqrt(3)
    assert ep_row[9] == pytest.approx((1.0 + 7.0 / math.sqrt(65.0)) / 2)        # median r of 1 and 7/sqrt(65)
    assert ep_row[10:] == [1200, 800, 2000, 12.4]                                # 4 x 300, 4 x 200, sum, s
    assert lg_row[:8] == ["evolving", "mobil", "long", 2, 600, 0, 2, 0.0]
    assert lg_row[8] == pytest.approx(T975_DF1 * 0.05, rel=1e-9) and math.isnan(lg_row[9])
    assert lg_row[10:] == [1200, 400, 1600, 7.6]
    assert md[0] == ["evolving", "mobil", "episodes", "4 x 300", "1/2", "0.50", f"{h3 / 2:.4f}",
                     f"{(1 + 7 / math.sqrt(65)) / 2:.2f}", "1,200", "2,000", "12"]
    assert md[1][4:8] == ["0/2", "0.00", f"{T975_DF1 * 0.05:.4f}", "–"]
    # per mutant: both designs' intervals with n and detection
    m1, m2 = rows_m
    assert m1[:3] == ["evolving", "mobil", "m1"] and m1[3:] == [pytest.approx(1.0), pytest.approx(0.0), 4, 1,
                                                                pytest.approx(0.15),
                                                                pytest.approx(T975_DF1 * 0.05, rel=1e-9), 2, 0]
    assert m2[3:] == [pytest.approx(0.0), pytest.approx(h3, rel=1e-9), 4, 0, pytest.approx(0.35),
                      pytest.approx(T975_DF1 * 0.05, rel=1e-9), 2, 0]
    assert md_m[0] == ["evolving", "mobil", "m1", "1.0000 ± 0.0000 (n 4)", "yes", "0.1500 ± 0.6353 (n 2)", "no"]
