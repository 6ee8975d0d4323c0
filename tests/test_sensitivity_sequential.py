"""The sensitivity experiment's sequential design (``--sequential``, evoscen_experiments.sensitivity_sequential) on
synthetic episode results: rounds go only to unresolved comparisons, each stops at its verdict, a rerun computes
nothing again, the profile ``frozen`` is not counted; the fixed designs' counts leave it out too; the tables'
column names name D. Values by hand."""

from __future__ import annotations

import csv
import math
from types import SimpleNamespace

import pytest

from evoscen_experiments import sensitivity_sequential as sq
from evoscen_experiments.experiments import config_loader
from evoscen_experiments.sensitivity import summarise_design
from evoscen_experiments.sequential import boundaries

FIRST = 700
INTACT_D = 0.5
# intact − mutant D per episode (seeds 700..707), chosen so that every verdict below follows by hand for any
# boundaries c1 in (2.5, 3.0) at the first look (4 of 8 episodes) and c2 in (1.9, 2.1) at the second
DIFFS = {
    # mean 1, sd 0.00163: half <= 3 x 0.00163 / 2 < 0.003 -> above 0 at look 1: worse
    "stale": [1.0, 1.002, 0.998, 1.0, 1.0, 1.0, 1.0, 1.0],
    # mean 0, sd 0.01155: half < 3 x 0.01155 / 2 = 0.0173 < delta 0.05 -> equivalent at look 1
    "timid": [0.01, -0.01, 0.01, -0.01, 0.01, -0.01, 0.01, -0.01],
    # look 1: mean -0.5, sd 0.8165, half > 2.5 x 0.8165 / 2 = 1.02: holds 0 -> continue; look 2: mean -0.5,
    # sd sqrt(2/7) = 0.5345, half < 2.1 x 0.5345 / sqrt(8) = 0.397 -> below 0: better
    "late_braking": [-0.5, -1.5, 0.5, -0.5, -0.5, -0.5, -0.5, -0.5],
    # mean 0 at both looks, sd 1.155 then 1.069: half > 1.9 x 1.069 / sqrt(8) = 0.72 > delta -> unresolved at 8
    "weak_braking": [1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0],
    # as stale: worse at look 1, but a profile: reported, never counted
    "frozen": [1.0, 1.002, 0.998, 1.0, 1.0, 1.0, 1.0, 1.0],
}
PLAN = sq.Plan(round_size=4, budget=8, delta=0.05, spending="obrien_fleming", steps=20, first_seed=FIRST)


def report(d: float) -> dict:
    return {"settings": {"score_form": "comparative"}, "safety": {"collisions": 0, "exposures": 0},
            "comparative": {"score": d, "safety": {"score": 1.0}, "progress": {"score": d},
                            "interaction": {"score": 1.0}}}


class Engine:
    """A stand-in for the run engine: results by round key, computed once (as the campaign's saved runs)."""

    def __init__(self) -> None:
        self.saved: dict[str, dict] = {}
        self.computed: list[tuple[str, int]] = []
        self.stop_after: int | None = None  # interrupt once this many runs were computed

    def __call__(self, rounds: list) -> dict | None:
        for rnd in rounds:
            if rnd.key in self.saved:
                continue
            if self.stop_after is not None and len(self.computed) >= self.stop_after:
                return None
            variant, seed = rnd.label.split("--")[2], rnd.cfg.seed
            d = INTACT_D if variant == "intact" else INTACT_D - DIFFS[variant][seed - FIRST]
            self.saved[rnd.key] = {"seed": seed, "steps": 20, "wall_time_s": 0.1, "report": report(d)}
            self.computed.append((variant, seed))
        return {r.key: self.saved[r.key] for r in rounds}


@pytest.fixture(scope="module")
def load():
    return config_loader(None)


COMPS = [("level0", "mobil", m) for m in DIFFS]


def test_boundaries_the_hand_values_assume():
    c1, c2 = boundaries((0.5, 1.0), 0.05, "obrien_fleming")
    assert 2.5 < c1 < 3.0 and 1.9 < c2 < 2.1


def test_rounds_go_only_to_unresolved_comparisons_and_each_stops_at_its_verdict(load, tmp_path):
    engine = Engine()
    verdicts, rounds, results, meta = sq.run_looks(PLAN, COMPS, load, engine)
    got = {m: (sq.WORDS[v.verdict], v.episodes, v.looks) for (_, _, m), v in verdicts.items()}
    assert got == {"stale": ("worse", 4, 1), "timid": ("equivalent", 4, 1), "late_braking": ("better", 8, 2),
                   "weak_braking": ("unresolved", 8, 2), "frozen": ("worse", 4, 1)}
    look1 = [(v, s) for v in ("intact", *DIFFS) for s in range(700, 704)]
    look2 = [(v, s) for v in ("intact", "late_braking", "weak_braking") for s in range(704, 708)]
    assert sorted(engine.computed) == sorted(look1 + look2)  # the intact seed once per base, shared
    assert verdicts[("level0", "mobil", "stale")].mean == pytest.approx(1.0)
    assert verdicts[("level0", "mobil", "late_braking")].mean == pytest.approx(-0.5)
    assert verdicts[("level0", "mobil", "late_braking")].high < 0
    assert {meta[r.key][0] for r in rounds} == {"sequential"} and len(rounds) == 36

    sq.write_tables(tmp_path, PLAN, ["mobil"], ["level0"], list(DIFFS), verdicts, rounds, results, meta)
    with (tmp_path / "verdicts.csv").open(newline="") as f:
        rows = {r["mutant"]: r for r in csv.DictReader(f)}
    assert [rows[m]["verdict"] for m in DIFFS] == ["worse", "equivalent", "better", "unresolved", "worse"]
    assert rows["frozen"]["role"] == "profile" and rows["stale"]["role"] == "defect"
    assert (rows["late_braking"]["episodes"], rows["late_braking"]["looks"]) == ("8", "2")
    assert float(rows["stale"]["delta_d_mean"]) == pytest.approx(1.0)
    # weak_braking unresolved at mean 0: no episodes would resolve it; resolved ones state none
    assert {m: rows[m]["episodes_needed"] for m in DIFFS} == {m: "" for m in DIFFS}
    with (tmp_path / "verdict_counts.csv").open(newline="") as f:
        (count,) = csv.DictReader(f)
    # frozen's "worse" is not counted: 1 of the 4 defects
    assert {k: count[k] for k in ("worse", "better", "equivalent", "unresolved", "defects", "profiles", "runs")} == {
        "worse": "1", "better": "1", "equivalent": "1", "unresolved": "1", "defects": "4", "profiles": "1",
        "runs": "36"}
    text = (tmp_path / "sensitivity.md").read_text()
    assert "## Sequential verdicts" in text and "| level0 | mobil | 1/4 | 1 | 1 | 1 | 36 |" in text
    assert "| level0 | mobil | frozen (profile) | worse |" in text


def test_a_rerun_computes_nothing_and_an_interrupted_one_only_what_is_missing(load):
    engine = Engine()
    first = sq.run_looks(PLAN, COMPS, load, engine)
    n = len(engine.computed)
    again = sq.run_looks(PLAN, COMPS, load, engine)
    assert len(engine.computed) == n == 36
    assert {c: v.verdict for c, v in again[0].items()} == {c: v.verdict for c, v in first[0].items()}

    engine = Engine()
    engine.stop_after = 27  # look 1's 24 runs and 3 of look 2's 12
    assert sq.run_looks(PLAN, COMPS, load, engine) is None
    engine.stop_after = None
    resumed = sq.run_looks(PLAN, COMPS, load, engine)
    assert len(engine.computed) == 36 and len(set(engine.computed)) == 36  # each run once, over both calls
    assert {c: v.verdict for c, v in resumed[0].items()} == {c: v.verdict for c, v in first[0].items()}


def args_of(**kw) -> SimpleNamespace:
    base = dict(sequential=True, budget=None, round_size=None, delta=None, spending=None, design=None,
                compare_designs=False, episodes=None, seeds=None, steps=None, long_first_seed=None, blocks=None,
                block_size=None, seed_blocks=None, episode_steps=None, first_seed="0")
    return SimpleNamespace(**{**base, **kw})


def test_plan_defaults_and_bad_options():
    plan = sq.resolve_plan(args_of())
    assert (plan.budget, plan.round_size, plan.delta, plan.spending, plan.steps) == (2000, 100, 0.005,
                                                                                     "pocock", 300)
    assert plan.looks[:2] == (100, 200) and len(plan.looks) == 20
    assert sq.resolve_plan(args_of(sequential=False)) is None
    from evoscen_sim.errors import InputError

    for kw, msg in ((dict(sequential=False, budget="8"), "--budget applies with --sequential only"),
                    (dict(seed_blocks="1:4", first_seed="5"), "--seed-blocks and --first-seed together"),
                    (dict(seed_blocks="1:400,500:550"), "--seed-blocks: block 500–550 holds 51 seeds, fewer than "
                                                        "--round-size 100"),
                    (dict(seed_blocks="1:400,300:800"), "--seed-blocks: blocks 1:400 and 300:800 overlap"),
                    (dict(design="long"), "--sequential and --design long together"),
                    (dict(round_size="9", budget="8"), "--round-size 9 exceeds --budget 8"),
                    (dict(delta="0"), "--delta = '0': expected a number > 0"),
                    (dict(spending="linear"), "--spending 'linear': expected one of obrien_fleming, pocock")):
        with pytest.raises(InputError, match=msg):
            sq.resolve_plan(args_of(**kw))


def test_fixed_design_counts_leave_the_profile_out():
    # intact − mutant per seed: frozen and stale d = [1, 1.1, 1.2], mean 1.1, half t(0.975, 2) x 0.1 / sqrt(3) =
    # 0.248: both detected; timid d = [0, -0.1, 0.1]: not
    intact = {0: 2.0, 1: 2.0, 2: 2.0}
    s = summarise_design(intact, {"frozen": {0: 1.0, 1: 0.9, 2: 0.8}, "stale": {0: 1.0, 1: 0.9, 2: 0.8},
                                  "timid": {0: 2.0, 1: 2.1, 2: 1.9}})
    assert s.per_mutant["frozen"].above_zero and s.per_mutant["stale"].above_zero
    assert (s.detected, s.mutants, s.score) == (1, 2, 0.5)  # stale of {stale, timid}; frozen reported only
    assert math.isclose(s.per_mutant["frozen"].half, 4.302652729911275 * 0.1 / math.sqrt(3))


def test_column_names_name_d():
    from evoscen_experiments import leaderboard, sensitivity_tables as st

    for header in (st.SENSITIVITY_CSV, st.SCORES_CSV, st.BLOCKS_CSV, st.ROUNDS_CSV, sq.VERDICTS_CSV,
                   leaderboard.csv_header("mobil")):
        assert not [c for c in header if "intelligence" in c], header
    assert {"delta_d_mean", "delta_d_ci95", "role"} <= set(st.SENSITIVITY_CSV)
    assert {"d_intact_mean", "d_intact_ci95"} <= set(st.SCORES_CSV)
    assert {"delta_d_mean", "delta_d_ci95"} <= set(st.BLOCKS_CSV) and "d" in st.ROUNDS_CSV
    assert {"d_mean", "d_ci95", "delta_d_vs_mobil_mean"} <= set(leaderboard.csv_header("mobil"))


def test_an_unresolved_comparison_states_the_episodes_a_fixed_design_would_need():
    # intact − mutant 1, −0.5, 1, −0.5: mean 0.25, sd sqrt(4 x 0.75² / 3) = 0.8660; (1.95996 + 0.84162) x 0.8660
    # / 0.25 = 9.705, squared 94.19 -> 95 episodes; a resolved comparison states none
    diffs = [1.0, -0.5, 1.0, -0.5]
    rounds, results, meta = [], {}, {}
    for k, x in enumerate(diffs):
        for variant, d in (("intact", INTACT_D), ("stale", INTACT_D - x)):
            key = f"{variant}-{k}"
            rounds.append(SimpleNamespace(key=key, cfg=SimpleNamespace(seed=FIRST + k)))
            results[key] = {"report": report(d)}
            meta[key] = ("sequential", "level0", "mobil", variant)
    comp = ("level0", "mobil", "stale")
    d = sq.scores_into({}, rounds, results, meta)
    assert d[("level0", "mobil", "stale")] == pytest.approx({FIRST + k: INTACT_D - x for k, x in enumerate(diffs)})
    for words, expected in (("continue", 95), ("unresolved", 95), ("a_higher", None), ("equivalent", None)):
        v = sq.Verdict(words, 4, 0.25, -1.0, 1.5, 1)
        assert sq.needed_of(PLAN, comp, v, d) == expected
    # only the comparison's own episodes count: the first two give mean 0.25, sd 1.0607 -> (2.8016 x 4.243)² = 141.3
    assert sq.needed_of(PLAN, comp, sq.Verdict("unresolved", 2, 0.25, -9, 9, 1), d) == 142
    # a round without a result adds nothing
    assert sq.scores_into({}, rounds, {}, meta) == {}


def test_seed_blocks_make_one_design_each_and_their_verdicts_stand_side_by_side(load, tmp_path):
    plan = sq.resolve_plan(args_of(seed_blocks="700:707,800:805", round_size="4", budget="8", delta="0.05",
                                   episode_steps="20"))
    # each block from its first seed, its budget at most the block's size (6 seeds: looks at 4 and 6)
    assert [(p.first_seed, p.budget, p.looks, p.label) for p in plan.parts] == [
        (700, 8, (4, 8), "700–707"), (800, 6, (4, 6), "800–805")]
    assert sq.resolve_plan(args_of()).parts[0].label == "0–1999"
    plan = sq.resolve_plan(args_of(seed_blocks="700:707,800:807", round_size="4", budget="8", delta="0.05",
                                   episode_steps="20"))

    # block 800: the same differences as block 700, late_braking's turned round (worse there: a contradiction)
    class Blocks(Engine):
        def __call__(self, rounds):
            for rnd in rounds:
                seed = rnd.cfg.seed
                if seed >= 800 and rnd.key not in self.saved:
                    variant = rnd.label.split("--")[2]
                    x = DIFFS[variant][seed - 800] if variant != "intact" else 0.0
                    d = INTACT_D - (-x if variant == "late_braking" else x)
                    self.saved[rnd.key] = {"seed": seed, "steps": 20, "wall_time_s": 0.1, "report": report(d)}
                    self.computed.append((variant, seed))
            return super().__call__(rounds)

    engine = Blocks()
    parts = [(p, *sq.run_looks(p, COMPS, load, engine)) for p in plan.parts]
    # block 800 mirrors block 700 but for late_braking: the hand values of DIFFS with its sign turned
    assert {m: v.verdict for (_, _, m), v in parts[1][1].items()} == {
        "stale": "a_higher", "timid": "equivalent", "late_braking": "a_higher", "weak_braking": "unresolved",
        "frozen": "a_higher"}
    table = sq.write_blocks(tmp_path, plan, ["mobil"], ["level0"], list(DIFFS), parts)
    with (tmp_path / "replication.csv").open(newline="") as f:
        rep = {r["mutant"]: r for r in csv.DictReader(f)}
    assert [rep[m]["verdict_block_700_707"] for m in DIFFS] == ["worse", "equivalent", "better", "unresolved",
                                                                 "worse"]
    assert [rep[m]["verdict_block_800_807"] for m in DIFFS] == ["worse", "equivalent", "worse", "unresolved",
                                                                 "worse"]
    assert [rep[m]["contradiction"] for m in DIFFS] == ["", "", "yes", "", ""]
    with (tmp_path / "verdict_counts.csv").open(newline="") as f:
        assert [(r["block"], r["worse"], r["better"]) for r in csv.DictReader(f)] == [("700–707", "1", "1"),
                                                                                     ("800–807", "2", "0")]
    assert "| 700–707 | level0 | mobil | 1/4 |" in table and "| 800–807 | level0 | mobil | 2/4 |" in table
    assert "Contradictions (worse in one block, better in another): level0/mobil/late_braking." in table
    assert "seed blocks 700–707, 800–807, each a design of its own" in (tmp_path / "sensitivity.md").read_text()


def test_a_failed_episode_fails_its_comparison_and_the_others_go_on(load, tmp_path):
    class Failing(Engine):  # stale's episode 701 never comes back (its plug-in raised)
        def __call__(self, rounds):
            got = super().__call__(rounds)
            return {k: v for k, v in got.items() if k not in self.broken}

    engine = Failing()
    first_look, meta = sq.look_rounds(PLAN, COMPS, 0, load)
    engine.broken = {r.key for r in first_look if meta[r.key][3] == "stale" and r.cfg.seed == 701}
    verdicts, rounds, results, meta = sq.run_looks(PLAN, COMPS, load, engine)
    got = {m: sq.WORDS[v.verdict] for (_, _, m), v in verdicts.items()}
    assert got == {"stale": "failed", "timid": "equivalent", "late_braking": "better", "weak_braking": "unresolved",
                   "frozen": "worse"}  # the others as without the failure
    assert len(rounds) == 35 and all(r.key in results for r in rounds)  # the failed round is not among them
    sq.write_tables(tmp_path, PLAN, ["mobil"], ["level0"], list(DIFFS), verdicts, rounds, results, meta)
    with (tmp_path / "verdict_counts.csv").open(newline="") as f:
        (count,) = csv.DictReader(f)
    assert (count["worse"], count["failed"], count["runs"]) == ("0", "1", "35")

    engine = Failing()  # the intact SUT's episode fails: every comparison of the base
    engine.broken = {r.key for r in first_look if meta[r.key][3] == "intact" and r.cfg.seed == 700}
    verdicts = sq.run_looks(PLAN, COMPS, load, engine)[0]
    assert {sq.WORDS[v.verdict] for v in verdicts.values()} == {"failed"}


def test_a_profile_is_looked_at_once(load):
    class OpenProfile(Engine):  # frozen as weak_braking: open after the first look (its mean 0, sd 1.155)
        def __call__(self, rounds):
            for rnd in rounds:
                variant = rnd.label.split("--")[2]
                if variant == "frozen" and rnd.key not in self.saved:
                    d = INTACT_D - DIFFS["weak_braking"][rnd.cfg.seed - FIRST]
                    self.saved[rnd.key] = {"seed": rnd.cfg.seed, "steps": 20, "wall_time_s": 0.1, "report": report(d)}
                    self.computed.append((variant, rnd.cfg.seed))
            return super().__call__(rounds)

    engine = OpenProfile()
    verdicts = sq.run_looks(PLAN, COMPS, load, engine)[0]
    frozen, weak = verdicts[("level0", "mobil", "frozen")], verdicts[("level0", "mobil", "weak_braking")]
    assert sq.WORDS[frozen.verdict] == "unresolved" and (frozen.episodes, frozen.looks) == (4, 1)
    assert sq.WORDS[weak.verdict] == "unresolved" and weak.episodes == 8  # a defect runs to the budget
    assert sorted(s for v, s in engine.computed if v == "frozen") == [700, 701, 702, 703]
