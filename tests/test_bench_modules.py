"""The benchmarks' package functions (evoscen_experiments.bench, .bench_fidelity, .bench_run_costs,
.profiling): their option checks, the shared ``--mutants`` parser, the child processes' import path and
the synthetic HighD recording's sizes. Nothing here times anything."""

from __future__ import annotations

import os
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from evoscen_experiments import bench, bench_fidelity, bench_run_costs, profiling
from evoscen_sim.errors import InputError
from evoscen_sut.mutants import LIBRARY


def test_mutant_names_all_or_distinct_known_names():
    assert profiling.mutant_names("--mutants", " all ") == list(LIBRARY)
    assert profiling.mutant_names("--mutants", "stale, tailgating") == ["stale", "tailgating"]
    with pytest.raises(InputError, match=r"^--mutants: unknown mutant 'nosuch': expected 'all' or names from blind_behind, "):
        profiling.mutant_names("--mutants", "stale,nosuch")
    with pytest.raises(InputError, match=r"^--mutants 'stale,stale': expected distinct comma-separated names$"):
        profiling.mutant_names("--mutants", "stale,stale")


def _bench_args(**changes) -> SimpleNamespace:
    base = {"steps": 5000, "repeats": 5, "bag_steps": 10000, "graph_steps": 5000, "graph_repeats": 3,
            "experiment_episodes": 8, "jobs": 2, "experiment_mutants": "tailgating, stale", "bv_nodes": "single,4"}
    return SimpleNamespace(**{**base, **changes})


def test_bench_options_are_checked_in_order_with_one_line_errors():
    assert bench.checked_options(_bench_args()) == (["tailgating", "stale"], ["single", "4"])
    assert bench.checked_options(_bench_args(bag_steps=0, bv_nodes="")) == (["tailgating", "stale"], [])
    cases = [({"bag_steps": -1}, "--bag-steps = -1: expected an integer >= 0 (0 = skip)"),
             ({"jobs": 0, "bv_nodes": "33"}, "--jobs = 0: expected a positive integer"),
             ({"bv_nodes": "by_policy,33"}, "--bv-nodes = 'by_policy,33': expected comma-separated by_policy, "
                                            "single or numbers in [1, 32]")]
    for changes, line in cases:
        with pytest.raises(InputError) as err:
            bench.checked_options(_bench_args(**changes))
        assert str(err.value) == line
    with pytest.raises(InputError, match=r"^--experiment-mutants = 'stale,stale': expected distinct"):
        bench.checked_options(_bench_args(experiment_mutants="stale,stale"))


def test_a_child_process_gets_this_process_import_path(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    monkeypatch.setattr(sys, "path", ["", "/a", "/b"])
    env = bench.child_env()
    assert env["PYTHONPATH"] == os.pathsep.join(["/a", "/b", "/elsewhere"])
    assert env["HOME"] == os.environ["HOME"]


def test_synthetic_recording_has_the_asked_sizes():
    # 4 vehicles, 40 rows: 10 rows (frames) each, starting in frames 1 .. 91 of 100
    rec = bench_fidelity.synthetic_recording(np.random.default_rng(0), vehicles=4, frames=100, rows=40)
    assert rec.num_rows == 40 and len(rec.tracks_meta["id"]) == 4
    frames = np.asarray(rec.tracks["frame"])
    assert frames.min() >= 1 and frames.max() <= 100


def test_impossible_sizes_end_before_anything_is_made(capsys, tmp_path):
    with pytest.raises(InputError, match=r"^--vehicles, --frames and --rows must be >= 1$"):
        bench_fidelity.run(0, 100, 100, 0, tmp_path)
    assert bench_fidelity.run(2, 10, 1000, 0, tmp_path) == 1  # 500 rows a vehicle, 10 frames
    assert capsys.readouterr().err == "error: --rows 1000: more rows per vehicle (500) than --frames 10\n"
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match=r"^--repeats = 0: expected a positive integer$"):
        bench_run_costs.recording(100, 0, "level0")


def test_learned_costs_measure_the_learned_driver_of_the_default_makeup():
    """Under the highD make-up (the default) the learned driver drives the cars inside the make-up's driver:
    the bench times that driver, and its compiled forward pass equals numpy's and torch's."""
    from evoscen_experiments.bench import learned_bv_costs

    out = learned_bv_costs(steps=20, repeats=1)
    assert out["learned_act_us"] > 0 and out["grid_us"] > 0
    assert out["max_abs_diff_numpy_kernel"] < 1e-9 and out["max_abs_diff_torch_kernel"] < 1e-5, out


def test_the_write_path_rewrites_a_run_with_its_own_topics(tmp_path, capsys):
    """bench_recording's second figure: the run's messages (a command topic per BV node of the run, e.g.
    /evoscen/commands/bv_level0) written again three ways give the same bytes."""
    from evoscen_experiments.bench_run_costs import recorded_ratio, write_path
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": 30, "bvs.driver": "level0"})
    recorded_ratio(cfg, 30, 1, "level0", tmp_path)
    write_path(cfg, tmp_path)
    out = capsys.readouterr().out
    assert "bags byte-identical: yes" in out and "files byte-identical: yes" in out, out


def test_makeups_option_distinct_known_names_or_empty():
    from evoscen_experiments.bench_makeups import parse_makeups

    assert parse_makeups("highd,uniform") == ["highd", "uniform"]
    assert parse_makeups(" uniform ") == ["uniform"]
    assert parse_makeups("") == []
    for bad in ("highd,highd", "highd,nosuch", "highd,"):
        with pytest.raises(InputError) as err:
            parse_makeups(bad)
        assert str(err.value) == f"--makeups = {bad!r}: expected distinct comma-separated make-ups from uniform, highd"


def test_vehicle_steps_and_the_makeup_ratios_by_hand():
    from evoscen_experiments.bench_makeups import ratios, vehicle_steps_per_s

    assert vehicle_steps_per_s(1000.0, [21.0, 21.0]) == 21000.0
    assert vehicle_steps_per_s(2000.0, [20.0, 21.0, 22.0]) == 42000.0  # 2000 x mean 21
    rates = {"highd/level0": 4000.0, "highd/learned": 3200.0, "uniform/level0": 5000.0, "uniform/learned": 4000.0}
    got = ratios(rates, 8000.0)
    assert got == pytest.approx({
        "evoscen_over_sumo/highd": 0.5, "evoscen_over_sumo/uniform": 0.625,  # 4000/8000, 5000/8000
        "highd_over_uniform/level0": 0.8, "highd_over_uniform/learned": 0.8,  # 4000/5000, 3200/4000
        "learned_added_percent/highd": 25.0, "learned_added_percent/uniform": 25.0})  # 100 (4000/3200 - 1)
    assert ratios({"uniform/level0": 5000.0}, None) == {}  # no SUMO, one make-up, no learned: nothing to compare


def test_worlds_memory_runs_its_children_and_prints_per_world(capsys):
    from evoscen_experiments import bench_run_costs

    bench_run_costs.worlds_memory(3, 5, per_seed=2)  # 3 worlds: two of one seed, one of the next; 5 steps each
    out = capsys.readouterr().out
    assert "    1 world(s): peak" in out and "    3 world(s): peak" in out and out.count(", 0 failed") == 2
    assert "per world:" in out and "3 worlds in" in out


def test_worlds_option_is_checked():
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, str(repo / "scripts" / "bench_memory.py"), "--worlds", "0", "--steps", "5",
                           "5"], cwd=repo, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1] == "error: --worlds 0 --steps 5: expected at least 1 of each"


def test_batched_sizes_are_distinct_positive_counts():
    from evoscen_experiments.bench_batched import parse_sizes
    from evoscen_sim.errors import InputError

    assert parse_sizes("") == [] and parse_sizes("1,8,64") == [1, 8, 64]
    for bad in ("0", "1,1", "x", "4,-1"):
        with pytest.raises(InputError, match="^--batched = "):
            parse_sizes(bad)


def test_batched_worlds_count_every_vehicle_step(capsys):
    from evoscen_experiments import bench_batched

    rows = bench_batched.report([1, 2], 5, 1, False)["batched"]
    # 21 vehicles (SUT and 20 BVs) x 5 steps per world
    assert [(r["batch"], r["worlds"], r["vehicle_steps"]) for r in rows] == [(1, 1, 105), (2, 2, 210)]
    assert all(r["vehicle_steps_per_s"] == r["vehicle_steps"] / r["wall_s"] > 0 for r in rows)
    out = capsys.readouterr().out
    assert "batch    1 x 1:" in out and "batch    2 x 1:" in out
