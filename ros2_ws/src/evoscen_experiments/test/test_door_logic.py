"""The work behind the experiment scripts' doors, without a simulation: option checks (``key_values``,
``set_up``, the fidelity numbers), the SUT's jumps and the traffic figures (traffic_experiment), the table
of exposures by rule (exposures_by_rule); values worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from evoscen_experiments.experiments import key_values, set_up
from evoscen_sim.errors import InputError

T975_DF1 = 12.706204736  # Student-t 0.975 quantile, 1 degree of freedom


def test_key_values_strip_and_keep_the_rest_of_the_value() -> None:
    assert key_values("--set", [" bvs.count = 12", "models.x.rule=a=b", "k="]) == {
        "bvs.count": "12", "models.x.rule": "a=b", "k": ""}
    assert key_values("--set", []) == {}
    for item in ("nokey", "=5"):
        with pytest.raises(InputError, match=rf"^--set '{item}': expected KEY=VALUE$"):
            key_values("--set", [item])


def test_set_up_checks_before_it_creates_the_output(tmp_path) -> None:
    out = tmp_path / "o"

    def bad():
        raise InputError("--seeds = '0': expected an integer >= 1")

    with pytest.raises(InputError, match="--seeds"):
        set_up(out, bad)
    assert not out.exists()  # nothing written on bad input
    assert set_up(out, lambda: 7) == 7 and out.is_dir()
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(InputError, match=rf"^--out {blocker / 'sub'}: cannot create: "):
        set_up(blocker / "sub", lambda: 1)


def test_fidelity_numbers_name_the_option() -> None:
    from evoscen_experiments.fidelity_experiment import number

    assert number("--max-ttc", "30") == 30.0 and number("--min-speed", "0", inclusive=True) == 0.0
    assert number("--grid-1d", "3", integer=True, lo=2) == 3
    for text, message in (("0", "--bandwidth '0': expected a number > 0"), ("inf", "expected a number > 0"),
                          ("nan", "expected a number > 0"), ("x", "--bandwidth 'x': expected a number > 0")):
        with pytest.raises(InputError, match=message):
            number("--bandwidth", text)
    with pytest.raises(InputError, match=r"^--grid-1d '2\.5': expected an integer > 2$"):
        number("--grid-1d", "2.5", integer=True, lo=2)
    with pytest.raises(InputError, match=r"^--min-speed '-1': expected a number >= 0$"):
        number("--min-speed", "-1", inclusive=True)


def test_sut_jumps_count_moves_other_than_driving() -> None:
    from evoscen_experiments.traffic_experiment import sut_jumps

    # SUT in column 0, 0.1 s steps, 40 m/s at most: 4 m a step
    s = np.array([[0.0, 9.0], [3.0, 9.0], [6.0, 9.0], [-94.0, 9.0], [-91.0, 9.0], [-80.0, 9.0], [-82.0, 9.0]])
    lane = np.array([[1, 0], [1, 0], [2, 0], [2, 0], [2, 0], [2, 0], [2, 0]])
    target = np.array([[2, 0], [2, 0], [2, 0], [2, 0], [3, 0], [2, 0], [2, 0]])
    # step 2: into its target lane; step 3: the window shifted by 100 m (undone: 0 m, standing); step 5: +11 m
    # (a jump); step 6: backwards (a jump)
    assert sut_jumps(s, lane, target, 0, 0.1, 40.0, {3: 100.0}) == 2
    assert sut_jumps(s, lane, target, 0, 0.1, 40.0, {}) == 3  # without the shift, step 3 is a jump too
    lane2 = lane.copy()
    lane2[1, 0] = 0  # step 1: from lane 1 (target 2) to lane 0, a jump; step 2: 0 -> 2, its target then, not
    assert sut_jumps(s, lane2, target, 0, 0.1, 40.0, {3: 100.0}) == 3


def test_traffic_figures_over_runs() -> None:
    from evoscen_experiments.traffic_experiment import figures

    def run(seed, per_window, exposures, early, bv_bv, intelligence):
        return {"seed": seed, "steps": 600, "per_window": per_window, "mean_bvs": 0.0, "jumps": seed % 2,
                "exposures": exposures, "exposures_first_10pct": early, "bv_bv_collisions": bv_bv,
                "bv_hours": 1.5, "entries": seed, "shifts": 2 * seed, "intelligence": intelligence,
                "efficiency": 0.0}

    runs = [run(1, [8.0, 6.0, 9.0], 4, 1, 0, 0.5), run(2, [7.0, 3.0], 0, 0, 3, 0.7)]
    out, early, bv_hours = figures("mobil", runs, 600, {"traffic.mode": "loop"})
    assert out["per_window_mean_bvs"] == [7.5, 4.5]          # the common windows only
    assert (out["min_window_mean_bvs"], out["mean_window_mean_bvs"], out["min_window_any_run_bvs"]) == (4.5, 6.0, 3.0)
    assert (out["sut_jumps"], out["exposures"], early) == (1, 4, 1) and out["exposures_first_10pct_share"] == 0.25
    assert (out["bv_bv_collisions"], bv_hours, out["bv_bv_collisions_per_bv_hour"]) == (3, 3.0, 1.0)
    assert (out["entries_per_run"], out["shifts_per_run"]) == (1.5, 3.0)
    mean, half = out["intelligence"]
    assert mean == pytest.approx(0.6) and half == pytest.approx(T975_DF1 * 0.1)  # sd 0.1·√2, /√2
    assert list(out) == ["sut", "seeds", "steps", "overrides", "per_window_mean_bvs", "min_window_mean_bvs",
                         "mean_window_mean_bvs", "min_window_any_run_bvs", "sut_jumps", "exposures",
                         "exposures_first_10pct_share", "bv_bv_collisions", "bv_bv_collisions_per_bv_hour",
                         "entries_per_run", "shifts_per_run", "intelligence", "runs"]


def test_exposures_by_rule_table() -> None:
    from evoscen_eval.scoring.exposure_rules import RULES

    from evoscen_experiments.exposures_by_rule import table_lines

    def ep(exposures, cut_in, collisions):
        return {"exposures": exposures, "by_rule": {**dict.fromkeys(RULES, 0), "cut_in": cut_in},
                "collisions": [{}] * collisions}

    lines = table_lines({"mobil": {1: ep(2, 1, 0), 2: ep(4, 3, 1)}})
    assert lines[0] == "| SUT | exposures | " + " | ".join(RULES) + " | collisions | n |"
    assert lines[1] == "|---" * (len(RULES) + 4) + "|"
    cells = lines[2].split(" | ")
    half = T975_DF1 * 1.0  # sd √2, /√2
    assert cells[0] == "| mobil" and cells[1] == f"3.000 ± {half:.3f}" and cells[-1] == "2 |"
    assert cells[2 + RULES.index("cut_in")] == f"2.000 ± {half:.3f}"
    assert cells[2 + RULES.index("rear")] == "0.000 ± 0.000"
    assert cells[-2] == f"0.500 ± {T975_DF1 * 0.5:.3f}"


def test_traffic_experiment_shorter_than_one_window_says_so(capsys):
    """A run shorter than one 30-s window has no window figures: the experiment says so in one line
    instead of failing on the missing figures."""
    import argparse

    from evoscen_experiments import traffic_experiment

    args = argparse.Namespace(sut="mobil", seeds="1", first_seed="60000", steps="50", config=None, set=[],
                              compare_steps=None, json=None)
    assert traffic_experiment.main(args) in (0, None)
    out = capsys.readouterr().out
    assert "no complete 30-s window: a run of 50 steps is shorter than one" in out
    assert "lowest window mean" not in out
