"""The face: ``import evoscen`` gives a plug-in author, a script writer and a notebook user every name
they need (docs/plugins.md §19); its names are pinned, it imports nothing heavy, the version agrees
everywhere it is written, and the face of 0.6 (``evoscen_sim.api``) is an alias that warns."""

from __future__ import annotations

import configparser
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

FACE = sorted([
    # a plug-in's description and registration
    "ModelSpec", "Driver", "register_model", "unregister_model", "checked_answer",
    # parameters, errors, the scenario
    "number", "integer", "flag", "text", "number_range", "names", "InputError", "PluginFault", "ScenarioConfig",
    "load_scenario_config", "VehicleParams", "resolve_map_path", "scenario_rngs",
    # the view
    "TrafficView", "Neighborhood", "OWN", "LEFT", "RIGHT", "LANE_OFFSETS", "time_to_collision", "time_headway",
    "ROLE_BV", "ROLE_SUT", "POLICY_CODES", "common_shift", "new_trips",
    # road, throttle, Krauss following, hand-built worlds
    "RoadModel", "load_road", "accel_to_throttle", "throttle_to_accel", "krauss_for", "KraussCarFollowing",
    "KraussParams", "hand_built_world",
    # running and scoring
    "run_scenario", "score_bag", "RunResult", "run_experiment", "ExperimentResult",
    "__version__",
])
"""The face's names: a deliberate change updates this list (and docs/plugins.md §19)."""

FACE_06 = sorted([
    "InputError", "LANE_OFFSETS", "LEFT", "ModelSpec", "Neighborhood", "OWN", "POLICY_CODES", "PluginFault", "RIGHT",
    "ROLE_BV", "ROLE_SUT", "RoadModel", "ScenarioConfig", "TrafficView", "VehicleParams", "accel_to_throttle",
    "checked_answer", "common_shift", "flag", "hand_built_world", "integer", "load_road", "names", "new_trips", "number",
    "number_range", "register_model", "resolve_map_path", "scenario_rngs", "text", "throttle_to_accel",
    "time_headway", "time_to_collision", "unregister_model",
])
"""The names of 0.6's face, ``evoscen_sim.api``: every one is in :data:`FACE`."""


def test_the_face_is_pinned_and_every_name_resolves_to_its_module():
    import evoscen
    from evoscen_sim.model_registry import ModelSpec
    from evoscen_sim.physics.neighbors import LEFT, OWN
    from evoscen_sut.krauss import krauss_for

    assert evoscen.__all__ == FACE, "the face changed: a deliberate change updates FACE (docs/plugins.md §19)"
    assert evoscen.ModelSpec is ModelSpec and evoscen.krauss_for is krauss_for
    assert (evoscen.OWN, evoscen.LEFT) == (OWN, LEFT) == (2, 3)  # columns of lane offsets -2..2: own 0, left +1
    for name in FACE:
        assert getattr(evoscen, name) is not None, name
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        evoscen.no_such_name  # noqa: B018
    assert set(FACE_06) <= set(FACE)


def test_importing_the_face_starts_no_ros_and_loads_nothing_heavy():
    """``python -X importtime -c "import evoscen"``: no rclpy; a plug-in's usual names load the registry
    and the parameter checks, not the world, the road, numba or torch."""
    res = subprocess.run([sys.executable, "-X", "importtime", "-c",
                          "import sys, evoscen; from evoscen import ModelSpec, number; "
                          "print(sorted(m for m in ('rclpy', 'numba', 'torch', 'evoscen_sim.physics.world', "
                          "'evoscen_sim.road.road_model', 'evoscen_bringup') if m in sys.modules))"],
                         capture_output=True, text=True, timeout=60, check=True)
    assert res.stdout.strip() == "[]", res.stdout
    imported = {line.split("|")[-1].strip() for line in res.stderr.splitlines() if line.startswith("import time:")}
    assert "evoscen" in imported and not any(m == "rclpy" or m.startswith("rclpy.") for m in imported)


def _released_versions() -> list[str]:
    text = (REPO / "CHANGELOG.md").read_text(encoding="utf-8")
    return re.findall(r"^## (\d+\.\d+\.\d+) — ", text, flags=re.M)


def test_the_version_agrees_everywhere():
    import evoscen

    version = evoscen.__version__
    assert _released_versions()[0] == version, "the CHANGELOG's newest release is not evoscen.__version__"
    packages = sorted(p for p in (REPO / "ros2_ws" / "src").iterdir() if (p / "setup.cfg").is_file())
    assert len(packages) == 9 and {"evoscen", "evoscen_experiments"} <= {p.name for p in packages}
    for pkg in packages:
        cfg = configparser.ConfigParser(interpolation=None)
        cfg.read(pkg / "setup.cfg", encoding="utf-8")
        assert cfg["metadata"]["version"] == version, pkg.name
        xml = (pkg / "package.xml").read_text(encoding="utf-8")
        assert f"<version>{version}</version>" in xml, pkg.name
    res = subprocess.run([sys.executable, str(REPO / "scripts" / "run_scenario.py"), "--version"],
                         capture_output=True, text=True, timeout=120, cwd=REPO)
    assert (res.returncode, res.stdout.strip()) == (0, f"evoscen {version}"), res.stderr


def test_the_06_face_is_an_alias_that_warns():
    import evoscen

    sys.modules.pop("evoscen_sim.api", None)
    with pytest.warns(DeprecationWarning, match=r"^evoscen_sim\.api is deprecated \(moved in evoscen 0\.7\.0; "
                                                r"removed in 0\.8\.0\): use evoscen$"):
        import evoscen_sim.api as api
    assert api.__all__ == FACE_06
    for name in FACE_06:
        assert getattr(api, name) is getattr(evoscen, name), name
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        from evoscen import ModelSpec  # the face itself: no warning
    assert ModelSpec is api.ModelSpec


def test_run_scenario_and_score_bag_agree_with_each_other(tmp_path):
    """One in-process run through the face: its report is the one :func:`evoscen.score_bag` gives from
    its bag (the evaluator's scores from the bag alone), and the steps are those asked for."""
    import evoscen

    result = evoscen.run_scenario(overrides={"sut.model": "mobil", "steps": 40, "seed": 3}, out=tmp_path / "run")
    assert (result.status, result.steps, result.runner) == (0, 40, "inprocess")
    assert (tmp_path / "run" / "scenario.yaml").is_file() and result.report_dir == tmp_path / "run" / "report"
    offline = evoscen.score_bag(result.bag_dir)
    assert offline["intelligence"]["score"] == result.score
    assert offline["safety"]["collisions"] == result.report["safety"]["collisions"]
    with pytest.raises(evoscen.InputError, match="already holds a bag; choose another --out or pass --overwrite"):
        evoscen.run_scenario(overrides={"steps": 5}, out=tmp_path / "run")
    with pytest.raises(evoscen.InputError, match=r"^runner 'ros': expected one of inprocess, graph$"):
        evoscen.run_scenario(runner="ros")
    with pytest.raises(evoscen.InputError, match="no such bag directory"):
        evoscen.score_bag(tmp_path / "nowhere")


def test_run_experiment_returns_the_tables_it_wrote(tmp_path):
    """``evoscen.run_experiment("intelligence", ...)``: the door's options as keywords, its tables as rows;
    the paired difference is the mean over seeds of the per-seed differences of the rounds' D."""
    import evoscen

    result = evoscen.run_experiment("intelligence", out=tmp_path / "exp", suts=["mobil", "level0"], seeds=2,
                                    first_seed=5, steps=40, jobs=1)
    assert (result.status, result.kind) == (0, "intelligence")
    assert {"intelligence", "paired", "rounds"} <= set(result.tables)
    d = {(r["sut"], int(r["seed"])): float(r["d"]) for r in result.tables["rounds"]}
    assert sorted(d) == [("level0", 5), ("level0", 6), ("mobil", 5), ("mobil", 6)]
    (pair,) = result.tables["paired"]
    assert (pair["sut_a"], pair["sut_b"], pair["seeds"]) == ("mobil", "level0", "2")
    by_hand = ((d["mobil", 5] - d["level0", 5]) + (d["mobil", 6] - d["level0", 6])) / 2
    assert float(pair["delta_d_mean"]) == pytest.approx(by_hand, abs=1e-12)
    with pytest.raises(evoscen.InputError, match="--seeds = '0': expected an integer >= 1"):
        evoscen.run_experiment("intelligence", out=tmp_path / "bad", seeds=0)
    with pytest.raises(evoscen.InputError, match="unrecognized arguments: --no-such 1"):
        evoscen.run_experiment("intelligence", out=tmp_path / "bad", no_such=1)
    with pytest.raises(evoscen.InputError, match=r"^experiment 'nope': expected one of intelligence, sensitivity$"):
        evoscen.run_experiment("nope", out=tmp_path / "bad")
